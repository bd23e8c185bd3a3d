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

import numpy as np

from . import earth
from .attitude import cross3, q2mat, qmul, qnormalize, rv2q

__all__ = ["NavState", "coning_sculling", "strapdown_step", "STRAPDOWN_FLOPS"]

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
    """

    q: np.ndarray
    v: np.ndarray
    pos: np.ndarray
    t: float = 0.0
    a_prev: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def copy(self) -> "NavState":
        return NavState(self.q.copy(), self.v.copy(), self.pos.copy(), self.t, self.a_prev.copy())


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
    """Advance the navigation state by one interval ``T`` (s), in place; returns ``s``.

    Parameters
    ----------
    phi_m : (3,) compensated body rotation vector over the interval, rad.
    dv_m : (3,) compensated body velocity increment over the interval, m/s.

    Steps follow algorithms.md 1.2 (PSINS ``insupdate``): mid-interval extrapolation of
    velocity and position, velocity update with the rotation of the navigation frame over
    ``T/2``, trapezoidal position update, attitude update
    ``q_k = rv2q(-w_in^n T) (x) q_{k-1} (x) rv2q(phi_m)``.
    """
    lat, lon, h = float(s.pos[0]), float(s.pos[1]), float(s.pos[2])
    v = s.v
    # 3. mid-interval extrapolation
    v_half = v + s.a_prev * (T / 2.0)
    rm, rn = earth.radii(lat)
    lat_h = lat + float(v_half[1]) / (rm + h) * T / 2.0
    h_h = h + float(v_half[2]) * T / 2.0
    sl, cl = math.sin(lat_h), math.cos(lat_h)
    rm, rn = earth.radii(lat_h)
    rmh, rnh = rm + h_h, rn + h_h
    ve, vn = float(v_half[0]), float(v_half[1])
    w_ie = np.array([0.0, earth.OMEGA_IE * cl, earth.OMEGA_IE * sl], dtype=dtype)
    w_en = np.array([-vn / rmh, ve / rnh, ve * sl / cl / rnh], dtype=dtype)
    w_in = w_ie + w_en
    g_n = np.array([0.0, 0.0, -earth.gravity(lat_h, h_h)], dtype=dtype)
    # 4. velocity
    cbn = q2mat(s.q)
    f_n = cbn @ (dv_m.astype(dtype) / dtype(T))
    # rv2m(-w_in T/2) f^n  ~  f^n - (w_in T/2) x f^n
    f_n = f_n - cross3(w_in * dtype(T / 2.0), f_n)
    a_n = f_n + g_n - cross3(2.0 * w_ie + w_en, v)
    v_new = (v + a_n * dtype(T)).astype(dtype)
    # 5. position (float64)
    vm = (v.astype(np.float64) + v_new.astype(np.float64)) / 2.0
    rm, rn = earth.radii(lat_h)
    lat_new = lat + vm[1] / (rm + h_h) * T
    lon_new = lon + vm[0] / ((rn + h_h) * math.cos(lat_h)) * T
    h_new = h + vm[2] * T
    # 6. attitude
    q = qmul(rv2q((-w_in * dtype(T)).astype(dtype)), qmul(s.q, rv2q(phi_m.astype(dtype))))
    s.q = qnormalize(q).astype(dtype)
    s.v = v_new
    s.pos = np.array([lat_new, lon_new, h_new], dtype=np.float64)
    s.a_prev = a_n.astype(dtype)
    s.t += T
    return s
