"""Input validation at the firmware boundary (docs/hostile-input.md).

Every decoded message is checked here before any of its fields reaches the navigation: finite numbers, physical
ranges, valid dates and times (a leap second ``sec = 60`` is legal), plausible IMU words and time-stamp steps. A
check returns the *reason* a message is refused (a short snake-case string, counted by the loop as
``input_rejected_<reason>``) or None when the message may be used.

The checks are pure functions of the message (and, for the IMU time stamp, of the previous accepted stamp); they
hold no state, so the same functions serve the fuzz harness (``tests/fuzz``).
"""

from __future__ import annotations

import datetime as _dt
import math
from typing import Any

from protocols.stim import STATUS_SAMPLE_INVALID

__all__ = [
    "ALT_MAX_M",
    "ALT_MIN_M",
    "GEOID_MAX_M",
    "GST_STD_MAX_M",
    "IMU_STEP_MAX_FACTOR",
    "S24_MAX",
    "S24_MIN",
    "SPEED_MAX_MPS",
    "check_gga",
    "check_gst",
    "check_gyro_status",
    "check_imu_range",
    "check_imu_step",
    "check_imu_words",
    "check_nav_pvt",
    "check_rmc",
    "nav_pvt_datetime",
]

#: Height above the ellipsoid accepted from a receiver, m (below the Dead Sea shore minus margin; above an airliner's
#: ceiling with margin: COCOM limits a receiver to 18 km anyway).
ALT_MIN_M = -1000.0
ALT_MAX_M = 60_000.0
#: A receiver's own estimate of its position error (GST standard deviations) accepted, m: worse than 10 km is not
#: a fix (a value above it is refused, not clipped: the sentence says nothing usable).
GST_STD_MAX_M = 10_000.0
#: ``|geoid separation|`` accepted, m (EGM96 spans -107 .. +86 m).
GEOID_MAX_M = 200.0
#: Ground speed accepted, m/s (COCOM limit 515 m/s plus margin).
SPEED_MAX_MPS = 600.0
#: A 24-bit word at either rail is a saturated (clipped) sample, not a measurement.
S24_MAX = 2**23 - 1
S24_MIN = -(2**23)
#: An IMU time-stamp step above this many nominal periods (or not positive) is refused (a dropped frame or two is
#: a gap, counted by the loop; a jump of seconds is a corrupt stamp).
IMU_STEP_MAX_FACTOR = 50


def _finite(*xs: float | None) -> bool:
    return all(x is None or math.isfinite(x) for x in xs)


def _time_ok(t: _dt.time | None) -> bool:
    return t is None or isinstance(t, _dt.time)


def check_gga(s: Any) -> str | None:
    """Reason a GGA with a fix is refused, or None. (A GGA with quality 0 carries no fix and is not checked.)"""
    reason = check_gns(s)
    if reason is None and not 0 <= s.quality <= 9:
        return "quality"
    return reason


def check_gns(s: Any) -> str | None:
    """Reason a GNS (or the position part of a GGA) is refused, or None: finite values, latitude, longitude,
    geoid separation and ellipsoidal height in range (GNS has modes instead of a quality)."""
    if not _finite(s.lat_deg, s.lon_deg, s.altitude_msl_m, s.geoid_sep_m, s.hdop):
        return "not_finite"
    if s.lat_deg is not None and not -90.0 <= s.lat_deg <= 90.0:
        return "latitude"
    if s.lon_deg is not None and not -180.0 <= s.lon_deg <= 180.0:
        return "longitude"
    if s.geoid_sep_m is not None and abs(s.geoid_sep_m) > GEOID_MAX_M:
        return "height"
    if s.altitude_msl_m is not None and not ALT_MIN_M <= s.altitude_msl_m + (s.geoid_sep_m or 0.0) <= ALT_MAX_M:
        return "height"
    return None


def check_gst(s: Any) -> str | None:
    """Reason a GST's latitude and longitude error estimates are refused, or None: finite, and 0 to
    :data:`GST_STD_MAX_M` (the caller reads a zero as no estimate: a receiver without redundancy, a placeholder)."""
    if not _finite(s.lat_m, s.lon_m):
        return "not_finite"
    if not (0.0 <= s.lat_m <= GST_STD_MAX_M and 0.0 <= s.lon_m <= GST_STD_MAX_M):
        return "gst_range"
    return None


