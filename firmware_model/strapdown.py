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
