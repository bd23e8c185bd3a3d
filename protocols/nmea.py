"""NMEA 0183 sentences: framing, checksum, GGA, GNS, RMC, VTG, GSA and ZDA.

Source: ``docs/reference/wire-formats.md`` section 2.3 (gpsd NMEA notes; field order as in
pynmea2). A sentence is ``$`` + talker (2 letters) + type (3 letters) + ``,``-separated fields
+ ``*`` + two upper-case hex digits (XOR of every byte strictly between ``$`` and ``*``)
+ ``<CR><LF>``; at most 82 characters including ``$`` and ``<CR><LF>``. Proprietary sentences
start ``$P`` + a three-letter maker code (``$PSNSPOS``: maker ``SNS``); they are framed and
checked the same way and come out as :class:`NmeaSentence` with ``talker="PSNS"``.

What real receivers send beyond the standard (docs/icd.md "GNSS input" and "NMEA sentences: parsed, used,
counted"): a line ended by LF alone (the checksum then sits at ``[-4:-2]``) is accepted and counted in
:attr:`NmeaFormat.lf_only`; a receiving decoder built with ``max_len=NMEA_RX_MAX_LEN`` accepts the long sentences
of real receivers (u-blox ``$PUBX,00`` is 108-110 characters, ``$PUBX,03`` hundreds, MediaTek ``$PMTKCHN`` 204);
trailing fields may be omitted, GSV blocks may be empty, proprietary addresses may hold spaces, and a no-fix
sentence's placeholder position is read as absent. Time and date fields are range-checked (a parse error).
GNS (NMEA 3.0/4.10: one mode character per constellation) is typed as :class:`Gns`.

The builders and their number formats are in :mod:`protocols.nmea_build` (re-exported here). Every typed
sentence re-encodes with :func:`encode_nmea`; for sentences written by these
builders ``encode_nmea(parse(b)) == b`` holds byte for byte (the golden vectors check it).
"""

from __future__ import annotations

import datetime as _dt
import math
import re
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from ._fastinit import fast_frozen_init
from .crc import nmea_checksum
from .nmea_build import (
    KNOT_MPS,
    NMEA_MAX_LEN,
    build_gga,
    build_gsa,
    build_gst,
    build_gsv,
    build_rmc,
    build_sentence,
    build_vtg,
    build_zda,
    format_lat,
    format_lon,
)
from .stream import BAD_LENGTH, NEED_MORE

#: Longest line a receiving decoder accepts: the 82 of the standard plus the proprietary and
#: high-precision sentences of real receivers. In the receiver corpus (tests/protocols/corpus/receivers/):
#: MediaTek ``$PMTKCHN`` 204 characters, u-blox ``$PUBX,03`` 424 with 23 satellites (about 18 more per
#: satellite tracked); 1024, the most :func:`sentence_ok_fast` folds, holds ``$PUBX,03`` with 50 satellites.
NMEA_RX_MAX_LEN = 1024

