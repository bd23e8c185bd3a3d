"""Strapdown inertial mechanization in ENU (PSINS ``insupdate``).

Source: ``shared/reference/algorithms.md`` section 1.2 (PSINS toolbox, Yan Gongmin). Latitude,
longitude and height are carried in float64 (as a C6747 firmware must, at the DP cycle price);
attitude and velocity in the firmware's working precision ``dtype`` (float32 by default, the
C674x native type).

State: ``q = q_b^n`` (scalar first), ``v = v^n`` (m/s, ENU), ``pos = [L, lambda, h]``
(rad, rad, m).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from . import earth
from .attitude import cross3, q2mat, qmul, qnormalize, rv2q

__all__ = ["NavState", "coning_sculling", "strapdown_step", "strapdown_step_f64", "STRAPDOWN_FLOPS"]

#: Rough floating-point operation count of one :func:`strapdown_step` (for the cycle model).
STRAPDOWN_FLOPS = 260


@dataclass
class NavState:
    """Navigation state of the mechanization.

    Attributes
    ----------
    q : (4,) quaternion ``q_b^n``, working precision.
    v : (3,) ENU velocity, m/s, working precision.
    pos : (3,) float64 ``[L rad, lambda rad, h m]``.
    t : float64 time of validity, s (FPGA time).
    a_prev : (3,) previous ENU acceleration used for mid-interval extrapolation, m/s^2.
    f_n : (3,) specific force in n of the last step, m/s^2 (for the KF's F matrix).
    """

    q: np.ndarray
    v: np.ndarray
    pos: np.ndarray
    t: float = 0.0
    a_prev: np.ndarray = field(default_factory=lambda: np.zeros(3))
    f_n: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def copy(self) -> "NavState":
        return NavState(self.q.copy(), self.v.copy(), self.pos.copy(), self.t, self.a_prev.copy(), self.f_n.copy())


def coning_sculling(dtheta: np.ndarray, dv: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Combine n gyro/accelerometer increments into one rotation vector and velocity increment.

    Parameters
    ----------
    dtheta, dv : (n, 3) body-frame angle (rad) and velocity (m/s) increments, n in {1, 2}.

    Returns
    -------
    phi_m (3,) rad and dv_m (3,) m/s (algorithms.md 1.2 step 1: single-sample rotation
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


def strapdown_step(
    s: NavState,
    phi_m: np.ndarray,
    dv_m: np.ndarray,
    T: float,
    dtype: type = np.float32,
) -> NavState:
    """Advance the navigation state by one interval ``T`` (s); returns ``s``.

    Parameters
    ----------
    phi_m : (3,) compensated body rotation vector over the interval, rad.
    dv_m : (3,) compensated body velocity increment over the interval, m/s.
    dtype : precision of the attitude and velocity arithmetic (the firmware's ``nav_state_precision``).

    Steps follow algorithms.md 1.2 (PSINS ``insupdate``): mid-interval extrapolation of
    velocity and position, velocity update with the rotation of the navigation frame over
    ``T/2``, trapezoidal position update, attitude update
    ``q_k = rv2q(-w_in^n T) (x) q_{k-1} (x) rv2q(phi_m)``.

    The state's arrays are replaced, never written in place (the firmware's INS history keeps
    references to them). In float64 the step runs on Python floats (:func:`strapdown_step_f64`:
    IEEE double operations in a fixed order, docs/decisions.md D-10.F1); in float32 on numpy float32
    arrays, every operation rounded to single precision as the C674x does.
    """
    if dtype is np.float64:
        return strapdown_step_f64(s, np.asarray(phi_m).tolist(), np.asarray(dv_m).tolist(), T)
    lat, lon, h = float(s.pos[0]), float(s.pos[1]), float(s.pos[2])
    v = s.v
    dt = dtype
    # 3. mid-interval extrapolation (Earth quantities in float64: latitude is a DP variable)
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
    cbn = q2mat(s.q)
    f_n = cbn @ (dv_m.astype(dt) * dt(1.0 / T))
    a_n = f_n - cross3(w_in * dt(T / 2.0), f_n) - cross3(w_cor, v)
    a_n[2] -= dt(g)
    v_new = (v + a_n * dt(T)).astype(dt)
    # 5. position (float64), trapezoidal velocity, radii at the mid-interval latitude
    vm_e = 0.5 * (float(v[0]) + float(v_new[0]))
    vm_n = 0.5 * (float(v[1]) + float(v_new[1]))
    vm_u = 0.5 * (float(v[2]) + float(v_new[2]))
    s.pos = np.array((lat + vm_n / rmh * T, lon + vm_e / (rnh * cl) * T, h + vm_u * T), dtype=np.float64)
    # 6. attitude: q_k = rv2q(-w_in T) (x) q_{k-1} (x) rv2q(phi_m)
    q = qmul(rv2q(-w_in * dt(T)), qmul(s.q, rv2q(phi_m.astype(dt))))
    s.q = qnormalize(q).astype(dt)
    s.v = v_new
    s.a_prev = a_n.astype(dt)
    s.f_n = f_n
    s.t += T
    return s


_A, _E2, _1_E2 = earth.A_WGS84, earth.E2_WGS84, 1.0 - earth.E2_WGS84
_W_IE, _G0, _G_B1, _G_B2, _G_H = earth.OMEGA_IE, earth.G0, earth._G_B1, earth._G_B2, earth._G_H
_sin, _cos, _sqrt = math.sin, math.cos, math.sqrt
_array, _f64 = np.array, np.float64


def strapdown_step_f64(s: NavState, phi_m: Sequence[float], dv_m: Sequence[float], T: float) -> NavState:
    """:func:`strapdown_step` in double precision on Python floats (no per-operation numpy overhead).

    ``phi_m``, ``dv_m``: the compensated increments as three Python floats each (rad, m/s, body).

    Same equations and evaluation order as the float32 path and :mod:`firmware_model.earth`
    (``radii``, ``gravity`` inlined), one IEEE double operation per step. Vector notation in the
    comments; ``x, y, z`` suffixes are the body axes, ``e, n, u`` the ENU axes.
    """
    lat, lon, h = s.pos.tolist()
    ve0, vn0, vu0 = s.v.tolist()
    q0, q1, q2, q3 = s.q.tolist()
    ax, ay, az = s.a_prev.tolist()
    px, py, pz = phi_m
    dvx, dvy, dvz = dv_m
    T2 = T / 2.0
    # 3. mid-interval extrapolation: v_half = v + a_prev T/2, latitude and height at T/2
    ve, vn, vu = ve0 + ax * T2, vn0 + ay * T2, vu0 + az * T2
    d = 1.0 - _E2 * _sin(lat) ** 2  # earth.radii(lat)
    rn = _A / _sqrt(d)
    rm = rn * _1_E2 / d
    lat_h = lat + vn / (rm + h) * T2
    h_h = h + vu * T2
    sl, cl = _sin(lat_h), _cos(lat_h)
    s2 = sl**2  # earth.radii(lat_h) and earth.gravity(lat_h, h_h) share sin^2
    d = 1.0 - _E2 * s2
    rn = _A / _sqrt(d)
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
    s.pos = _array((lat + vm_n / rmh * T, lon + vm_e / (rnh * cl) * T, h + vm_u * T))
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
    nrm = _sqrt(n0 * n0 + n1 * n1 + n2 * n2 + n3 * n3)  # qnormalize
    s.q = _array((n0 / nrm, n1 / nrm, n2 / nrm, n3 / nrm))
    s.v = _array((ve1, vn1, vu1))
    s.a_prev = _array((ae, an, au))
    s.f_n = _array((fe, fn, fu))
    s.t += T
    return s


def _rv2q(x: float, y: float, z: float) -> tuple[float, float, float, float]:
    """:func:`firmware_model.attitude.rv2q` on Python floats."""
    n2 = x * x + y * y + z * z
    if n2 < 1e-16:
        c = 1.0 - n2 / 8.0
        k = 0.5 - n2 / 48.0
    else:
        n = _sqrt(n2)
        c = _cos(n / 2.0)
        k = _sin(n / 2.0) / n
    return c, k * x, k * y, k * z
