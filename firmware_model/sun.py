"""Sun ephemeris as the DSP runs it: Grena (2012) Algorithm 5.

R. Grena, "Five new algorithms for the computation of sun position from 2010 to 2110",
Solar Energy 86(5):1323-1337, 2012, doi:10.1016/j.solener.2012.01.024. Algorithm 5 is the most
accurate of the five: maximum error 0.0027 deg against SPA over 2010-2110 (the paper's figure;
``tests/firmware_model/test_sun.py`` checks < 0.01 deg against pvlib's SPA). Written here from the
paper's description; the coefficient values are the paper's.

Time scale: ``t`` = days of Universal Time since 2060-01-01 00:00 UT (the paper's origin, the middle
of its validity range); ``t_e = t + Delta_tau / 86400`` is Terrestrial Time, with the paper's linear
Delta_tau extrapolation ``96.4 + 0.00158 t`` s. UTC is used for UT (``|UT1 - UTC| < 0.9 s``, i.e.
< 0.004 deg of hour angle, the same assumption SPA users make when they pass UTC).

Output: the topocentric unit sun vector in ENU, ``S^n = [sin Az cos el, cos Az cos el, sin el]``
(docs/reference/algorithms.md section 0; Az clockwise from North, el without refraction, as the geometric
vector the polarization pattern follows). It is formed directly from declination and hour angle,
so no atan2/asin is needed for the vector.

Precision as a C6747 firmware would write it (charged in :func:`ephemeris_cycles`): the time
``t`` (``|t| < 2e4`` days) and every phase that grows with it (``1.72e-2 t``, ``6.3 t``: up to 1.3e5 rad)
need double precision, since float32 would lose 0.008 rad at 1e5 rad. Each phase is reduced
modulo 2 pi in double precision and the sines/cosines of the reduced angles, the small periodic
terms and the final rotation to ENU are single precision.
"""

from __future__ import annotations

import datetime as _dt
import functools
import math

import numpy as np

from . import c674x
from .arrays import FloatArray, FloatDtype
from .units import TWO_PI

__all__ = [
    "GRENA_T0",
    "delta_tau_s",
    "ephemeris_cycles",
    "grena_days",
    "grena_days_from_datetime",
    "sun_az_el",
    "sun_equatorial",
    "sun_vector_enu",
]

#: Origin of Grena's time scale.
GRENA_T0 = _dt.datetime(2060, 1, 1, tzinfo=_dt.UTC)
#: Earth radius over astronomical unit, the parallax factor of the elevation (paper: 4.26e-5).
PARALLAX = 4.26e-5

# Algorithm 5 heliocentric-longitude coefficients (Grena 2012, Table 5 / section 3.5).
_L0, _L1 = 1.7527901, 1.7202792159e-2
_OMEGA_A = 0.0172019715  # rad/day, anomalistic year
_A = (3.33024e-2, 3.512e-4, 5.2e-6)  # sin(k w t)
_B = (-2.0582e-3, -4.07e-5, -9e-7)  # cos(k w t)
_BETA, _DBETA = 2.92e-5, -8.23e-5  # slow modulation of the first harmonic
_OMEGA = (1.49e-3, 4.31e-3, 1.076e-2, 1.575e-2, 2.152e-2, 3.152e-2, 2.1277e-1)  # rad/day (planets, Moon)
_D = (1.27e-5, 1.21e-5, 2.33e-5, 3.49e-5, 2.67e-5, 1.28e-5, 3.14e-5)  # rad
_PHI = (-2.337, 3.065, -1.533, -2.358, 0.074, 1.547, -0.488)  # rad
_OMEGA_N, _NU0 = 9.282e-4, -0.8  # nutation: longitude of the Moon's ascending node
_DLAMBDA = 8.34e-5
_EPS0, _EPS1, _DEPS = 4.089567e-1, -6.19e-9, 4.46e-5
_H0, _H1 = 1.7528311, 6.300388099  # Greenwich sidereal angle, rad and rad/day
_H_NUT = 0.92  # equation of the equinoxes factor on the nutation in longitude


def grena_days(year: int, month: int, day: int, hour_ut: float) -> float:
    """Grena's ``t`` (days of UT since 2060-01-01 00:00) from a Gregorian date (paper Eq. 1).

    Integer truncations as in the paper; valid 2000-2199 (the ``0.01 y`` term is the
    Gregorian century rule for that range).
    """
    y, m = year, month
    if m <= 2:
        m += 12
        y -= 1
    return (
        int(365.25 * (y - 2000)) + int(30.6001 * (m + 1)) - int(0.01 * y) + day + hour_ut / 24.0 - 21958.0
    )


def grena_days_from_datetime(t: _dt.datetime) -> float:
    """``t`` for a timezone-aware datetime (converted to UTC)."""
    u = t.astimezone(_dt.UTC)
    hour = u.hour + u.minute / 60.0 + (u.second + u.microsecond * 1e-6) / 3600.0
    return grena_days(u.year, u.month, u.day, hour)


def delta_tau_s(t_days: float) -> float:
    """TT - UT, s: the paper's linear extrapolation ``96.4 + 0.00158 t``."""
    return 96.4 + 0.00158 * t_days


def _reduce(x: float) -> float:
    """Angle modulo 2 pi in double precision (what ``fmod`` costs on the DSP: 1 DIVDP-class op)."""
    return x - TWO_PI * math.floor(x / TWO_PI)