__all__ = [
    "KNOT_MPS",
    "NMEA_MAX_LEN",
    "NMEA_RX_MAX_LEN",
    "Gga",
    "Gns",
    "Gsa",
    "Gst",
    "Gsv",
    "NmeaFormat",
    "NmeaSentence",
    "Rmc",
    "Vtg",
    "Zda",
    "build_gga",
    "build_gsa",
    "build_gsv",
    "build_rmc",
    "build_sentence",
    "build_vtg",
    "build_zda",
    "encode_nmea",
    "format_lat",
    "format_lon",
    "sentence_ok",
    "sentence_ok_fast",
]


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class NmeaSentence:
    """Any checked NMEA sentence: talker (``GP``, or ``PSNS`` for proprietary), type and raw fields."""

    talker: str
    kind: str
    fields: tuple[str, ...]


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class Gga:
    """GGA fix data. Angles in degrees (south/west negative); ``altitude_msl_m`` above MSL."""

    talker: str
    time_utc: _dt.time | None
    lat_deg: float | None
    lon_deg: float | None
    quality: int
    num_sats: int | None
    hdop: float | None
    altitude_msl_m: float | None
    geoid_sep_m: float | None


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class Gns:
    """GNS fix data (NMEA 3.0 / 4.10): ``mode`` has one character per constellation (GPS, GLONASS, Galileo,
    BeiDou, ...): N none, A autonomous, D differential, P precise, R RTK fixed, F RTK float, E estimated (DR),
    M manual, S simulator. ``nav_status`` (4.10: S safe, C caution, U unsafe, V not valid) or None."""

    talker: str
    time_utc: _dt.time | None
    lat_deg: float | None
    lon_deg: float | None
    mode: str
    num_sats: int | None
    hdop: float | None
    altitude_msl_m: float | None
    geoid_sep_m: float | None
    nav_status: str | None


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class Rmc:
    """RMC recommended minimum data. Speed in m/s, course in degrees clockwise from true north."""

    talker: str
    time_utc: _dt.time | None
    valid: bool
    lat_deg: float | None
    lon_deg: float | None
    speed_mps: float | None
    course_deg: float | None
    date: _dt.date | None
    mode: str | None
    #: NMEA 4.10 navigational status (13th field), None in the 2.3 layout
    nav_status: str | None = None


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class Vtg:
    """VTG course over ground and ground speed (m/s, from the knots field), FAA mode letter."""

    talker: str
    course_true_deg: float | None
    course_mag_deg: float | None
    speed_mps: float | None
    mode: str | None


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class Gsa:
    """GSA DOP and active satellites: ``mode`` M/A, ``fix_type`` 1 none / 2 2D / 3 3D, 12 ID slots."""

    talker: str
    mode: str
    fix_type: int
    sat_ids: tuple[int | None, ...]
    pdop: float | None
    hdop: float | None
    vdop: float | None
    #: NMEA 4.10 GNSS system id (18th field: 1 GPS, 2 GLONASS, 3 Galileo, 4 BeiDou), None in the 2.3 layout
    system_id: int | None = None


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class Gst:
    """GST pseudorange error statistics (NMEA 0183, the sentence that supports RAIM): ``rms_m`` the RMS of the
    standard deviations of the range inputs (m); the error ellipse's semi-major and semi-minor standard deviations
    (m) and the semi-major axis' orientation (deg from true north); the standard deviations of the latitude,
    longitude and altitude errors (m, 1 sigma). Empty fields are None."""

    talker: str
    time_utc: _dt.time | None
    rms_m: float | None
    major_m: float | None
    minor_m: float | None
    orient_deg: float | None
    lat_m: float | None
    lon_m: float | None
    alt_m: float | None


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class Gsv:
    """One GSV sentence: ``sats`` = (number, elevation deg, azimuth deg, C/N0 dBHz) with None for empty fields;
    ``signal_id`` (NMEA 4.10) or None."""

    talker: str
    num_msgs: int
    msg_num: int
    num_sv: int
    sats: tuple[tuple[int, int | None, int | None, int | None], ...]
    signal_id: int | None = None


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class Zda:
    """ZDA UTC time and date with the local zone offset (hours, minutes)."""

    talker: str
    time_utc: _dt.time | None
    date: _dt.date | None
    zone_hours: int | None
    zone_minutes: int | None


def _parse_time_uncached(s: str) -> _dt.time:
    """``hhmmss[.s...]`` (UTC) as a time, refused (``ValueError``) unless it is six ASCII digits, optionally a point
    and digits, with hh < 24, mm < 60 and ss < 61. Second 60 (a leap second, NMEA allows it) is held at
    hh:mm:59.999999, as the firmware boundary holds NAV-PVT's (docs/hostile-input.md); fractions beyond the
    microsecond are cut. No number of the field goes through float, so no token can overflow."""
    frac = s[7:]
    if not (len(s) >= 6 and s.isascii() and s[:6].isdigit() and (len(s) == 6 or s[6] == ".")
            and (not frac or frac.isdigit())):
        raise ValueError(f"bad NMEA time {s!r}")
    hh, mm, ss = int(s[0:2]), int(s[2:4]), int(s[4:6])
    if hh > 23 or mm > 59 or ss > 60:
        raise ValueError(f"NMEA time {s!r} out of range")
    if ss == 60:
        return _dt.time(hh, mm, 59, 999_999)
    return _dt.time(hh, mm, ss, int(frac[:6].ljust(6, "0")) if frac else 0)