def check_rmc(s: Any) -> str | None:
    """Reason an RMC is refused, or None."""
    if not _finite(s.lat_deg, s.lon_deg, s.speed_mps, s.course_deg):
        return "not_finite"
    if s.lat_deg is not None and not -90.0 <= s.lat_deg <= 90.0:
        return "latitude"
    if s.lon_deg is not None and not -180.0 <= s.lon_deg <= 180.0:
        return "longitude"
    if s.speed_mps is not None and not 0.0 <= s.speed_mps <= SPEED_MAX_MPS:
        return "speed"
    if s.course_deg is not None and not 0.0 <= s.course_deg <= 360.0:
        return "course"
    if s.date is not None and not 2000 <= s.date.year <= 2099:
        return "date"
    return None


def nav_pvt_datetime(p: Any) -> tuple[_dt.date, _dt.time] | None:
    """The UTC date and time of a NAV-PVT, None when a field is out of range.

    A leap second (``sec = 60``, which u-blox receivers send at 23:59:60) is legal: it maps to 23:59:59.999999
    (``datetime`` has no 61st second; the 1 s of UT1-UTC ambiguity is far below the ephemeris' need)."""
    if not (2000 <= p.year <= 2099 and 1 <= p.month <= 12 and 0 <= p.hour <= 23 and 0 <= p.min <= 59
            and 0 <= p.sec <= 60):
        return None
    try:
        date = _dt.date(p.year, p.month, p.day)
    except ValueError:  # day 0, 31 April, 29 February of a common year
        return None
    if p.sec == 60:
        return date, _dt.time(p.hour, p.min, 59, 999_999)
    return date, _dt.time(p.hour, p.min, p.sec)


def check_nav_pvt(p: Any) -> str | None:
    """Reason the position/velocity of a NAV-PVT is refused, or None (its date and time: :func:`nav_pvt_datetime`)."""
    if not -900_000_000 <= p.lat <= 900_000_000:
        return "latitude"
    if not -1_800_000_000 <= p.lon <= 1_800_000_000:
        return "longitude"
    if not ALT_MIN_M <= p.height * 1e-3 <= ALT_MAX_M:
        return "height"
    if max(abs(p.velN), abs(p.velE), abs(p.velD)) * 1e-3 > SPEED_MAX_MPS:
        return "speed"
    if not -1_000_000_000 < p.nano < 1_000_000_000:
        return "time"
    return None


def check_imu_words(gyro: tuple[int, int, int], accel: tuple[int, int, int]) -> str | None:
    """Reason the inertial words of an IMU frame are refused (a word at a 24-bit rail: saturated), or None."""
    g0, g1, g2 = gyro
    if not (S24_MIN < g0 < S24_MAX and S24_MIN < g1 < S24_MAX and S24_MIN < g2 < S24_MAX):
        return "gyro_saturated"
    a0, a1, a2 = accel
    if not (S24_MIN < a0 < S24_MAX and S24_MIN < a1 < S24_MAX and S24_MIN < a2 < S24_MAX):
        return "accel_saturated"
    return None


def check_gyro_status(status: int) -> str | None:
    """Reason a gyro sample is refused by its own STATUS byte (``gyro_status``: overload, a measurement-channel
    error, start-up or a system integrity error, :data:`protocols.stim.STATUS_SAMPLE_INVALID`), or None."""
    return "gyro_status" if status & STATUS_SAMPLE_INVALID else None


def check_imu_range(gyro: tuple[int, int, int], accel: tuple[int, int, int], gyro_max: int,
                    accel_max: tuple[int, int, int]) -> tuple[str | None, str | None]:
    """Reasons (gyro, accel) the words of an IMU frame lie beyond the fitted units' measurement ranges, or None
    each. ``gyro_max``: the largest gyro word magnitude the configured range gives (LSB); ``accel_max``: the largest
    ADC code magnitude per axis. A word within the 24-bit rails but beyond the range (e.g. 512 deg/s from a
    +-400 deg/s STIM210) is not a measurement of that unit."""
    g0, g1, g2 = gyro
    g = None if max(abs(g0), abs(g1), abs(g2)) <= gyro_max else "gyro_range"
    a0, a1, a2 = accel
    a = None if abs(a0) <= accel_max[0] and abs(a1) <= accel_max[1] and abs(a2) <= accel_max[2] else "accel_range"
    return g, a


def check_imu_step(step_us: int, period_us: float) -> str | None:
    """Reason an IMU time-stamp step (unwrapped, us) is refused, or None."""
    if step_us <= 0 or step_us > IMU_STEP_MAX_FACTOR * period_us:
        return "imu_time_step"
    return None
