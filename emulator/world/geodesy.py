"""The world's own Earth model: WGS-84 radii of curvature, normal gravity, Earth rate, geodetic <-> ECEF/ENU.

Independent of the firmware's kernels (docs/architecture.md, the independence rule): normal gravity is the closed
Somigliana formula with the second-order free-air reduction of NIMA TR8350.2 (WGS-84, third edition), eq. (4-1)
and (4-3), with the derived constants of its Table 3.4 -- not the firmware's PSINS series. Geodetic <-> ECEF and the
ENU projection come from pymap3d. Only the WGS-84 *defining* constants are shared (:mod:`protocols.constants`).
All functions take numpy arrays (any shape) or floats; angles in rad, lengths in m.
"""

from __future__ import annotations

import numpy as np
import pymap3d

from protocols.constants import A_WGS84, E2_WGS84, F_WGS84, OMEGA_IE

__all__ = ["GAMMA_E", "OMEGA_IE", "ecef_to_enu_vector", "geodetic_to_ecef", "normal_gravity", "radii"]

#: Normal gravity at the equator, m/s^2 (TR8350.2 Table 3.4).
GAMMA_E = 9.7803253359
#: Somigliana's constant k = (b gamma_p)/(a gamma_e) - 1 (TR8350.2 Table 3.4).
_K_SOMIGLIANA = 0.00193185265241
#: m = omega^2 a^2 b / GM (TR8350.2 Table 3.4).
_M_GEOD = 0.00344978650684

_ELLIPSOID = pymap3d.Ellipsoid.from_name("wgs84")


def radii(lat: np.ndarray | float) -> tuple[np.ndarray, np.ndarray]:
    """Meridian and prime-vertical radii of curvature ``(R_M, R_N)``, m."""
    s2 = np.sin(lat) ** 2
    d = 1.0 - E2_WGS84 * s2
    rn = A_WGS84 / np.sqrt(d)
    return rn * (1.0 - E2_WGS84) / d, rn


def normal_gravity(lat: np.ndarray | float, h: np.ndarray | float) -> np.ndarray:
    """Magnitude of WGS-84 normal gravity at latitude ``lat`` and ellipsoidal height ``h``, m/s^2.

    Somigliana (TR8350.2 eq. 4-1) on the ellipsoid, then the free-air series (eq. 4-3) above it.
    """
    s2 = np.sin(lat) ** 2
    g0 = GAMMA_E * (1.0 + _K_SOMIGLIANA * s2) / np.sqrt(1.0 - E2_WGS84 * s2)
    h = np.asarray(h, dtype=np.float64)
    return g0 * (1.0 - 2.0 / A_WGS84 * (1.0 + F_WGS84 + _M_GEOD - 2.0 * F_WGS84 * s2) * h
                 + 3.0 * h * h / (A_WGS84 * A_WGS84))


def geodetic_to_ecef(lat: float, lon: float, h: float) -> np.ndarray:
    """WGS-84 geodetic (rad, rad, m) to ECEF (m), by pymap3d."""
    x, y, z = pymap3d.geodetic2ecef(lat, lon, h, ell=_ELLIPSOID, deg=False)
    return np.array([float(x), float(y), float(z)])


def ecef_to_enu_vector(d: np.ndarray, lat: float, lon: float) -> np.ndarray:
    """An ECEF vector ``d`` expressed in the local ENU axes at (``lat``, ``lon``) (rad), by pymap3d."""
    e, n, u = pymap3d.ecef2enuv(float(d[0]), float(d[1]), float(d[2]), lat, lon, deg=False)
    return np.array([float(e), float(n), float(u)])