# A receiver repeats one epoch's time and date in several sentences (RMC, GGA, ZDA): small
# caches of the last few strings save most of the datetime work on a stream.
_TIME_CACHE: dict[str, _dt.time] = {}
_DATE_CACHE: dict[str, _dt.date] = {}
_CACHE_MAX = 64


def _parse_time(s: str) -> _dt.time | None:
    if not s:
        return None
    t = _TIME_CACHE.get(s)
    if t is None:
        t = _parse_time_uncached(s)
        if len(_TIME_CACHE) >= _CACHE_MAX:
            _TIME_CACHE.clear()
        _TIME_CACHE[s] = t
    return t


def encode_nmea(obj: Gga | Gns | Gsv | Rmc | Vtg | Gsa | Gst | Zda | NmeaSentence) -> bytes:
    """Encode any object :class:`NmeaFormat` decodes (the inverse of its ``parse``)."""
    if isinstance(obj, Gsv):
        fields = [str(obj.num_msgs), str(obj.msg_num), f"{obj.num_sv:02d}"]
        for prn, elev, az, snr in obj.sats:
            fields += [f"{prn:02d}", "" if elev is None else f"{elev:02d}", "" if az is None else f"{az:03d}",
                       "" if snr is None else f"{snr:02d}"]
        if obj.signal_id is not None:
            fields.append(f"{obj.signal_id:X}")
        return build_sentence(obj.talker, "GSV", fields)
    if isinstance(obj, Gns):
        fields = [_format_time_nmea(obj.time_utc), *format_lat(obj.lat_deg or 0.0), *format_lon(obj.lon_deg or 0.0),
                  obj.mode, "" if obj.num_sats is None else f"{obj.num_sats:02d}", _opt_f(obj.hdop, ".2f"),
                  _opt_f(obj.altitude_msl_m, ".3f"), _opt_f(obj.geoid_sep_m, ".3f"), "", ""]
        if obj.lat_deg is None:
            fields[1:5] = ["", "", "", ""]
        if obj.nav_status is not None:
            fields.append(obj.nav_status)
        return build_sentence(obj.talker, "GNS", fields)
    if isinstance(obj, Gga):
        if obj.quality == 0:
            return build_gga(obj.time_utc or _dt.time(), 0.0, 0.0, 0.0, 0.0, quality=0, talker=obj.talker)
        return build_gga(obj.time_utc or _dt.time(), obj.lat_deg or 0.0, obj.lon_deg or 0.0, obj.altitude_msl_m or 0.0,
                         obj.geoid_sep_m or 0.0, obj.quality, obj.num_sats or 0, obj.hdop or 0.0, obj.talker)
    if isinstance(obj, Rmc):
        date = obj.date or _dt.date(2000, 1, 1)
        return build_rmc(obj.time_utc or _dt.time(), date, obj.lat_deg or 0.0, obj.lon_deg or 0.0, obj.speed_mps or 0.0,
                         obj.course_deg or 0.0, valid=obj.valid, mode=obj.mode or "", talker=obj.talker,
                         nav_status=obj.nav_status)
    if isinstance(obj, Vtg):
        return build_vtg(obj.course_true_deg, obj.speed_mps, obj.mode or "", obj.course_mag_deg, obj.talker)
    if isinstance(obj, Gsa):
        return build_gsa(obj.fix_type, obj.sat_ids, obj.pdop, obj.hdop, obj.vdop, obj.mode, obj.talker,
                         system_id=obj.system_id)
    if isinstance(obj, Gst):
        return build_gst(obj.time_utc or _dt.time(), obj.rms_m, obj.major_m, obj.minor_m, obj.orient_deg, obj.lat_m,
                         obj.lon_m, obj.alt_m, obj.talker)
    if isinstance(obj, Zda):
        return build_zda(obj.time_utc or _dt.time(), obj.date or _dt.date(2000, 1, 1), obj.zone_hours,
                         obj.zone_minutes, obj.talker)
    return build_sentence(obj.talker, obj.kind, obj.fields)


