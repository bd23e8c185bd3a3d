"""Strapdown inertial mechanization in ENU (PSINS ``insupdate``) and coning/sculling compensation.

Source: ``docs/reference/algorithms.md`` section 1.2 (PSINS toolbox, Yan Gongmin). Latitude, longitude and
height are carried in float64 (as a C6747 firmware must, at the DP cycle price); attitude and velocity in the
firmware's ``nav_state_precision`` (float64 by default, docs/decisions/firmware.md D-L.1; float32 is the C674x native
type). State: :class:`~firmware_model.nav_state.NavState`.

One reference and one fast path (docs/decisions/performance.md D-10.F1):

* :func:`strapdown_step` is the reference: the equations on numpy arrays and scalars of ``dtype``, any mix
  of state and arithmetic precision;
* :func:`strapdown_step_fast` gives bit for bit the reference's result for a state held in ``dtype``
  (float64 or float32), without numpy's per-operation overhead: in float64 one IEEE double operation per
  step on Python floats; in float32 the same operations on Python floats rounded to single precision by
  ``struct`` (:mod:`firmware_model.precision`), the dot and matrix-vector products by numpy.

Reductions (``|phi|^2`` of ``rv2q``, the quaternion norm, ``C_b^n dv``) have one summation order per
precision in both: float64 left to right (the order of the C loops), float32 numpy's ``dot`` / ``@``
(the BLAS order the float32 build has always used). ``tests/firmware_model/fast_path_cases.py`` holds the
equivalence cases.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Sequence
from typing import Any, Final

import numpy as np

from . import earth
from .arrays import FloatArray, FloatDtype
from .attitude import cross3, q2mat, qmul
from .nav_state import A_PREV, POS, NavState, Q, V
from .precision import rounder

__all__ = ["STRAPDOWN_FLOPS", "NavState", "coning_sculling", "coning_sculling_fast", "strapdown_kernel",
           "strapdown_step", "strapdown_step_fast"]

#: Rough floating-point operation count of one :func:`strapdown_step` (for the cycle model).
STRAPDOWN_FLOPS = 260


def coning_sculling(dtheta: FloatArray, dv: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Combine n gyro/accelerometer increments into one rotation vector and velocity increment.

    Parameters
    ----------
    dtheta, dv : (n, 3) body-frame angle (rad) and velocity (m/s) increments, n in {1, 2}.

    Returns
    -------
    phi_m (3,) rad and dv_m (3,) m/s (docs/reference/algorithms.md 1.2 step 1: single-sample rotation
    compensation for n = 1; two-sample coning/sculling with coefficient 2/3 for n = 2).
    """
    n = dtheta.shape[0]
    if n == 1:
        th, v = dtheta[0], dv[0]
        return th, v + 0.5 * cross3(th, v)
    if n == 2:
        t1, t2 = dtheta
        v1, v2 = dv
        th = t1 + t2
        vv = v1 + v2
        phi = th + (2.0 / 3.0) * cross3(t1, t2)
        dvm = vv + 0.5 * cross3(th, vv) + (2.0 / 3.0) * (cross3(t1, v2) + cross3(v1, t2))
        return phi, dvm
    raise ValueError(f"coning_sculling supports 1 or 2 subsamples, got {n}")


#: the working precision's rounders for :func:`coning_sculling_fast` (3 and 6 values)
_ROUND_3_6 = {dt: (rounder(dt, 3), rounder(dt, 6)) for dt in (np.float32, np.float64)}


def coning_sculling_fast(dtheta: Sequence[float], dv: Sequence[float],
                         dtype: FloatDtype) -> tuple[tuple[float, ...], tuple[float, ...]]:
    """:func:`coning_sculling` of one sample (n = 1), bit for bit, on Python floats: ``dtheta``, ``dv`` three values
    of ``dtype`` (float32 or float64) each; returns ``(phi_m, dv_m)`` as tuples of Python floats.

    The single-sample rotation compensation ``dv_m = dv + 1/2 dtheta x dv`` with every product and sum rounded to
    ``dtype`` (:mod:`firmware_model.precision`): what the 200 Hz loop runs with rate output.
    """
    r3, r6 = _ROUND_3_6[dtype]
    px, py, pz = dtheta
    ux, uy, uz = dv
    c0, c1, c2, c3, c4, c5 = r6.unpack(r6.pack(py * uz, pz * ux, px * uy, pz * uy, px * uz, py * ux))
    c0, c1, c2 = r3.unpack(r3.pack(c0 - c3, c1 - c4, c2 - c5))
    return (px, py, pz), r3.unpack(r3.pack(ux + 0.5 * c0, uy + 0.5 * c1, uz + 0.5 * c2))


