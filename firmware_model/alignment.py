"""Initial alignment kernels: coarse levelling and solar-vector heading (gravity + Sun, TRIAD).

At rest the accelerometers measure ``f^b = C_n^b [0, 0, g]`` (ENU), which fixes pitch and roll;
heading needs a second, non-vertical reference vector. Without a magnetometer or a GNSS heading the
base firmware takes it from the Sun: the PSNS gives ``+-S^b``, the ephemeris (Grena 2012, at the
GNSS position and UTC) gives ``S^n``, and TRIAD (Black 1964; Shuster & Oh 1981) combines the two
vector pairs with gravity as the primary (exact) one, so the Sun only sets the rotation about the
vertical. The sign of ``+-S^b`` is the one whose vertical component has the sign of the Sun's
elevation (the Sun is above the horizon when the PSNS is valid). Fine alignment is the Kalman filter's
job afterwards (misalignment, biases).
"""

from __future__ import annotations

import math

import numpy as np

from . import c674x
from .arrays import FloatArray

__all__ = ["level_cycles", "level_from_specific_force", "solar_heading_alignment", "triad", "triad_cycles"]


def level_cycles(c: c674x.KernelCosts) -> int:
    """Coarse levelling: asin + atan2 + sqrt (MATHLIB inline [S, R2]) + a few FLOPs."""
    return c.math("asin") + c.math("atan2") + c.math("sqrt") + c.flops(6, 4)


def triad_cycles(c: c674x.KernelCosts) -> int:
    """TRIAD: 4 cross products, 4 rsqrt normalisations, one 3x3 x 3x3 product (DSPF_sp_mat_mul) [D]."""
    return c.math("rsqrt", 4) + c.flops(4 * 6 + 12, 4 * 3 + 6) + c.mat_mul(3, 3, 3)


def level_from_specific_force(f_b: FloatArray) -> tuple[float, float]:
    """Pitch and roll (rad) from the mean specific force at rest (body, m/s^2).

    ``f^b = g [-cos(p) sin(r), sin(p), cos(p) cos(r)]`` for ``C_b^n = a2mat(p, r, y)``.
    """
    g = math.sqrt(float(f_b @ f_b))
    pitch = math.asin(max(-1.0, min(1.0, float(f_b[1]) / g)))
    roll = math.atan2(-float(f_b[0]), float(f_b[2]))
    return pitch, roll


def _unit(v: FloatArray) -> FloatArray:
    return v / math.sqrt(float(v @ v))


def _cross(a: FloatArray, b: FloatArray) -> FloatArray:
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def triad(b1: FloatArray, b2: FloatArray, r1: FloatArray, r2: FloatArray) -> FloatArray:
    """TRIAD attitude ``C_b^n`` from two vector pairs (body ``b1, b2``; navigation ``r1, r2``).

    ``b1 <-> r1`` is matched exactly; ``b2 <-> r2`` only fixes the rotation about it.
    Raises ``ValueError`` when the pairs are (nearly) parallel.
    """
    b1, b2, r1, r2 = (np.asarray(v, dtype=np.float64) for v in (b1, b2, r1, r2))
    t1b, t1r = _unit(b1), _unit(r1)
    cb, cr = _cross(t1b, _unit(b2)), _cross(t1r, _unit(r2))
    nb, nr = float(cb @ cb), float(cr @ cr)
    if nb < 1e-6 or nr < 1e-6:
        raise ValueError("TRIAD: reference vectors are (nearly) parallel")
    t2b, t2r = cb / math.sqrt(nb), cr / math.sqrt(nr)
    mb = np.column_stack([t1b, t2b, _cross(t1b, t2b)])
    mr = np.column_stack([t1r, t2r, _cross(t1r, t2r)])
    return mr @ mb.T


def solar_heading_alignment(f_b: FloatArray, s_b: FloatArray, s_n: FloatArray) -> tuple[FloatArray, int]:
    """Coarse alignment ``C_b^n`` from the mean specific force and the bi-direction solar vector.

    Parameters
    ----------
    f_b : (3,) mean specific force at rest, body, m/s^2 (points up: ``f^n = [0, 0, g]``).
    s_b : (3,) measured ``+-S^b`` (unit, sign unknown).
    s_n : (3,) ephemeris sun vector, ENU (unit, Sun above the horizon).

    Returns
    -------
    ``C_b^n`` (3, 3) and the sign applied to ``s_b``.
    """
    up = _unit(np.asarray(f_b, dtype=np.float64))
    sb = np.asarray(s_b, dtype=np.float64)
    sign = 1 if (float(up @ sb) >= 0.0) == (float(s_n[2]) >= 0.0) else -1
    return triad(up, sign * sb, np.array([0.0, 0.0, 1.0]), np.asarray(s_n, dtype=np.float64)), sign
