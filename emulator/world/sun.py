"""Sun truth from NREL SPA (Reda & Andreas 2004, corrigendum 2007) through ``pvlib.spa``.

:class:`SunModel` gives the geometric (unrefracted, topocentric) unit sun vector in ENU and its
azimuth/elevation for a scenario time and an observer position (``docs/reference/algorithms.md``
section 3: ``S^n = [sin(Az) cos(el), cos(Az) cos(el), sin(el)]``, Az clockwise
from north).

Evaluating the full SPA costs ~4 ms per call, too much for the 5 Hz polarization sensors of a
fast-mode run. SPA's *geocentric* part (apparent sidereal time ``v``, geocentric right ascension
``alpha`` and declination ``delta``, Earth-Sun distance ``R``; SPA steps 1-10 and 12-13) is
therefore evaluated by ``pvlib.spa`` on 60 s nodes, an hour at a time, and interpolated
linearly (the curvature of these quantities over 60 s is below 1e-7 deg). The topocentric part
is done here with vectors: the Sun at Greenwich hour angle ``v - alpha`` and distance ``R`` in
ECEF, minus the observer's WGS-84 ECEF position, projected on the local geodetic ENU axes. This
is SPA's own parallax correction in vector form; the test suite checks it against
``pvlib.spa.solar_position`` (< 1e-4 deg) and against skyfield with the DE421 ephemeris
(< 0.01 deg).
"""

from __future__ import annotations

import datetime as _dt
import math

import numpy as np
from pvlib import spa

from protocols.constants import DEG

from . import geodesy

__all__ = ["AU_M", "SunModel", "sun_vector_from_az_el"]

#: Astronomical unit, m (IAU 2012).
AU_M = 149_597_870_700.0
NODE_STEP_S = 60.0
CHUNK_NODES = 61  # one hour per chunk


def sun_vector_from_az_el(az: float, el: float) -> np.ndarray:
    """ENU unit vector from azimuth (clockwise from north) and elevation, rad."""
    ce = math.cos(el)
    return np.array([math.sin(az) * ce, math.cos(az) * ce, math.sin(el)])


class SunModel:
    """Topocentric geometric sun direction (see module docstring).

    Parameters
    ----------
    epoch : UTC time of scenario t = 0 (timezone-aware).
    delta_t_s : TT - UT1 (s); None uses ``pvlib.spa.calculate_deltat`` for the epoch's month.
    """

    def __init__(self, epoch: _dt.datetime, delta_t_s: float | None = None) -> None:
        if epoch.tzinfo is None:
            raise ValueError("SunModel needs a timezone-aware epoch")
        self.epoch = epoch
        self.unix0 = epoch.timestamp()
        if delta_t_s is None:
            delta_t_s = float(spa.calculate_deltat(epoch.year, epoch.month))
        self.delta_t_s = float(delta_t_s)
        self._chunks: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = {}

    # -- SPA geocentric part ----------------------------------------------------------------
    def geocentric_exact(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """SPA's ``v`` (apparent sidereal time), ``alpha``, ``delta`` (deg) and ``R`` (AU) at scenario times ``t``."""
        ut = self.unix0 + np.atleast_1d(np.asarray(t, dtype=np.float64))
        v, alpha, delta = spa.solar_position_numpy(ut, 0.0, 0.0, 0.0, 1013.25, 12.0, self.delta_t_s, 0.5667,
                                                   1, sst=True)
        jd = spa.julian_day(ut)
        jde = spa.julian_ephemeris_day(jd, self.delta_t_s)
        jme = spa.julian_ephemeris_millennium(spa.julian_ephemeris_century(jde))
        r = spa.heliocentric_radius_vector(jme)
        return np.asarray(v), np.asarray(alpha), np.asarray(delta), np.asarray(r)

    def _chunk(self, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        c = self._chunks.get(k)
        if c is None:
            t = (k * (CHUNK_NODES - 1) + np.arange(CHUNK_NODES)) * NODE_STEP_S
            v, alpha, delta, r = self.geocentric_exact(t)
            gha = np.unwrap(np.mod(v - alpha, 360.0), period=360.0)
            c = (t, gha, delta, r)
            if len(self._chunks) > 48:
                self._chunks.clear()
            self._chunks[k] = c
        return c

    def geocentric(self, t: float) -> tuple[float, float, float]:
        """Interpolated Greenwich hour angle (deg), declination (deg) and distance (AU) at scenario time ``t``."""
        span = (CHUNK_NODES - 1) * NODE_STEP_S
        k = math.floor(t / span)
        tn, gha, delta, r = self._chunk(k)
        i = min(max(int((t - tn[0]) / NODE_STEP_S), 0), CHUNK_NODES - 2)
        s = (t - tn[i]) / NODE_STEP_S
        return (gha[i] + s * (gha[i + 1] - gha[i]), delta[i] + s * (delta[i + 1] - delta[i]),
                r[i] + s * (r[i + 1] - r[i]))

    # -- topocentric ------------------------------------------------------------------------
    def sun_enu(self, t: float, lat: float, lon: float, h: float) -> np.ndarray:
        """Unit geometric sun vector in ENU at scenario time ``t`` for an observer at ``lat, lon`` (rad), ``h`` (m)."""
        gha, dec, r_au = self.geocentric(t)
        lam_s = -gha * DEG
        cd = math.cos(dec * DEG)
        r = r_au * AU_M
        sun = np.array([r * cd * math.cos(lam_s), r * cd * math.sin(lam_s), r * math.sin(dec * DEG)])
        s = geodesy.ecef_to_enu_vector(sun - geodesy.geodetic_to_ecef(lat, lon, h), lat, lon)
        unit: np.ndarray = s / float(np.linalg.norm(s))
        return unit

    def az_el(self, t: float, lat: float, lon: float, h: float) -> tuple[float, float]:
        """Azimuth (clockwise from north, [0, 2 pi)) and geometric elevation, rad."""
        s = self.sun_enu(t, lat, lon, h)
        return math.atan2(s[0], s[1]) % (2.0 * math.pi), math.asin(max(-1.0, min(1.0, float(s[2]))))

    def spa_az_el(self, t: float, lat: float, lon: float, h: float, pressure_hpa: float = 1013.25,
                  temperature_c: float = 12.0) -> tuple[float, float, float]:
        """Full ``pvlib.spa.solar_position`` (slow): azimuth, elevation, apparent (refracted) elevation, deg."""
        r = spa.solar_position_numpy(np.array([self.unix0 + t]), lat / DEG, lon / DEG, h, pressure_hpa,
                                     temperature_c, self.delta_t_s, 0.5667, 1)
        return float(r[4][0]), float(r[3][0]), float(r[2][0])