def strapdown_step(
    s: NavState,
    phi_m: FloatArray | Sequence[float],
    dv_m: FloatArray | Sequence[float],
    T: float,
    dtype: FloatDtype = np.float32,
) -> NavState:
    """Advance the navigation state by one interval ``T`` (s); returns ``s`` (the reference formulation).

    Parameters
    ----------
    phi_m : (3,) compensated body rotation vector over the interval, rad.
    dv_m : (3,) compensated body velocity increment over the interval, m/s.
    dtype : precision of the attitude and velocity arithmetic (the firmware's ``nav_state_precision``).

    Notes
    -----
    Steps follow docs/reference/algorithms.md 1.2 (PSINS ``insupdate``): mid-interval extrapolation of
    velocity and position, velocity update with the rotation of the navigation frame over ``T/2``,
    trapezoidal position update, attitude update ``q_k = rv2q(-w_in^n T) (x) q_{k-1} (x) rv2q(phi_m)``.
    Numpy arrays and scalars of ``dtype``; Earth quantities and position in float64 (latitude is a DP
    variable). The state's arrays are replaced, never written in place (:class:`NavState`,
    docs/decisions/performance.md D-10.F2). :func:`strapdown_step_fast` is the same step, faster.
    """
    dt = dtype
    phi = np.asarray(phi_m).astype(dt)
    dv = np.asarray(dv_m).astype(dt)
    lat, lon, h = (float(x) for x in s.pos)
    v = s.v
    # 3. mid-interval extrapolation
    v_half = v + s.a_prev * dt(T / 2.0)
    ve, vn, vu = float(v_half[0]), float(v_half[1]), float(v_half[2])
    rm, rn = earth.radii(lat)
    lat_h = lat + vn / (rm + h) * (T / 2.0)
    h_h = h + vu * (T / 2.0)
    sl, cl = math.sin(lat_h), math.cos(lat_h)
    rm, rn = earth.radii(lat_h)
    rmh, rnh = rm + h_h, rn + h_h
    wie_n, wie_u = earth.OMEGA_IE * cl, earth.OMEGA_IE * sl
    wen = (-vn / rmh, ve / rnh, ve * sl / cl / rnh)
    w_in = np.array((wen[0], wie_n + wen[1], wie_u + wen[2]), dtype=dt)
    w_cor = np.array((wen[0], 2.0 * wie_n + wen[1], 2.0 * wie_u + wen[2]), dtype=dt)  # 2 w_ie + w_en
    g = earth.gravity(lat_h, h_h)
    # 4. velocity: f^n = C_b^n dv_m / T, rotated back by the n-frame turn over T/2
    f_n = _matvec(q2mat(s.q), dv * dt(1.0 / T))
    a_n = f_n - cross3(w_in * dt(T / 2.0), f_n) - cross3(w_cor, v)
    a_n[2] -= dt(g)
    v_new = (v + a_n * dt(T)).astype(dt)
    # 5. position (float64), trapezoidal velocity, radii at the mid-interval latitude
    vm_e = 0.5 * (float(v[0]) + float(v_new[0]))
    vm_n = 0.5 * (float(v[1]) + float(v_new[1]))
    vm_u = 0.5 * (float(v[2]) + float(v_new[2]))
    s.pos = np.array((lat + vm_n / rmh * T, lon + vm_e / (rnh * cl) * T, h + vm_u * T), dtype=np.float64)
    # 6. attitude: q_k = rv2q(-w_in T) (x) q_{k-1} (x) rv2q(phi_m), normalised
    q = qmul(_rv2q_ref(-w_in * dt(T)), qmul(s.q, _rv2q_ref(phi)))
    s.q = (q / np.sqrt(_dot(q, q))).astype(dt)
    s.v = v_new
    s.a_prev = a_n.astype(dt)
    s.f_n = f_n
    s.t += T
    return s


def _dot(a: FloatArray, b: FloatArray) -> Any:
    """Dot product in the build's summation order: float64 left to right, otherwise numpy's ``dot``."""
    if a.dtype == np.float64 and b.dtype == np.float64:
        x, y = a.tolist(), b.tolist()
        acc = x[0] * y[0]
        for i in range(1, len(x)):
            acc += x[i] * y[i]
        return acc
    return np.dot(a, b)