def sun_equatorial(t_days: float, dtype: FloatDtype = np.float32) -> tuple[float, float, float]:
    """Geocentric apparent declination, Greenwich hour angle and nutation in longitude.

    Parameters
    ----------
    t_days : Grena ``t`` (float64, days of UT since 2060-01-01).
    dtype : working precision of the single-precision stages (float32 on the DSP).

    Returns
    -------
    (sin_delta, cos_delta, H_greenwich) : declination as sine/cosine and the Greenwich hour angle
    (rad, reduced to [0, 2 pi)). The local hour angle is ``H_greenwich + lambda``.
    """
    sp = dtype
    te = t_days + delta_tau_s(t_days) / 86400.0  # DP
    wte = _reduce(_OMEGA_A * te)  # DP phase, reduced
    s1 = float(sp(math.sin(float(sp(wte)))))
    c1 = float(sp(math.cos(float(sp(wte)))))
    s2 = 2.0 * s1 * c1
    c2 = (c1 + s1) * (c1 - s1)
    s3 = s2 * c1 + c2 * s1
    c3 = c2 * c1 - s2 * s1
    # periodic part (all terms < 0.034 rad: single precision is ample)
    per = _A[0] * s1 + _B[0] * c1 + _A[1] * s2 + _B[1] * c2 + _A[2] * s3 + _B[2] * c3
    per += _DBETA * s1 * math.sin(float(sp(_BETA * te)))
    for om, d, ph in zip(_OMEGA, _D, _PHI):
        per += d * math.sin(float(sp(_reduce(om * te + ph))))
    nu = _reduce(_OMEGA_N * te + _NU0)
    snu, cnu = math.sin(float(sp(nu))), math.cos(float(sp(nu)))
    dlam = _DLAMBDA * snu
    # ecliptic longitude of the Sun: secular part in DP, reduced, then SP
    lam = float(sp(_reduce(_L0 + _L1 * te) + float(sp(per)) + math.pi + dlam))
    eps = float(sp(_EPS0 + _EPS1 * te + _DEPS * cnu))
    sl, cl = float(sp(math.sin(lam))), float(sp(math.cos(lam)))
    se, ce = float(sp(math.sin(eps))), float(sp(math.cos(eps)))
    # right ascension and declination (alpha = atan2(sl ce, cl); delta = asin(sl se))
    sin_d = sl * se
    cos_d = math.sqrt(max(0.0, 1.0 - sin_d * sin_d))
    alpha = math.atan2(sl * ce, cl)
    gha = _reduce(_H0 + _H1 * t_days) + _H_NUT * dlam - alpha  # sidereal phase in DP
    return float(sp(sin_d)), float(sp(cos_d)), _reduce(gha)


def sun_vector_enu(t_days: float, lat: float, lon: float, dtype: FloatDtype = np.float32) -> FloatArray:
    """Topocentric unit sun vector in ENU at latitude/longitude (rad), no refraction.

    ``E = -cos d sin H``, ``N = cos L sin d - sin L cos d cos H``, ``U = sin L sin d + cos L cos d cos H``
    with the local hour angle ``H = GHA + lambda``; then the parallax lowers the elevation by
    ``4.26e-5 cos(el)`` (Grena's topocentric correction). Shape (3,), ``dtype``.
    """
    sin_d, cos_d, gha = sun_equatorial(t_days, dtype)
    h = float(dtype(_reduce(gha + lon)))
    sh, ch = math.sin(h), math.cos(h)
    sl, cl = math.sin(lat), math.cos(lat)
    e = -cos_d * sh
    n = cl * sin_d - sl * cos_d * ch
    u = sl * sin_d + cl * cos_d * ch
    # parallax: el' = el - p cos(el): U -= p cos^2(el), horizontal grows by (1 + p U)
    k = 1.0 + PARALLAX * u
    u = u - PARALLAX * (1.0 - u * u)
    return np.array([e * k, n * k, u], dtype=dtype)


def sun_az_el(t_days: float, lat: float, lon: float) -> tuple[float, float]:
    """Azimuth (rad, clockwise from North, [0, 2 pi)) and elevation (rad), for reports and tests."""
    s = sun_vector_enu(t_days, lat, lon, dtype=np.float64)
    return math.atan2(s[0], s[1]) % TWO_PI, math.asin(max(-1.0, min(1.0, float(s[2]))))


@functools.cache
def ephemeris_cycles() -> int:
    """C674x cycles of one :func:`sun_vector_enu` call [D from S figures].

    Double precision: 12 phases ``a + b t`` (MPYDP + ADDDP each) and their reduction modulo 2 pi
    (one ``recipdp``-class multiply, a truncation and a MPYDP/SUBDP each: charged as ``divdp``), the
    TT/UT step: ``dp_flops(30, 30) + 13 divdp``. Single precision: 11 ``sinsp``, 5 ``cossp``,
    1 ``atan2sp``, 1 ``sqrtsp`` and ~60 FLOPs of periodic sums and the ENU rotation.
    MATHLIB inline figures [S, R2].
    """
    return (
        c674x.dp_flops(30, 30)
        + c674x.mathlib("divdp", 13)
        + c674x.mathlib("sinsp", 11)
        + c674x.mathlib("cossp", 5)
        + c674x.mathlib("atan2sp")
        + c674x.mathlib("sqrtsp")
        + c674x.flops(40, 30)
    )