def _format_time_nmea(t: _dt.time | None) -> str:
    if t is None:
        return ""
    return f"{t.hour:02d}{t.minute:02d}{t.second:02d}.{t.microsecond // 10000:02d}"


def _opt_f(v: float | None, fmt: str) -> str:
    return "" if v is None else format(v, fmt)


def _date_ddmmyy(d: str) -> _dt.date | None:
    """RMC's ``ddmmyy`` as 20yy-mm-dd; refused (``ValueError``) unless six ASCII digits of a real date. Which
    century and whether the date is believed is the firmware's business (a week rollover, an RTC date)."""
    if not d:
        return None
    v = _DATE_CACHE.get(d)
    if v is None:
        if not (len(d) == 6 and d.isascii() and d.isdigit()):
            raise ValueError(f"bad NMEA date {d!r}")
        v = _dt.date(2000 + int(d[4:6]), int(d[2:4]), int(d[0:2]))
        if len(_DATE_CACHE) >= _CACHE_MAX:
            _DATE_CACHE.clear()
        _DATE_CACHE[d] = v
    return v


# The typed parsers take the whole split sentence ``f`` (``f[0]`` is the address field).


def _lat(v: str, hemi: str) -> float | None:
    if not v:
        return None
    x = float(v)  # ddmm.mmmmm
    d = x // 100.0
    m = x - 100.0 * d
    if not (0.0 <= m < 60.0 and d >= 0.0):
        raise ValueError(f"bad latitude {v!r}")
    x = d + m / 60.0
    if hemi == "N":
        return x
    if hemi == "S":
        return -x
    raise ValueError(f"bad hemisphere {hemi!r}")


def _lon(v: str, hemi: str) -> float | None:
    if not v:
        return None
    x = float(v)  # dddmm.mmmmm
    d = x // 100.0
    m = x - 100.0 * d
    if not (0.0 <= m < 60.0 and d >= 0.0):
        raise ValueError(f"bad longitude {v!r}")
    x = d + m / 60.0
    if hemi == "E":
        return x
    if hemi == "W":
        return -x
    raise ValueError(f"bad hemisphere {hemi!r}")


def _pad(f: list[str], n: int) -> list[str]:
    """``f`` with omitted trailing fields as empty ones, up to ``n`` entries (address included)."""
    return f if len(f) >= n else f + [""] * (n - len(f))


def _position(f: list[str], i: int, fix: bool) -> tuple[float | None, float | None]:
    """Latitude and longitude from ``f[i:i + 4]``. With a fix a malformed value is refused (``ValueError``) and an
    out-of-range one is passed on for the firmware to refuse and count; without one (GGA quality 0, RMC ``V``, GNS
    mode all ``N``) the fields are a receiver's placeholder (``36000.0000,N,72000.0000,E``, ``8960.0000,N``, zeros)
    or a stale position: a malformed or out-of-range one is read as absent (None), not as an error."""
    if fix:
        return _lat(f[i], f[i + 1]), _lon(f[i + 2], f[i + 3])
    try:
        lat, lon = _lat(f[i], f[i + 1]), _lon(f[i + 2], f[i + 3])
    except ValueError:
        return None, None
    if lat is None or lon is None or not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0):
        return None, None
    return lat, lon


def _gga(talker: str, f: list[str]) -> Gga:
    """GGA; trailing fields may be omitted (a 13-field GGA of real receivers: they are None)."""
    if len(f) < 2:
        raise ValueError("GGA needs at least its time field")
    f = _pad(f, 15)
    quality = int(f[6] or 0)
    lat, lon = _position(f, 2, quality != 0)
    return Gga(
        talker,
        _TIME_CACHE.get(f[1]) or _parse_time(f[1]),
        lat,
        lon,
        quality,
        int(f[7]) if f[7] else None,
        float(f[8]) if f[8] else None,
        float(f[9]) if f[9] else None,
        float(f[11]) if f[11] else None,
    )


