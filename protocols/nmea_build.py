"""NMEA 0183 sentence builders: framing, checksum and the number formats of GGA, RMC, VTG, GSA, GSV and ZDA.

The writing half of :mod:`protocols.nmea` (which re-exports every name here, and parses what these write).
Number formats (a u-blox-like rendering, and the one that the golden vectors pin down):

==========  =======================================================================
field       format
==========  =======================================================================
time        ``hhmmss.ss`` (UTC)
lat / lon   ``ddmm.mmmmm`` / ``dddmm.mmmmm`` (5 decimals of arc-minutes, 1.85 cm) + N/S, E/W
altitude    metres, 3 decimals (GGA altitude above MSL and geoid separation)
HDOP etc.   2 decimals
speed       knots, 3 decimals (RMC, VTG); VTG km/h is derived from the *rounded* knots, so a
            decoded sentence re-encodes to the same bytes
course      degrees true, 2 decimals, [0, 360)
==========  =======================================================================

NMEA 4.10 (the layout u-blox receivers send from protocol 23.01 on, NMEA 0183 v4.10): RMC gains a 13th field
``navStatus`` (``nav_status=``), GSA an 18th ``systemId`` (``system_id=``: 1 GPS, 2 GLONASS, 3 Galileo,
4 BeiDou) and GSV a last ``signalId`` (``signal_id=``); the arguments default to None, the 2.3 layout.
Satellite numbers per NMEA 4.10 / the u-blox numbering: GPS 1-32, SBAS 33-64, GLONASS 65-96 (talker GL),
Galileo 1-36 (GA), BeiDou 1-63 (GB / BD): :data:`SV_NUMBERS`.
"""

from __future__ import annotations

import datetime as _dt
from collections.abc import Sequence

from .crc import nmea_checksum

__all__ = [
    "KNOT_MPS",
    "NMEA_MAX_LEN",
    "NMEA_SYSTEM_ID",
    "SV_NUMBERS",
    "build_gga",
    "build_gsa",
    "build_gst",
    "build_gsv",
    "build_rmc",
    "build_sentence",
    "build_vtg",
    "build_zda",
    "format_lat",
    "format_lon",
]

#: Longest legal sentence, bytes, including ``$`` and ``<CR><LF>``.
NMEA_MAX_LEN = 82
#: One knot in m/s.
KNOT_MPS = 1852.0 / 3600.0
#: NMEA 4.10 satellite-number ranges per talker (u-blox receiver descriptions, "Satellite numbering", NMEA 4.10
#: column): GPS 1-32, GLONASS 65-96, Galileo 1-36, BeiDou 1-63
SV_NUMBERS: dict[str, range] = {"GP": range(1, 33), "GL": range(65, 97), "GA": range(1, 37), "GB": range(1, 64),
                                "BD": range(1, 64)}
#: NMEA 4.10 GNSS system id (GSA field 18, GSV signal id companion) per talker
NMEA_SYSTEM_ID: dict[str, int] = {"GP": 1, "GL": 2, "GA": 3, "GB": 4, "BD": 4}


def format_lat(lat_deg: float, decimals: int = 5) -> tuple[str, str]:
    """``(ddmm.mmmmm, N|S)`` for a latitude in degrees."""
    return _format_angle(lat_deg, 2, decimals, "N", "S")


def format_lon(lon_deg: float, decimals: int = 5) -> tuple[str, str]:
    """``(dddmm.mmmmm, E|W)`` for a longitude in degrees."""
    return _format_angle(lon_deg, 3, decimals, "E", "W")


def _format_angle(v: float, deg_digits: int, decimals: int, pos: str, neg: str) -> tuple[str, str]:
    hemi = pos if v >= 0 else neg
    a = abs(v)
    scale = 10**decimals
    total = round(a * 60.0 * scale)  # integer count of 10^-decimals arc-minutes
    deg, rem = divmod(total, 60 * scale)
    minutes = rem / scale
    return f"{deg:0{deg_digits}d}{minutes:0{3 + decimals}.{decimals}f}", hemi


def _format_time(t: _dt.time, decimals: int = 2) -> str:
    frac = t.microsecond / 1e6
    sec = t.second + frac
    return f"{t.hour:02d}{t.minute:02d}{sec:0{3 + decimals}.{decimals}f}"