def _matvec(c: FloatArray, x: FloatArray) -> FloatArray:
    """``C x`` for a 3x3 ``C``, each row summed as :func:`_dot` sums."""
    if c.dtype == np.float64 and x.dtype == np.float64:
        return np.array([_dot(row, x) for row in c])
    return c @ x


def _rv2q_ref(phi: FloatArray) -> FloatArray:
    """:func:`firmware_model.attitude.rv2q` with ``|phi|^2`` summed by :func:`_dot`."""
    n2 = float(_dot(phi, phi))
    if n2 < 1e-16:
        c = 1.0 - n2 / 8.0
        k = 0.5 - n2 / 48.0
    else:
        n = math.sqrt(n2)
        c = math.cos(n / 2.0)
        k = math.sin(n / 2.0) / n
    return np.array([c, k * phi[0], k * phi[1], k * phi[2]], dtype=phi.dtype)


def strapdown_step_fast(s: NavState, phi_m: Sequence[float], dv_m: Sequence[float], T: float,
                        dtype: FloatDtype = np.float32) -> NavState:
    """:func:`strapdown_step`, bit for bit, for a state held in ``dtype`` (``q``, ``v``, ``a_prev`` float64 or
    float32 values); ``phi_m``, ``dv_m``: three Python floats each (rad, m/s, body; ``array.tolist()`` of an
    array), rounded to ``dtype`` here.

    The state stays in its float form (:meth:`NavState.as_floats`): a step creates no arrays. Other
    precisions go to the reference.
    """
    step: Callable[[NavState, Sequence[float], Sequence[float], float], NavState] = strapdown_kernel(dtype)
    return step(s, phi_m, dv_m, T)


def strapdown_kernel(dtype: FloatDtype) -> Callable[[NavState, Sequence[float], Sequence[float], float], NavState]:
    """The step that :func:`strapdown_step_fast` runs for a state held in ``dtype``, ``step(s, phi_m, dv_m, T)``:
    for a caller that steps every tick in one precision and picks it once (the firmware's 200 Hz loop)."""
    if dtype is _F64:
        return _step_f64
    if dtype is _F32:
        return _step_f32
    return functools.partial(strapdown_step, dtype=dtype)


_F64, _F32 = np.float64, np.float32


# Final: the compiled path (tools/build_compiled.py) keeps these as C doubles and calls math.sin/cos/sqrt
# directly (C libm, as CPython's math module does), instead of looking module globals up on every use.
_A: Final[float] = earth.A_WGS84
_E2: Final[float] = earth.E2_WGS84
_1_E2: Final[float] = 1.0 - earth.E2_WGS84
_W_IE: Final[float] = earth.OMEGA_IE
_G0: Final[float] = earth.G0
_G_B1: Final[float] = earth._G_B1
_G_B2: Final[float] = earth._G_B2
_G_H: Final[float] = earth._G_H
_array = np.array