def _gns(talker: str, f: list[str]) -> Gns:
    """GNS; trailing fields may be omitted. A mode of N only (or empty) is no fix (the position may be absent)."""
    if len(f) < 2:
        raise ValueError("GNS needs at least its time field")
    f = _pad(f, 13)
    lat, lon = _position(f, 2, f[6].strip("N") != "")
    return Gns(
        talker,
        _TIME_CACHE.get(f[1]) or _parse_time(f[1]),
        lat,
        lon,
        f[6],
        int(f[7]) if f[7] else None,
        float(f[8]) if f[8] else None,
        float(f[9]) if f[9] else None,
        float(f[10]) if f[10] else None,
        f[13] if len(f) > 13 and f[13] else None,
    )


def _rmc(talker: str, f: list[str]) -> Rmc:
    """RMC; trailing fields may be omitted (status ``V`` or absent: no fix, the position may be absent)."""
    if len(f) < 2:
        raise ValueError("RMC needs at least its time field")
    f = _pad(f, 12)
    speed = f[7]
    valid = f[2] == "A"
    lat, lon = _position(f, 3, valid)
    return Rmc(
        talker,
        _TIME_CACHE.get(f[1]) or _parse_time(f[1]),
        valid,
        lat,
        lon,
        float(speed) * KNOT_MPS if speed else None,
        float(f[8]) if f[8] else None,
        _DATE_CACHE.get(f[9]) or _date_ddmmyy(f[9]),
        f[12] if len(f) > 12 and f[12] else None,
        f[13] if len(f) > 13 and f[13] else None,
    )


def _vtg(talker: str, f: list[str]) -> Vtg:
    """VTG; trailing fields may be omitted."""
    f = _pad(f, 9)
    if f[5]:
        speed: float | None = float(f[5]) * KNOT_MPS
    elif f[7]:
        speed = float(f[7]) / 3.6
    else:
        speed = None
    return Vtg(talker, float(f[1]) if f[1] else None, float(f[3]) if f[3] else None, speed,
               f[9] if len(f) > 9 and f[9] else None)


def _gsa(talker: str, f: list[str]) -> Gsa:
    """GSA; trailing fields may be omitted (``$GPGSA,A,1,,,,``: they are None). The 18th field is NMEA 4.10's system
    id only when it is one hex digit 1-F; anything else there (a receiver's extra DOP, ``3.3``) is not read."""
    f = _pad(f, 18)
    try:
        ids = tuple(map(_SAT_IDS.__getitem__, f[3:15]))
    except KeyError:
        ids = tuple(int(s) if s else None for s in f[3:15])
    sys_id = f[18] if len(f) > 18 else ""
    return Gsa(talker, f[1], int(f[2] or 1), ids, float(f[15]) if f[15] else None, float(f[16]) if f[16] else None,
               float(f[17]) if f[17] else None,
               int(sys_id, 16) if len(sys_id) == 1 and sys_id in "123456789ABCDEFabcdef" else None)


def _stat_m(s: str) -> float | None:
    """A GST statistic: empty -> None; else a finite number >= 0 (``ValueError`` otherwise: ``inf``, ``nan``, a
    negative standard deviation)."""
    if not s:
        return None
    v = float(s)
    if not (math.isfinite(v) and v >= 0.0):
        raise ValueError(f"bad GST statistic {s!r}")
    return v


def _gst(talker: str, f: list[str]) -> Gst:
    """GST: time, range RMS, semi-major, semi-minor, orientation (finite, taken modulo 360), latitude, longitude and
    altitude error (finite, >= 0); trailing fields may be omitted."""
    f = _pad(f, 9)
    orient = float(f[5]) if f[5] else None
    if orient is not None and not math.isfinite(orient):
        raise ValueError(f"bad GST orientation {f[5]!r}")
    return Gst(talker, _TIME_CACHE.get(f[1]) or _parse_time(f[1]), _stat_m(f[2]), _stat_m(f[3]), _stat_m(f[4]),
               None if orient is None else orient % 360.0, _stat_m(f[6]), _stat_m(f[7]), _stat_m(f[8]))