def _opt(v: float | None, fmt: str) -> str:
    return "" if v is None else format(v, fmt)


def build_sentence(talker: str, kind: str, fields: list[str] | tuple[str, ...]) -> bytes:
    """Frame a sentence: ``$`` + body + ``*`` + checksum + CR LF."""
    body = f"{talker}{kind}," + ",".join(fields)
    s = f"${body}*{nmea_checksum(body):02X}\r\n".encode("ascii")
    if len(s) > NMEA_MAX_LEN:
        raise ValueError(f"NMEA sentence of {len(s)} bytes exceeds {NMEA_MAX_LEN}")
    return s


def build_gga(
    time_utc: _dt.time,
    lat_deg: float,
    lon_deg: float,
    altitude_msl_m: float,
    geoid_sep_m: float | None,
    quality: int = 1,
    num_sats: int = 12,
    hdop: float = 0.8,
    talker: str = "GP",
) -> bytes:
    """GGA sentence. ``quality`` 0 invalid, 1 GPS, 2 DGPS, 4 RTK fixed, 5 RTK float, 6 DR. ``geoid_sep_m`` None:
    the separation field and its unit left empty (MSL height only, as several receiver families send it)."""
    lat, ns = format_lat(lat_deg)
    lon, ew = format_lon(lon_deg)
    if quality == 0:
        return build_sentence(talker, "GGA", [_format_time(time_utc), "", "", "", "", "0", "00", "99.99", "", "", "",
                                              "", "", ""])
    return build_sentence(
        talker,
        "GGA",
        [
            _format_time(time_utc),
            lat,
            ns,
            lon,
            ew,
            str(quality),
            f"{num_sats:02d}",
            f"{hdop:.2f}",
            f"{altitude_msl_m:.3f}",
            "M",
            "" if geoid_sep_m is None else f"{geoid_sep_m:.3f}",
            "" if geoid_sep_m is None else "M",
            "",
            "",
        ],
    )


def build_rmc(
    time_utc: _dt.time,
    date: _dt.date,
    lat_deg: float,
    lon_deg: float,
    speed_mps: float,
    course_deg: float,
    valid: bool = True,
    mode: str = "A",
    talker: str = "GP",
    nav_status: str | None = None,
) -> bytes:
    """RMC sentence (NMEA 2.3 with the mode indicator; NMEA 4.10 with ``nav_status``, e.g. ``V``). Speed in m/s is
    written in knots."""
    tail = [] if nav_status is None else [nav_status]
    if not valid:
        return build_sentence(talker, "RMC", [_format_time(time_utc), "V", "", "", "", "", "", "",
                                              date.strftime("%d%m%y"), "", "", "N", *tail])
    lat, ns = format_lat(lat_deg)
    lon, ew = format_lon(lon_deg)
    return build_sentence(
        talker,
        "RMC",
        [
            _format_time(time_utc),
            "A",
            lat,
            ns,
            lon,
            ew,
            f"{speed_mps / KNOT_MPS:.3f}",
            f"{course_deg % 360.0:.2f}",
            date.strftime("%d%m%y"),
            "",
            "",
            mode,
            *tail,
        ],
    )


def build_vtg(
    course_true_deg: float | None,
    speed_mps: float | None,
    mode: str = "A",
    course_mag_deg: float | None = None,
    talker: str = "GP",
) -> bytes:
    """VTG sentence: course true/magnetic (deg, 2 decimals), speed in knots and km/h.

    The km/h field is derived from the knots value after rounding to 3 decimals, so the
    sentence round-trips through :class:`NmeaFormat`. ``None`` leaves a field empty
    (a receiver without a fix: ``mode="N"``).
    """
    if speed_mps is None:
        kn = kmh = ""
    else:
        knots = round(speed_mps / KNOT_MPS, 3)
        kn = f"{knots:.3f}"
        kmh = f"{knots * 1.852:.3f}"
    return build_sentence(
        talker,
        "VTG",
        [
            _opt(None if course_true_deg is None else course_true_deg % 360.0, ".2f"),
            "T",
            _opt(None if course_mag_deg is None else course_mag_deg % 360.0, ".2f"),
            "M",
            kn,
            "N",
            kmh,
            "K",
            mode,
        ],
    )