def _step_f64(s: NavState, phi_m: Sequence[float], dv_m: Sequence[float], T: float) -> NavState:
    """The float64 kernel of :func:`strapdown_step_fast`: one IEEE double operation per step on Python floats.

    Same equations and evaluation order as :func:`strapdown_step` and :mod:`firmware_model.earth`
    (``radii``, ``gravity`` inlined), one IEEE double operation per step. Vector notation in the
    comments; ``x, y, z`` suffixes are the body axes, ``e, n, u`` the ENU axes.
    """
    q0, q1, q2, q3, ve0, vn0, vu0, lat, lon, h, ax, ay, az, _, _, _ = s.as_floats()  # the layout of nav_state
    px, py, pz = phi_m
    dvx, dvy, dvz = dv_m
    T2 = T / 2.0
    # 3. mid-interval extrapolation: v_half = v + a_prev T/2, latitude and height at T/2
    ve, vn, vu = ve0 + ax * T2, vn0 + ay * T2, vu0 + az * T2
    d = 1.0 - _E2 * math.sin(lat) ** 2  # earth.radii(lat)
    rn = _A / math.sqrt(d)
    rm = rn * _1_E2 / d
    lat_h = lat + vn / (rm + h) * T2
    h_h = h + vu * T2
    sl, cl = math.sin(lat_h), math.cos(lat_h)
    s2 = sl**2  # earth.radii(lat_h) and earth.gravity(lat_h, h_h) share sin^2
    d = 1.0 - _E2 * s2
    rn = _A / math.sqrt(d)
    rm = rn * _1_E2 / d
    rmh, rnh = rm + h_h, rn + h_h
    wie_n, wie_u = _W_IE * cl, _W_IE * sl
    wen_e, wen_n, wen_u = -vn / rmh, ve / rnh, ve * sl / cl / rnh
    wi_e, wi_n, wi_u = wen_e, wie_n + wen_n, wie_u + wen_u  # w_in = w_ie + w_en
    wc_e, wc_n, wc_u = wen_e, 2.0 * wie_n + wen_n, 2.0 * wie_u + wen_u  # 2 w_ie + w_en
    g = _G0 * (1.0 + _G_B1 * s2 + _G_B2 * s2 * s2) - _G_H * h_h
    # 4. velocity: f^n = C_b^n dv_m / T (q2mat), a = f^n - (w_in T/2) x f^n - w_cor x v - g
    c00 = q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3
    c01 = 2 * (q1 * q2 - q0 * q3)
    c02 = 2 * (q1 * q3 + q0 * q2)
    c10 = 2 * (q1 * q2 + q0 * q3)
    c11 = q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3
    c12 = 2 * (q2 * q3 - q0 * q1)
    c20 = 2 * (q1 * q3 - q0 * q2)
    c21 = 2 * (q2 * q3 + q0 * q1)
    c22 = q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3
    rT = 1.0 / T
    fx, fy, fz = dvx * rT, dvy * rT, dvz * rT
    fe = c00 * fx + c01 * fy + c02 * fz
    fn = c10 * fx + c11 * fy + c12 * fz
    fu = c20 * fx + c21 * fy + c22 * fz
    he, hn, hu = wi_e * T2, wi_n * T2, wi_u * T2
    ae = fe - (hn * fu - hu * fn) - (wc_n * vu0 - wc_u * vn0)
    an = fn - (hu * fe - he * fu) - (wc_u * ve0 - wc_e * vu0)
    au = fu - (he * fn - hn * fe) - (wc_e * vn0 - wc_n * ve0)
    au -= g
    ve1, vn1, vu1 = ve0 + ae * T, vn0 + an * T, vu0 + au * T
    # 5. position, trapezoidal velocity, radii at the mid-interval latitude
    vm_e = 0.5 * (ve0 + ve1)
    vm_n = 0.5 * (vn0 + vn1)
    vm_u = 0.5 * (vu0 + vu1)
    lat1, lon1, h1 = lat + vm_n / rmh * T, lon + vm_e / (rnh * cl) * T, h + vm_u * T
    # 6. attitude: q_k = rv2q(-w_in T) (x) q_{k-1} (x) rv2q(phi_m)
    a0, a1, a2, a3 = _rv2q(-(wi_e * T), -(wi_n * T), -(wi_u * T))
    b0, b1, b2, b3 = _rv2q(px, py, pz)
    # qmul(q, b)
    r0 = q0 * b0 - q1 * b1 - q2 * b2 - q3 * b3
    r1 = q0 * b1 + q1 * b0 + q2 * b3 - q3 * b2
    r2 = q0 * b2 - q1 * b3 + q2 * b0 + q3 * b1
    r3 = q0 * b3 + q1 * b2 - q2 * b1 + q3 * b0
    # qmul(a, r)
    n0 = a0 * r0 - a1 * r1 - a2 * r2 - a3 * r3
    n1 = a0 * r1 + a1 * r0 + a2 * r3 - a3 * r2
    n2 = a0 * r2 - a1 * r3 + a2 * r0 + a3 * r1
    n3 = a0 * r3 + a1 * r2 - a2 * r1 + a3 * r0
    nrm = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2 + n3 * n3)  # qnormalize
    s._set_floats((n0 / nrm, n1 / nrm, n2 / nrm, n3 / nrm, ve1, vn1, vu1, lat1, lon1, h1, ae, an, au, fe, fn, fu))
    s.t += T
    return s


def _rv2q(x: float, y: float, z: float) -> tuple[float, float, float, float]:
    """:func:`firmware_model.attitude.rv2q` on Python floats."""
    n2 = x * x + y * y + z * z
    if n2 < 1e-16:
        c = 1.0 - n2 / 8.0
        k = 0.5 - n2 / 48.0
    else:
        n = math.sqrt(n2)
        c = math.cos(n / 2.0)
        k = math.sin(n / 2.0) / n
    return c, k * x, k * y, k * z


