"""Small kernels the variants share: chi-square thresholds, compass unit mountings, SPD solves, attitude errors.

Every kernel states its C674x cycle cost next to it (``*_cycles``), in the build's precision
(:class:`firmware_model.c674x.KernelCosts`), like the base firmware's kernels.
"""

from __future__ import annotations

import math

import numpy as np

from .. import c674x
from ..arrays import FloatArray
from ..units import DEG

__all__ = [
    "CHI2_TABLE",
    "chi2_threshold",
    "compass_mountings",
    "cross",
    "misalignment_between",
    "plane_basis",
    "spd_inverse",
    "spd_inverse_cycles",
    "spd_solve",
    "spd_solve_cycles",
    "unit_mounting",
]

#: Upper quantiles ``chi2_{1-alpha}(m)`` for m = 1..6 degrees of freedom and the usual alphas
#: (docs/reference/algorithms.md 5.2; m = 4, 5 added from the same distribution; checked against scipy.stats in the
#: tests).
CHI2_TABLE: dict[float, tuple[float, ...]] = {
    0.05: (3.841, 5.991, 7.815, 9.488, 11.070, 12.592),
    0.01: (6.635, 9.210, 11.345, 13.277, 15.086, 16.812),
    0.005: (7.879, 10.597, 12.838, 14.860, 16.750, 18.548),
    0.001: (10.828, 13.816, 16.266, 18.467, 20.515, 22.458),
}


def chi2_threshold(dof: int, alpha: float) -> float:
    """``T_D = chi2_{1-alpha}(dof)`` (table lookup, the firmware has no quantile function)."""
    row = CHI2_TABLE.get(alpha)
    if row is None:
        raise ValueError(f"chi-square alpha must be one of {sorted(CHI2_TABLE)}, got {alpha}")
    if not 1 <= dof <= len(row):
        raise ValueError(f"chi-square table covers 1..{len(row)} degrees of freedom, got {dof}")
    return row[dof - 1]


def unit_mounting(zenith: float, azimuth: float) -> FloatArray:
    """``C_u^b`` (3, 3) of a single-direction polarization unit looking at ``zenith``/``azimuth`` (rad).

    Convention of :mod:`firmware_model.psns_geometry` (docs/architecture.md "Conventions"): azimuth in the body x-y
    plane from
    body +y (forward) towards +x (right), zenith angle from body +z; the unit's +z is its view ray, its
    +y points "up the hemisphere" (towards body +z in the ray's vertical plane), ``x = y x z``. A unit at
    the zenith (no vertical plane) is the identity turned by ``azimuth`` about z, so ``(0, 0)`` is the
    compass's unit 0. Columns are the unit axes in body coordinates.
    """
    if zenith < 1e-9:
        c, s = math.cos(azimuth), math.sin(azimuth)
        return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    st, ct = math.sin(zenith), math.cos(zenith)
    sa, ca = math.sin(azimuth), math.cos(azimuth)
    z = np.array([st * sa, st * ca, ct])
    y = np.array([-ct * sa, -ct * ca, st])
    x = np.array([y[1] * z[2] - y[2] * z[1], y[2] * z[0] - y[0] * z[2], y[0] * z[1] - y[1] * z[0]])
    return np.column_stack([x, y, z])


def compass_mountings(directions_deg: list[tuple[float, float]] | tuple[tuple[float, float], ...]) -> FloatArray:
    """Mountings (n, 3, 3) of units given as ``(zenith_deg, azimuth_deg)`` pairs (see :func:`unit_mounting`)."""
    return np.stack([unit_mounting(z * DEG, a * DEG) for z, a in directions_deg])


def cross(a: FloatArray, b: FloatArray) -> FloatArray:
    """Cross product of two 3-vectors without ``numpy.cross``'s axis handling (per-frame hot path)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]],
                    dtype=np.result_type(a, b))


def spd_solve(A: FloatArray, b: FloatArray) -> FloatArray:
    """Solve ``A x = b`` for a small symmetric positive-definite ``A`` (n, n) by Cholesky; ``b`` (n,) or (n, k)."""
    L = np.linalg.cholesky(A.astype(np.float64))
    y = np.linalg.solve(L, b.astype(np.float64))
    return np.linalg.solve(L.T, y).astype(A.dtype)


def spd_solve_cycles(n: int, k: int, c: c674x.KernelCosts) -> int:
    """Cholesky (``n^3/6`` MAC, n sqrt, n reciprocals) and ``k`` forward/back substitutions (``n^2`` MAC each) [D]."""
    mac = n * n * n // 6 + k * n * n
    return c.flops(mac, mac) + n * (c.math("sqrt") + c.math("recip"))


def spd_inverse(A: FloatArray) -> FloatArray:
    """Inverse of a small SPD matrix by Cholesky (symmetrised)."""
    inv = spd_solve(A, np.eye(A.shape[0], dtype=A.dtype))
    return (0.5 * (inv + inv.T)).astype(A.dtype)


def spd_inverse_cycles(n: int, c: c674x.KernelCosts) -> int:
    """Inverse of an n x n SPD matrix: Cholesky + n substitutions [D]."""
    return spd_solve_cycles(n, n, c)


def misalignment_between(cbn_computed: FloatArray, cbn_measured: FloatArray) -> FloatArray:
    """Misalignment ``phi`` (3,) with ``C_b^{n'} = (I - [phi x]) C_b^n`` (docs/reference/algorithms.md section 0),
    small angles.

    ``M = C_b^{n'} (C_b^n)^T = I - [phi x]``, so ``phi = (M_12 - M_21, M_20 - M_02, M_01 - M_10) / 2``.
    """
    M = cbn_computed @ cbn_measured.T
    return np.array([M[1, 2] - M[2, 1], M[2, 0] - M[0, 2], M[0, 1] - M[1, 0]], dtype=cbn_computed.dtype) * 0.5


def plane_basis(s: FloatArray) -> tuple[FloatArray, FloatArray]:
    """Two unit vectors spanning the plane perpendicular to the unit vector ``s`` (deterministic choice)."""
    a = np.array([1.0, 0.0, 0.0]) if abs(float(s[0])) < 0.9 else np.array([0.0, 1.0, 0.0])
    u1 = cross(s, a.astype(s.dtype))
    u1 = u1 / math.sqrt(float(u1 @ u1))
    u2 = cross(s, u1)
    return u1.astype(s.dtype), u2.astype(s.dtype)
