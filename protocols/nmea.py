"""NMEA 0183 sentences: framing, checksum, GGA and RMC.

Source: ``shared/reference/protocols.md`` section 2.3 (gpsd NMEA notes; field order as in
pynmea2). A sentence is ``$`` + talker (2 letters) + type (3 letters) + ``,``-separated fields
+ ``*`` + two upper-case hex digits (XOR of every byte strictly between ``$`` and ``*``)
+ ``<CR><LF>``; at most 82 characters including ``$`` and ``<CR><LF>``.

Latitude is written ``ddmm.mmmmm`` and longitude ``dddmm.mmmmm`` (5 decimals of arc-minutes,
1.85 cm), heights and speeds with the decimals of a u-blox receiver.
"""

from __future__ import annotations

import datetime as _dt
from dataclasses import dataclass

from .crc import nmea_checksum
from .stream import BAD_LENGTH, NEED_MORE

__all__ = [
    "NMEA_MAX_LEN",
    "KNOT_MPS",
    "NmeaSentence",
    "Gga",
    "Rmc",
    "NmeaFormat",
    "build_sentence",
    "build_gga",
    "build_rmc",
    "format_lat",
    "format_lon",
]

#: Longest legal sentence, bytes, including ``$`` and ``<CR><LF>``.
NMEA_MAX_LEN = 82
#: One knot in m/s.
KNOT_MPS = 1852.0 / 3600.0


@dataclass(frozen=True, slots=True)
class NmeaSentence:
    """Any checked NMEA sentence: talker (``GP``), type (``GGA``) and the raw field strings."""

    talker: str
    kind: str
    fields: tuple[str, ...]


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


def _parse_time(s: str) -> _dt.time | None:
    if not s:
        return None
    hh, mm = int(s[0:2]), int(s[2:4])
    sec = float(s[4:])
    whole = int(sec)
    return _dt.time(hh, mm, whole, int(round((sec - whole) * 1e6)) if sec != whole else 0)


def _parse_latlon(value: str, hemi: str, deg_digits: int) -> float | None:
    if not value:
        return None
    deg = int(value[:deg_digits])
    minutes = float(value[deg_digits:])
    if minutes >= 60.0:
        raise ValueError(f"minutes {minutes} >= 60")
    v = deg + minutes / 60.0
    if hemi in ("S", "W"):
        v = -v
    elif hemi not in ("N", "E"):
        raise ValueError(f"bad hemisphere {hemi!r}")
    return v


def _opt_float(s: str) -> float | None:
    return float(s) if s else None


def _opt_int(s: str) -> int | None:
    return int(s) if s else None


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
    geoid_sep_m: float,
    quality: int = 1,
    num_sats: int = 12,
    hdop: float = 0.8,
    talker: str = "GP",
) -> bytes:
    """GGA sentence. ``quality`` 0 invalid, 1 GPS, 2 DGPS, 4 RTK fixed, 5 RTK float, 6 DR."""
    lat, ns = format_lat(lat_deg)
    lon, ew = format_lon(lon_deg)
    if quality == 0:
        return build_sentence(talker, "GGA", [_format_time(time_utc), "", "", "", "", "0", "00", "99.99", "", "", "", "", "", ""])
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
            f"{geoid_sep_m:.3f}",
            "M",
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
) -> bytes:
    """RMC sentence (NMEA 2.3 with the mode indicator). Speed in m/s is written in knots."""
    if not valid:
        return build_sentence(talker, "RMC", [_format_time(time_utc), "V", "", "", "", "", "", "", date.strftime("%d%m%y"), "", "", "N"])
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
        ],
    )


class NmeaFormat:
    """:class:`~protocols.stream.FrameFormat` for NMEA 0183 sentences.

    Parses GGA and RMC into :class:`Gga` / :class:`Rmc`; any other checked sentence comes out
    as :class:`NmeaSentence`.
    """

    name = "nmea"
    sync = b"$"

    def frame_length(self, buf: bytearray, start: int) -> int:
        end = buf.find(b"\n", start + 1, start + NMEA_MAX_LEN)
        if end < 0:
            if len(buf) - start >= NMEA_MAX_LEN:
                return BAD_LENGTH
            return NEED_MORE
        # A new '$' before the line end means this candidate was cut short.
        if buf.find(b"$", start + 1, end) >= 0:
            return BAD_LENGTH
        return end + 1 - start

    def check(self, frame: bytes) -> bool:
        if len(frame) < 11 or frame[-2:] != b"\r\n" or frame[-5] != 0x2A:  # '*'
            return False
        try:
            want = int(frame[-4:-2], 16)
        except ValueError:
            return False
        return nmea_checksum(frame[1:-5]) == want

    def parse(self, frame: bytes) -> NmeaSentence | Gga | Rmc:
        body = frame[1:-5].decode("ascii")
        parts = body.split(",")
        head = parts[0]
        if len(head) != 5 or not head.isalnum():
            raise ValueError(f"bad NMEA address field {head!r}")
        talker, kind = head[:2], head[2:]
        f = parts[1:]
        if kind == "GGA":
            if len(f) < 14:
                raise ValueError("GGA needs 14 fields")
            return Gga(
                talker=talker,
                time_utc=_parse_time(f[0]),
                lat_deg=_parse_latlon(f[1], f[2], 2),
                lon_deg=_parse_latlon(f[3], f[4], 3),
                quality=int(f[5] or 0),
                num_sats=_opt_int(f[6]),
                hdop=_opt_float(f[7]),
                altitude_msl_m=_opt_float(f[8]),
                geoid_sep_m=_opt_float(f[10]),
            )
        if kind == "RMC":
            if len(f) < 11:
                raise ValueError("RMC needs at least 11 fields")
            speed = _opt_float(f[6])
            date = None
            if f[8]:
                d = f[8]
                date = _dt.date(2000 + int(d[4:6]), int(d[2:4]), int(d[0:2]))
            return Rmc(
                talker=talker,
                time_utc=_parse_time(f[0]),
                valid=f[1] == "A",
                lat_deg=_parse_latlon(f[2], f[3], 2),
                lon_deg=_parse_latlon(f[4], f[5], 3),
                speed_mps=None if speed is None else speed * KNOT_MPS,
                course_deg=_opt_float(f[7]),
                date=date,
                mode=f[11] if len(f) > 11 and f[11] else None,
            )
        return NmeaSentence(talker, kind, tuple(f))