_R1, _R3, _R4, _R6, _R8, _R10, _R16 = (rounder(np.float32, n) for n in (1, 3, 4, 6, 8, 10, 16))
_f32 = np.float32


@functools.lru_cache(maxsize=8)
def _f32_interval_constants(T: float) -> tuple[float, float, float]:
    """``float32(T/2), float32(T), float32(1/T)`` as Python floats (the step interval rarely changes)."""
    return float(_f32(T / 2.0)), float(_f32(T)), float(_f32(1.0 / T))


def _qmul_f32(p: Sequence[float], q: Sequence[float]) -> tuple[float, ...]:
    """:func:`firmware_model.attitude.qmul` of two float32 quaternions (Python floats), float32 rounding."""
    p0, p1, p2, p3 = p
    q0, q1, q2, q3 = q
    (m00, m11, m22, m33, m01, m10, m23, m32, m02, m13, m20, m31, m03, m12, m21, m30) = _R16.unpack(_R16.pack(
        p0 * q0, p1 * q1, p2 * q2, p3 * q3, p0 * q1, p1 * q0, p2 * q3, p3 * q2,
        p0 * q2, p1 * q3, p2 * q0, p3 * q1, p0 * q3, p1 * q2, p2 * q1, p3 * q0))
    r = _R4.unpack(_R4.pack(m00 - m11, m01 + m10, m02 - m13, m03 + m12))
    r = _R4.unpack(_R4.pack(r[0] - m22, r[1] + m23, r[2] + m20, r[3] - m21))
    return _R4.unpack(_R4.pack(r[0] - m33, r[1] - m32, r[2] + m31, r[3] + m30))


def _rv2q_f32(x: float, y: float, z: float) -> tuple[float, ...]:
    """:func:`firmware_model.attitude.rv2q` of a float32 rotation vector, float32 result: ``|phi|^2`` by
    numpy's float32 dot (its BLAS summation order), the trigonometry in double, ``float32(k) * phi``."""
    phi = _array((x, y, z), dtype=_f32)
    n2 = float(np.dot(phi, phi))
    if n2 < 1e-16:
        c = 1.0 - n2 / 8.0
        k = 0.5 - n2 / 48.0
    else:
        n = math.sqrt(n2)
        c = math.cos(n / 2.0)
        k = math.sin(n / 2.0) / n
    (k,) = _R1.unpack(_R1.pack(k))  # float32(k) * phi (NumPy's rule for a Python float times float32)
    return _R4.unpack(_R4.pack(c, k * x, k * y, k * z))


def _cross_f32(a: Sequence[float], b: Sequence[float]) -> tuple[float, ...]:
    """:func:`firmware_model.attitude.cross3` of two float32 3-vectors, float32 rounding."""
    a0, a1, a2 = a
    b0, b1, b2 = b
    p = _R6.unpack(_R6.pack(a1 * b2, a2 * b1, a2 * b0, a0 * b2, a0 * b1, a1 * b0))
    return _R3.unpack(_R3.pack(p[0] - p[1], p[2] - p[3], p[4] - p[5]))