def _gsv(talker: str, f: list[str]) -> Gsv:
    """GSV: blocks of (PRN, elevation, azimuth, C/N0). A block with an empty PRN (``$GPGSV,3,1,00,,,,,...``: a
    receiver's empty slots) is skipped; a last block cut short has its omitted fields None; one field beyond whole
    blocks is NMEA 4.10's signal id."""
    if len(f) < 4:
        raise ValueError("GSV needs at least 3 fields")
    n_sat_fields = len(f) - 4
    signal_id = None
    if n_sat_fields % 4 == 1:  # NMEA 4.10: a trailing signal id
        signal_id = int(f[-1], 16) if f[-1] else None
        n_sat_fields -= 1
    elif n_sat_fields % 4:  # the last block cut short
        f = _pad(f, len(f) + 4 - n_sat_fields % 4)
        n_sat_fields += 4 - n_sat_fields % 4
    sats = tuple((int(f[4 + 4 * i]), int(f[5 + 4 * i]) if f[5 + 4 * i] else None,
                  int(f[6 + 4 * i]) if f[6 + 4 * i] else None, int(f[7 + 4 * i]) if f[7 + 4 * i] else None)
                 for i in range(n_sat_fields // 4) if f[4 + 4 * i])
    return Gsv(talker, int(f[1]), int(f[2]), int(f[3]), sats, signal_id)


#: Satellite-ID strings of GSA slots (NMEA writes 2 digits, some receivers 1 or 3).
_SAT_IDS: dict[str, int | None] = {"": None, **{str(i): i for i in range(1000)}, **{f"{i:02d}": i for i in range(100)},
                                   **{f"{i:03d}": i for i in range(1000)}}


def _small_int(s: str, lo: int, hi: int, what: str) -> int:
    """A short signed decimal integer field within [lo, hi], else ``ValueError`` (no huge or non-ASCII number)."""
    body = s[1:] if s[:1] in ("-", "+") else s
    if not (0 < len(body) <= 4 and body.isascii() and body.isdigit()):
        raise ValueError(f"bad {what} {s!r}")
    v = int(s)
    if not lo <= v <= hi:
        raise ValueError(f"{what} {s!r} out of range")
    return v


def _zda(talker: str, f: list[str]) -> Zda:
    """ZDA: time, day 01-31, month 01-12, four-digit year (a real date), local zone hours -13..13 and minutes
    00-59; a field out of range is refused (``ValueError``)."""
    if len(f) < 5:
        raise ValueError("ZDA needs its time and date fields")
    f = f + [""] * (7 - len(f))  # the zone fields may be omitted
    date = None
    if f[2] and f[3] and f[4]:
        key = f[2] + "/" + f[3] + "/" + f[4]
        date = _DATE_CACHE.get(key)
        if date is None:
            if len(f[4]) != 4 or not f[4].isdigit():
                raise ValueError(f"bad ZDA year {f[4]!r}")
            date = _dt.date(_small_int(f[4], 1, 9999, "ZDA year"), _small_int(f[3], 1, 12, "ZDA month"),
                            _small_int(f[2], 1, 31, "ZDA day"))
            if len(_DATE_CACHE) >= _CACHE_MAX:
                _DATE_CACHE.clear()
            _DATE_CACHE[key] = date
    elif f[2] or f[3] or f[4]:
        raise ValueError("ZDA date with an empty field")
    return Zda(talker, _TIME_CACHE.get(f[1]) or _parse_time(f[1]), date,
               _small_int(f[5], -13, 13, "ZDA zone hours") if f[5] else None,
               _small_int(f[6], 0, 59, "ZDA zone minutes") if f[6] else None)


#: The two checksum characters -> value (upper case per NMEA 0183; lower case accepted).
_HEX2 = {**{f"{i:02X}".encode(): i for i in range(256)}, **{f"{i:02x}".encode(): i for i in range(256)}}

#: The same, pre-XORed with the framing bytes '$', '*', the two hex digits, CR and LF.
_HEX2_FRAMED = {k: v ^ 0x24 ^ 0x2A ^ k[0] ^ k[1] ^ 0x0D ^ 0x0A for k, v in _HEX2.items()}

_PARSERS: dict[str, Callable[[str, list[str]], Gga | Gns | Gsv | Rmc | Vtg | Gsa | Gst | Zda]] = {
    "GGA": _gga, "GNS": _gns, "GSV": _gsv, "RMC": _rmc, "VTG": _vtg, "GSA": _gsa, "GST": _gst, "ZDA": _zda}


def sentence_ok(frame: bytes) -> bool:
    """Reference check of one candidate sentence: ``$`` ... ``*hh`` CR LF framing and the XOR of the body
    (:func:`~protocols.crc.nmea_checksum`) equal to the two hex digits."""
    if len(frame) < 11 or frame[0] != 0x24 or frame[-1] != 0x0A or frame[-2] != 0x0D or frame[-5] != 0x2A:
        return False
    want = _HEX2.get(frame[-4:-2])
    return want is not None and nmea_checksum(frame[1:-5]) == want


def sentence_ok_fast(frame: bytes) -> bool:
    """:func:`sentence_ok` with the XOR folded over the whole frame as one integer (what the stream runs): the
    ``$`` and LF are XORed out with the expected value, so any other first or last byte fails the check."""
    if len(frame) < 11 or frame[-2] != 0x0D or frame[-5] != 0x2A:  # '\r', '*'
        return False
    want = _HEX2_FRAMED.get(frame[-4:-2])
    if want is None:
        return False
    # XOR of every byte by folding the frame as one integer (<= 1024 bytes: 8192 bits);
    # the framing bytes $ * h h CR LF are XORed out through _HEX2_FRAMED.
    x = int.from_bytes(frame, "little")
    if len(frame) > 128:
        x ^= x >> 4096
        x ^= x >> 2048
        x ^= x >> 1024
    x ^= x >> 512
    x ^= x >> 256
    x ^= x >> 128
    x ^= x >> 64
    x ^= x >> 32
    x ^= x >> 16
    x ^= x >> 8
    return (x & 0xFF) == want


class NmeaFormat:
    """:class:`~protocols.stream.FrameFormat` for NMEA 0183 sentences.

    Parses GGA, GNS, RMC, VTG, GSA, GSV, GST and ZDA into :class:`Gga`, :class:`Gns`, :class:`Rmc`, :class:`Vtg`,
    :class:`Gsa`, :class:`Gsv`, :class:`Gst` and :class:`Zda`; any other checked sentence (also proprietary ``$P...``)
    comes out as :class:`NmeaSentence`.
    """

    name = "nmea"
    sync = b"$"

    def __init__(self, max_len: int = NMEA_MAX_LEN) -> None:
        # Longest accepted line; 82 is the standard's limit, proprietary sentences of real
        # receivers (u-blox PUBX,00: ~110 characters) need more.
        if not 11 <= max_len <= 1024:
            raise ValueError(f"max_len {max_len} outside [11, 1024]")
        self.max_len = max_len
        #: sentences accepted with an LF-only line end (NMEA wants CR LF; many receivers and loggers send LF)
        self.lf_only = 0

    @staticmethod
    def encode(obj: Any) -> bytes:
        """Encode a decoded object back to its frame (:func:`encode_nmea`)."""
        return encode_nmea(obj)

    def frame_length(self, buf: bytes | bytearray, start: int) -> int:
        """Length up to and including the LF. A candidate longer than :data:`_LONG_LINE` must be printable ASCII
        to be waited for or taken: a stray ``$`` before binary bytes (UBX on the same port) is refused at 128
        bytes, as before the long lines of real receivers were accepted, not held for up to ``max_len``."""
        end = buf.find(b"\n", start + 1, start + self.max_len)
        if end < 0:
            n = len(buf) - start
            if n >= self.max_len or (n >= _LONG_LINE and _NOT_IN_LONG_LINE.search(buf, start + 1) is not None):
                return BAD_LENGTH
            return NEED_MORE
        # A new '$' before the line end means this candidate was cut short.
        if buf.find(b"$", start + 1, end) >= 0:
            return BAD_LENGTH
        if end - start >= _LONG_LINE and _NOT_IN_LONG_LINE.search(buf, start + 1, end) is not None:
            return BAD_LENGTH
        return end + 1 - start

    def check(self, frame: bytes) -> bool:
        """Framing and checksum of one candidate (:func:`sentence_ok_fast`); a line ended by LF alone is
        checked with its checksum at ``[-4:-2]`` (and counted in :attr:`lf_only` when parsed)."""
        if frame[-2] == 0x0D:
            return sentence_ok_fast(frame)
        if len(frame) < 10 or frame[-4] != 0x2A or frame[-1] != 0x0A or frame[0] != 0x24:
            return False
        want = _HEX2.get(frame[-3:-1])
        return want is not None and nmea_checksum(frame[1:-4]) == want

    def parse(self, frame: bytes) -> NmeaSentence | Gga | Gns | Gsv | Rmc | Vtg | Gsa | Gst | Zda:
        if frame[-2] != 0x0D:
            obj = self._parse(frame, -4)
            self.lf_only += 1  # counted once the sentence is accepted (parse errors are counted as such)
            return obj
        return self._parse(frame, -5)

    @staticmethod
    def _parse(frame: bytes, end: int) -> NmeaSentence | Gga | Gns | Gsv | Rmc | Vtg | Gsa | Gst | Zda:
        parts = frame[1:end].decode("ascii").split(",")
        head = _HEADS.get(parts[0])
        if head is None:
            head = _classify_head(parts[0])
        talker, kind, p = head
        if p is not None:
            return p(talker, parts)
        return NmeaSentence(talker, kind, tuple(parts[1:]))


#: Lines longer than this (the receiving limit before long proprietary sentences were accepted) are taken only when
#: every byte between ``$`` and LF is printable ASCII or CR (:meth:`NmeaFormat.frame_length`); shorter candidates are
#: framed as they always were, so their counters do not change.
_LONG_LINE = 128
_NOT_IN_LONG_LINE = re.compile(rb"[^\x20-\x23\x25-\x7e\r]")

#: A typed sentence parser: (talker, the split sentence) -> the sentence object.
_Parser = Callable[[str, list[str]], Gga | Gns | Gsv | Rmc | Vtg | Gsa | Gst | Zda]
_HEADS: dict[str, tuple[str, str, _Parser | None]] = {}


def _classify_head(head: str) -> tuple[str, str, _Parser | None]:
    """Split an address field into (talker, kind, typed parser or None); cache the good ones.

    * ``P`` + anything printable: proprietary (NMEA 0183 reserves ``P`` for them; no talker starts with it), talker
      ``P`` + the three-letter maker code, kind the rest as sent (``$PGRME``: kind ``E``; ``$PSRFTXTVersion
      GSW3.2.2...``: SiRF banners with spaces and no comma; ``$PUBX``: kind empty);
    * ``ttsss`` (five upper-case letters or digits): talker and sentence type, typed when the type is known;
    * another upper-case alphanumeric address of 3 to 10 characters (``$LOG108``, RGM-3800 replies): an untyped
      sentence with talker ``""`` and the whole address as its kind.
    """
    r: tuple[str, str, _Parser | None]
    if len(head) >= 4 and head[0] == "P" and head.isprintable() and head[:4].isalnum() and head[:4].isupper():
        r = (head[:4], head[4:], None)  # proprietary: 'P' + maker code, then the type (may be empty)
    elif len(head) == 5 and head.isalnum() and head.isupper():
        talker, kind = head[:2], head[2:]
        r = (talker, kind, _PARSERS.get(kind))
    elif 3 <= len(head) <= 10 and head.isalnum() and head.isupper():
        r = ("", head, None)
    else:
        raise ValueError(f"bad NMEA address field {head!r}")
    if len(_HEADS) < 256:
        _HEADS[head] = r
    return r