def build_gsa(
    fix_type: int,
    sat_ids: list[int | None] | tuple[int | None, ...],
    pdop: float | None,
    hdop: float | None,
    vdop: float | None,
    mode: str = "A",
    talker: str = "GP",
    system_id: int | None = None,
) -> bytes:
    """GSA sentence: ``mode`` A (automatic) / M (manual), ``fix_type`` 1 none / 2 2D / 3 3D; NMEA 4.10 adds
    ``system_id`` (:data:`NMEA_SYSTEM_ID`).

    ``sat_ids`` fills the 12 satellite slots in order (``None`` = empty slot; fewer than 12
    entries leave the remaining slots empty). DOPs with 2 decimals.
    """
    slots = list(sat_ids)
    if len(slots) > 12:
        raise ValueError(f"GSA has 12 satellite slots, got {len(slots)}")
    slots += [None] * (12 - len(slots))
    ids = ["" if s is None else f"{s:02d}" for s in slots]
    tail = [] if system_id is None else [f"{system_id:X}"]
    return build_sentence(talker, "GSA", [mode, str(fix_type), *ids, _opt(pdop, ".2f"), _opt(hdop, ".2f"),
                                          _opt(vdop, ".2f"), *tail])


def build_gsv(
    sats: Sequence[tuple[int, int | None, int | None, int | None]],
    talker: str = "GP",
    signal_id: int | None = None,
) -> bytes:
    """GSV sentences (as many as needed, 4 satellites each): ``sats`` = (number, elevation deg, azimuth deg,
    C/N0 dBHz or None when not tracked). NMEA 4.10 adds ``signal_id`` (1 = GPS L1 C/A, GLONASS L1 OF, ...).
    No satellite in view: one sentence with 0 satellites (as u-blox receivers send)."""
    n = len(sats)
    total = max(1, (n + 3) // 4)
    tail = [] if signal_id is None else [f"{signal_id:X}"]
    out = bytearray()
    for k in range(total):
        fields = [str(total), str(k + 1), f"{n:02d}"]
        for prn, elev, az, snr in sats[4 * k: 4 * k + 4]:
            fields += [f"{prn:02d}", "" if elev is None else f"{elev:02d}", "" if az is None else f"{az:03d}",
                       "" if snr is None else f"{snr:02d}"]
        out += build_sentence(talker, "GSV", [*fields, *tail])
    return bytes(out)


def build_zda(
    time_utc: _dt.time,
    date: _dt.date,
    zone_hours: int | None = 0,
    zone_minutes: int | None = 0,
    talker: str = "GP",
) -> bytes:
    """ZDA sentence: UTC time, day, month, 4-digit year, local zone hours and minutes."""
    zh = "" if zone_hours is None else (f"{zone_hours:03d}" if zone_hours < 0 else f"{zone_hours:02d}")
    zm = "" if zone_minutes is None else f"{zone_minutes:02d}"
    return build_sentence(talker, "ZDA", [_format_time(time_utc), f"{date.day:02d}", f"{date.month:02d}",
                                          f"{date.year:04d}", zh, zm])


def build_gst(
    time_utc: _dt.time,
    rms_m: float | None,
    major_m: float | None,
    minor_m: float | None,
    orient_deg: float | None,
    lat_m: float | None,
    lon_m: float | None,
    alt_m: float | None,
    talker: str = "GP",
) -> bytes:
    """GST sentence (pseudorange error statistics, NMEA 0183): UTC time of the fix, the RMS of the range inputs'
    standard deviations, the error ellipse's semi-major and semi-minor standard deviations, the semi-major axis'
    orientation (deg from true north), the latitude, longitude and altitude error standard deviations (m, 1 sigma),
    each with one decimal as u-blox receivers print them (``None``: an empty field)."""
    return build_sentence(talker, "GST", [_format_time(time_utc), _opt(rms_m, ".1f"), _opt(major_m, ".1f"),
                                          _opt(minor_m, ".1f"), _opt(orient_deg, ".1f"), _opt(lat_m, ".1f"),
                                          _opt(lon_m, ".1f"), _opt(alt_m, ".1f")])