def _step_f32(s: NavState, phi_m: Sequence[float], dv_m: Sequence[float], T: float) -> NavState:
    """The float32 kernel of :func:`strapdown_step_fast`: element-wise float32 operations on Python floats rounded
    by ``struct``; the dot products (``rv2q``, normalisation) and ``C_b^n x`` by numpy (their BLAS summation
    order); Earth quantities and position in double."""
    R3p, R3u = _R3.pack, _R3.unpack
    x = s.as_floats()
    q = x[Q]
    v0 = x[V]
    ve0, vn0, vu0 = v0
    lat, lon, h = x[POS]
    T2w, Tw, rTw = _f32_interval_constants(T)
    px, py, pz = R3u(R3p(*phi_m))  # phi_m.astype(float32)
    dvx, dvy, dvz = R3u(R3p(*dv_m))
    # 3. mid-interval extrapolation: v_half = v + a_prev T/2 (float32); latitude, height, rates in double
    ax, ay, az = x[A_PREV]
    t = R3u(R3p(ax * T2w, ay * T2w, az * T2w))
    ve, vn, vu = R3u(R3p(ve0 + t[0], vn0 + t[1], vu0 + t[2]))
    d = 1.0 - _E2 * math.sin(lat) ** 2  # earth.radii(lat)
    rn = _A / math.sqrt(d)
    rm = rn * _1_E2 / d
    lat_h = lat + vn / (rm + h) * (T / 2.0)
    h_h = h + vu * (T / 2.0)
    sl, cl = math.sin(lat_h), math.cos(lat_h)
    s2 = sl**2
    d = 1.0 - _E2 * s2
    rn = _A / math.sqrt(d)
    rm = rn * _1_E2 / d
    rmh, rnh = rm + h_h, rn + h_h
    wie_n, wie_u = _W_IE * cl, _W_IE * sl
    wen_e, wen_n, wen_u = -vn / rmh, ve / rnh, ve * sl / cl / rnh
    w_in = R3u(R3p(wen_e, wie_n + wen_n, wie_u + wen_u))
    w_cor = R3u(R3p(wen_e, 2.0 * wie_n + wen_n, 2.0 * wie_u + wen_u))
    g = _G0 * (1.0 + _G_B1 * s2 + _G_B2 * s2 * s2) - _G_H * h_h
    # 4. velocity: f^n = C_b^n dv_m / T; C_b^n = q2mat(q) in float32
    q0, q1, q2, q3 = q
    p00, p11, p22, p33, p12, p03, p13, p02, p23, p01 = _R10.unpack(_R10.pack(
        q0 * q0, q1 * q1, q2 * q2, q3 * q3, q1 * q2, q0 * q3, q1 * q3, q0 * q2, q2 * q3, q0 * q1))
    a, b, d01, d02, d10, d12, d20, d21 = _R8.unpack(_R8.pack(
        p00 + p11, p00 - p11, p12 - p03, p13 + p02, p12 + p03, p23 - p01, p13 - p02, p23 + p01))
    c00, c11, c22 = R3u(R3p(a - p22, b + p22, b - p22))
    c00, c11, c22 = R3u(R3p(c00 - p33, c11 - p33, c22 + p33))
    cbn = _array((c00, 2 * d01, 2 * d02, 2 * d10, c11, 2 * d12, 2 * d20, 2 * d21, c22), dtype=_f32).reshape(3, 3)
    f_n = cbn @ _array(R3u(R3p(dvx * rTw, dvy * rTw, dvz * rTw)), dtype=_f32)
    fe, fn, fu = f_n.tolist()
    # a = f^n - (w_in T/2) x f^n - w_cor x v - g
    c1 = _cross_f32(R3u(R3p(w_in[0] * T2w, w_in[1] * T2w, w_in[2] * T2w)), (fe, fn, fu))
    c2 = _cross_f32(w_cor, v0)
    ae, an, au = R3u(R3p(fe - c1[0], fn - c1[1], fu - c1[2]))
    ae, an, au = R3u(R3p(ae - c2[0], an - c2[1], au - c2[2]))
    (gw,) = _R1.unpack(_R1.pack(g))
    ae, an, au = R3u(R3p(ae, an, au - gw))
    t = R3u(R3p(ae * Tw, an * Tw, au * Tw))
    ve1, vn1, vu1 = R3u(R3p(ve0 + t[0], vn0 + t[1], vu0 + t[2]))
    # 5. position (double), trapezoidal velocity, radii at the mid-interval latitude
    vm_e = 0.5 * (ve0 + ve1)
    vm_n = 0.5 * (vn0 + vn1)
    vm_u = 0.5 * (vu0 + vu1)
    lat1, lon1, h1 = lat + vm_n / rmh * T, lon + vm_e / (rnh * cl) * T, h + vm_u * T
    # 6. attitude: q_k = rv2q(-w_in T) (x) q_{k-1} (x) rv2q(phi_m), normalised (float32)
    wt = R3u(R3p(w_in[0] * Tw, w_in[1] * Tw, w_in[2] * Tw))
    qn = _qmul_f32(_rv2q_f32(-wt[0], -wt[1], -wt[2]), _qmul_f32(q, _rv2q_f32(px, py, pz)))
    qa = _array(qn, dtype=_f32)
    # qnormalize in float32: |q|^2 by numpy's dot, sqrt and the divisions rounded to float32
    (nrm,) = _R1.unpack(_R1.pack(math.sqrt(float(np.dot(qa, qa)))))
    q0n, q1n, q2n, q3n = _R4.unpack(_R4.pack(qn[0] / nrm, qn[1] / nrm, qn[2] / nrm, qn[3] / nrm))
    s._set_floats((q0n, q1n, q2n, q3n, ve1, vn1, vu1, lat1, lon1, h1, ae, an, au, fe, fn, fu), _f32)
    s.t += T
    return s
