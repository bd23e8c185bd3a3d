"""WGS-84 Earth model: radii, normal gravity, Earth and transport rates (ENU).

The firmware's own kernels. The WGS-84 defining constants come from :mod:`protocols.constants`, which the
world shares; the models built on them here are the firmware's (``docs/reference/algorithms.md`` section 1.1).

Conventions: navigation frame n = ENU; position ``p = [L, lambda, h]`` = latitude (rad),
longitude (rad), ellipsoidal height (m).
"""

from __future__ import annotations

import math

import numpy as np

from protocols.constants import A_WGS84, E2_WGS84, F_WGS84, OMEGA_IE

from .arrays import FloatArray

__all__ = [
    "A_WGS84",
    "E2_WGS84",
    "F_WGS84",
    "G0",
    "OMEGA_IE",
    "ecef_to_geodetic",
    "geodetic_to_ecef",
    "gravity",
    "gravity_n",
    "m_pv",
    "omega_en_n",
    "omega_ie_n",
    "radii",
]

#: Equatorial normal gravity, m/s^2 (PSINS ``G0``).
G0 = 9.7803267714
#: Gravity-model coefficients (PSINS ``pos2g``, "grs80" in ``earth.m``).
_G_B1 = 5.27094e-3
_G_B2 = 2.32718e-5
_G_H = 3.086e-6


def radii(lat: float) -> tuple[float, float]:
    """Meridian and prime-vertical radii of curvature ``(R_M, R_N)`` in m at latitude ``lat`` (rad)."""
    s2 = math.sin(lat) ** 2
    d = 1.0 - E2_WGS84 * s2
    rn = A_WGS84 / math.sqrt(d)
    rm = rn * (1.0 - E2_WGS84) / d
    return rm, rn


def gravity(lat: float, h: float) -> float:
    """Magnitude of normal gravity, m/s^2 (docs/reference/algorithms.md 1.1, PSINS classic model).

    ``g = g0 (1 + 5.27094e-3 sin^2 L + 2.32718e-5 sin^4 L) - 3.086e-6 h``.
    At 39.979 deg, 50 m this is 9.801492 m/s^2.
    """
    s2 = math.sin(lat) ** 2
    return G0 * (1.0 + _G_B1 * s2 + _G_B2 * s2 * s2) - _G_H * h


def gravity_n(lat: float, h: float) -> FloatArray:
    """Gravity vector in ENU, ``[0, 0, -g]`` m/s^2."""
    return np.array([0.0, 0.0, -gravity(lat, h)])


def omega_ie_n(lat: float) -> FloatArray:
    """Earth rate in ENU, ``[0, w cos L, w sin L]`` rad/s."""
    return np.array([0.0, OMEGA_IE * math.cos(lat), OMEGA_IE * math.sin(lat)])


def omega_en_n(lat: float, h: float, v_enu: FloatArray) -> FloatArray:
    """Transport rate in ENU, ``[-vN/R_Mh, vE/R_Nh, vE tan L/R_Nh]`` rad/s."""
    rm, rn = radii(lat)
    rmh, rnh = rm + h, rn + h
    ve, vn = float(v_enu[0]), float(v_enu[1])
    return np.array([-vn / rmh, ve / rnh, ve * math.tan(lat) / rnh])


def m_pv(lat: float, h: float) -> FloatArray:
    """Map ENU velocity to ``[dL/dt, dlambda/dt, dh/dt]``: ``[[0,1/R_Mh,0],[1/(R_Nh cos L),0,0],[0,0,1]]``."""
    rm, rn = radii(lat)
    return np.array(
        [[0.0, 1.0 / (rm + h), 0.0], [1.0 / ((rn + h) * math.cos(lat)), 0.0, 0.0], [0.0, 0.0, 1.0]]
    )


def geodetic_to_ecef(lat: float, lon: float, h: float) -> FloatArray:
    """WGS-84 geodetic (rad, rad, m) to ECEF (m)."""
    _, rn = radii(lat)
    cl, sl = math.cos(lat), math.sin(lat)
    return np.array(
        [(rn + h) * cl * math.cos(lon), (rn + h) * cl * math.sin(lon), (rn * (1.0 - E2_WGS84) + h) * sl]
    )


def ecef_to_geodetic(x: float, y: float, z: float) -> tuple[float, float, float]:
    """ECEF (m) to WGS-84 geodetic (rad, rad, m): the fixed-point iteration of latitude and height (Heiskanen &
    Moritz 1967, Physical Geodesy, eq. 5-27); five iterations reach 1e-12 rad for terrestrial heights."""
    p = math.hypot(x, y)
    lon = math.atan2(y, x)
    lat = math.atan2(z, p * (1.0 - E2_WGS84))
    h = 0.0
    for _ in range(5):
        rn = A_WGS84 / math.sqrt(1.0 - E2_WGS84 * math.sin(lat) ** 2)
        if abs(lat) < math.radians(89.0):
            h = p / math.cos(lat) - rn
        else:  # near a pole: from z (cos lat -> 0)
            h = abs(z) / abs(math.sin(lat)) - rn * (1.0 - E2_WGS84)
        lat = math.atan2(z, p * (1.0 - E2_WGS84 * rn / (rn + h)))
    return lat, lon, h
