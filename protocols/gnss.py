"""One GNSS receiver epoch as bytes: a configurable NMEA/UBX output set at 1 Hz.

A receiver model hands :func:`build_epoch` one :class:`GnssFix` (what the receiver knows at
the epoch) and a :class:`GnssOutputSet` (which messages it is configured to send, in which
order); the result is the burst the receiver writes once per epoch. The ICD's GNSS budget is
computed from the same function, so the numbers there are the bytes a run really sends.

Defaults follow a u-blox receiver (docs/reference/wire-formats.md section 2.3: NEO-class units print RMC,
VTG, GGA, GSA and more at 9600 8N1; ZDA is off by default on real units but part of the default set here).
"""

from __future__ import annotations

import datetime as _dt
import math
from dataclasses import dataclass

from .constants import A_WGS84, F_WGS84
from .nmea import build_gga, build_gsa, build_gsv, build_rmc, build_vtg, build_zda
from .nmea_build import NMEA_SYSTEM_ID, build_gst
from .ubx import (
    NavPosllh,
    NavPvt,
    NavSol,
    NavStatus,
    NavTimeGps,
    NavTimeUtc,
    NavVelned,
    encode_nav_pvt,
    encode_nav_status,
    encode_ubx,
)

__all__ = [
    "FAA_MODE",
    "GPS_EPOCH",
    "GPS_UTC_LEAP_S",
    "GPS_UTC_LEAP_TABLE",
    "NMEA_SENTENCES",
    "NMEA_VERSIONS",
    "UBX_MESSAGES",
    "GnssFix",
    "GnssOutputSet",
    "build_epoch",
    "geodetic_ecef",
    "gps_time_of_week_ms",
    "gps_utc_offset_s",
    "gps_week",
    "legacy_nav_from_fix",
    "nav_pvt_from_fix",
    "nav_status_from_fix",
]

GPS_EPOCH = _dt.datetime(1980, 1, 6, tzinfo=_dt.UTC)
#: GPS - UTC in seconds since 2017-01-01 (IERS Bulletin C: no leap second announced since).
GPS_UTC_LEAP_S = 18
#: GPS - UTC (s) from each date on: the leap seconds since the GPS epoch, from the IERS table of TAI - UTC
#: (``Leap_Second.dat`` of the IERS Earth Orientation Centre, Bulletin C; GPS - UTC = TAI - UTC - 19 s).
GPS_UTC_LEAP_TABLE: tuple[tuple[_dt.date, int], ...] = (
    (_dt.date(1980, 1, 6), 0), (_dt.date(1981, 7, 1), 1), (_dt.date(1982, 7, 1), 2), (_dt.date(1983, 7, 1), 3),
    (_dt.date(1985, 7, 1), 4), (_dt.date(1988, 1, 1), 5), (_dt.date(1990, 1, 1), 6), (_dt.date(1991, 1, 1), 7),
    (_dt.date(1992, 7, 1), 8), (_dt.date(1993, 7, 1), 9), (_dt.date(1994, 7, 1), 10), (_dt.date(1996, 1, 1), 11),
    (_dt.date(1997, 7, 1), 12), (_dt.date(1999, 1, 1), 13), (_dt.date(2006, 1, 1), 14), (_dt.date(2009, 1, 1), 15),
    (_dt.date(2012, 7, 1), 16), (_dt.date(2015, 7, 1), 17), (_dt.date(2017, 1, 1), GPS_UTC_LEAP_S),
)


def gps_utc_offset_s(utc: _dt.datetime | _dt.date) -> int:
    """GPS - UTC (s) at a UTC instant (:data:`GPS_UTC_LEAP_TABLE`; 0 before the GPS epoch)."""
    d = utc.date() if isinstance(utc, _dt.datetime) else utc
    n = 0
    for start, leap in GPS_UTC_LEAP_TABLE:
        if d < start:
            break
        n = leap
    return n
NMEA_SENTENCES = ("RMC", "VTG", "GGA", "GSA", "GSV", "GST", "ZDA")
#: NMEA layouts: 2.3 (mode indicator) and 4.10 (RMC navStatus, GSA systemId, GSV signalId)
NMEA_VERSIONS = ("2.3", "4.10")
#: NMEA 2.3 mode indicator (RMC/VTG) for each GGA fix quality.
FAA_MODE = {1: "A", 2: "D", 4: "R", 5: "F", 6: "E"}
#: UBX output messages: NAV-PVT (protocol 14+) and the set of the generations before it (u-blox 5/6/7, and M8/F9
#: configured so): NAV-SOL, NAV-POSLLH, NAV-VELNED, NAV-TIMEUTC, NAV-TIMEGPS with NAV-STATUS
UBX_MESSAGES = ("NAV-PVT", "NAV-STATUS", "NAV-SOL", "NAV-POSLLH", "NAV-VELNED", "NAV-TIMEUTC", "NAV-TIMEGPS")


@dataclass(frozen=True, slots=True)
class GnssFix:
    """What a receiver reports at one epoch (SI units, degrees for angles as on the wire).

    ``utc`` is the epoch (timezone-aware UTC); ``height_m`` is ellipsoidal and
    ``height_m - geoid_sep_m`` the height above MSL; ``vel_enu_mps`` is East, North, Up.
    ``fix_type`` uses the UBX codes (0 none, 2 2D, 3 3D); ``quality`` the GGA codes.
    """

    utc: _dt.datetime
    lat_deg: float
    lon_deg: float
    height_m: float
    geoid_sep_m: float = 0.0
    #: False: GGA leaves the geoid-separation field empty (MSL height only), as several receiver families do
    geoid_sep_in_gga: bool = True
    vel_enu_mps: tuple[float, float, float] = (0.0, 0.0, 0.0)
    fix_type: int = 3
    quality: int = 1
    sat_ids: tuple[int, ...] = (2, 5, 6, 12, 13, 15, 17, 19, 24, 25, 29, 30)
    hdop: float = 0.8
    vdop: float = 1.2
    pdop: float = 1.44
    h_acc_m: float = 2.5
    v_acc_m: float = 4.0
    s_acc_mps: float = 0.1
    head_acc_deg: float = 1.0
    t_acc_ns: int = 20
    ttff_ms: int = 28000
    msss_ms: int = 60000
    #: satellites in view for GSV: (system talker GP/GL/GA/GB, NMEA 4.10 number, elevation deg, azimuth deg,
    #: C/N0 dBHz or None); empty: GSV lists none
    sky: tuple[tuple[str, int, int, int, int | None], ...] = ()
    #: GST: the receiver's own estimate of its latitude, longitude and altitude errors (m, 1 sigma) and of its range
    #: errors (RMS, m); None: GST derives them from ``h_acc_m`` / ``v_acc_m`` and ``hdop``
    gst_std_m: tuple[float, float, float] | None = None
    gst_range_rms_m: float | None = None


@dataclass(frozen=True, slots=True)
class GnssOutputSet:
    """Messages sent once per epoch, in this order: NMEA sentences then UBX messages.

    ``nmea`` is any ordered subset of :data:`NMEA_SENTENCES`; ``ubx`` of :data:`UBX_MESSAGES`;
    ``talker`` the NMEA talker (``GP`` GPS only, ``GN`` multi-GNSS: then GSA and GSV come once per system
    with the system's own talker, as u-blox receivers send them); ``version`` the NMEA layout
    (:data:`NMEA_VERSIONS`).
    """

    nmea: tuple[str, ...] = ("RMC", "VTG", "GGA", "GSA", "ZDA")
    ubx: tuple[str, ...] = ()
    talker: str = "GP"
    rate_hz: float = 1.0
    version: str = "2.3"

    def __post_init__(self) -> None:
        bad = [s for s in self.nmea if s not in NMEA_SENTENCES] + [m for m in self.ubx if m not in UBX_MESSAGES]
        if bad:
            raise ValueError(f"unknown GNSS output message(s) {bad}; NMEA: {NMEA_SENTENCES}, UBX: {UBX_MESSAGES}")
        if self.version not in NMEA_VERSIONS:
            raise ValueError(f"NMEA version {self.version!r}; expected one of {NMEA_VERSIONS}")
        if not 0 < self.rate_hz <= 25:
            raise ValueError(f"GNSS output rate {self.rate_hz} Hz outside (0, 25]")


def gps_time_of_week_ms(utc: _dt.datetime) -> int:
    """GPS time of week, ms, of a UTC instant (GPS = UTC + the leap seconds of that date, :func:`gps_utc_offset_s`)."""
    dt = utc - GPS_EPOCH + _dt.timedelta(seconds=gps_utc_offset_s(utc))
    ms = dt.days * 86_400_000 + dt.seconds * 1000 + dt.microseconds // 1000
    return ms % (7 * 86_400_000)


def _course_speed(vel_enu: tuple[float, float, float]) -> tuple[float, float]:
    ve, vn = vel_enu[0], vel_enu[1]
    return math.degrees(math.atan2(ve, vn)) % 360.0, math.hypot(ve, vn)


def nav_pvt_from_fix(fix: GnssFix) -> NavPvt:
    """UBX-NAV-PVT content of ``fix`` (rounded to the message's integer units)."""
    t = fix.utc
    course, speed = _course_speed(fix.vel_enu_mps)
    ok = fix.fix_type >= 2
    return NavPvt(
        iTOW=gps_time_of_week_ms(t), year=t.year, month=t.month, day=t.day, hour=t.hour, min=t.minute, sec=t.second,
        valid=0x07, tAcc=fix.t_acc_ns, nano=t.microsecond * 1000, fixType=fix.fix_type,
        flags=0x01 if ok else 0x00, flags2=0xE0, numSV=len(fix.sat_ids),
        lon=round(fix.lon_deg * 1e7), lat=round(fix.lat_deg * 1e7), height=round(fix.height_m * 1e3),
        hMSL=round((fix.height_m - fix.geoid_sep_m) * 1e3), hAcc=round(fix.h_acc_m * 1e3),
        vAcc=round(fix.v_acc_m * 1e3), velN=round(fix.vel_enu_mps[1] * 1e3), velE=round(fix.vel_enu_mps[0] * 1e3),
        velD=round(-fix.vel_enu_mps[2] * 1e3), gSpeed=round(speed * 1e3), headMot=round(course * 1e5),
        sAcc=round(fix.s_acc_mps * 1e3), headAcc=round(fix.head_acc_deg * 1e5), pDOP=round(fix.pdop * 100),
        flags3=0 if ok else 0x01, reserved0=0, headVeh=0, magDec=0, magAcc=0,
    )


def nav_status_from_fix(fix: GnssFix) -> NavStatus:
    """UBX-NAV-STATUS content of ``fix`` (gpsFixOk, week and time-of-week set)."""
    ok = fix.fix_type >= 2
    return NavStatus(iTOW=gps_time_of_week_ms(fix.utc), gpsFix=fix.fix_type, flags=(0x01 if ok else 0) | 0x0C,
                     fixStat=0, flags2=0, ttff=fix.ttff_ms, msss=fix.msss_ms)


def gps_week(utc: _dt.datetime) -> int:
    """GPS week number (continuous, not modulo 1024) of a UTC instant."""
    dt = utc - GPS_EPOCH + _dt.timedelta(seconds=gps_utc_offset_s(utc))
    return dt.days // 7


def legacy_nav_from_fix(fix: GnssFix, name: str) -> NavSol | NavPosllh | NavVelned | NavTimeUtc | NavTimeGps:
    """The content of one legacy NAV message (``name`` of :data:`UBX_MESSAGES` other than NAV-PVT/STATUS) for
    ``fix``, rounded to the message's integer units (NAV-SOL's ECEF position and velocity from the WGS-84
    geodetic fix, the same closed forms as :func:`geodetic_ecef`)."""
    t = fix.utc
    itow = gps_time_of_week_ms(t)
    ok = fix.fix_type >= 2
    if name == "NAV-POSLLH":
        return NavPosllh(iTOW=itow, lon=round(fix.lon_deg * 1e7), lat=round(fix.lat_deg * 1e7),
                         height=round(fix.height_m * 1e3), hMSL=round((fix.height_m - fix.geoid_sep_m) * 1e3),
                         hAcc=round(fix.h_acc_m * 1e3), vAcc=round(fix.v_acc_m * 1e3))
    ve, vn, vu = fix.vel_enu_mps
    if name == "NAV-VELNED":
        course, speed = _course_speed(fix.vel_enu_mps)
        return NavVelned(iTOW=itow, velN=round(vn * 100), velE=round(ve * 100), velD=round(-vu * 100),
                         speed=round(math.sqrt(ve * ve + vn * vn + vu * vu) * 100), gSpeed=round(speed * 100),
                         heading=round(course * 1e5), sAcc=min(round(fix.s_acc_mps * 100), 0xFFFFFFFF),
                         cAcc=round(fix.head_acc_deg * 1e5))
    frac_ns = t.microsecond * 1000 - (itow % 1000) * 1_000_000
    if name == "NAV-SOL":
        lat, lon = math.radians(fix.lat_deg), math.radians(fix.lon_deg)
        x, y, z = geodetic_ecef(lat, lon, fix.height_m)
        sl, cl, so, co = math.sin(lat), math.cos(lat), math.sin(lon), math.cos(lon)
        vx = -so * ve - sl * co * vn + cl * co * vu
        vy = co * ve - sl * so * vn + cl * so * vu
        vz = cl * vn + sl * vu
        return NavSol(iTOW=itow, fTOW=frac_ns, week=gps_week(t), gpsFix=fix.fix_type,
                      flags=(0x01 if ok else 0) | 0x0C, ecefX=round(x * 100), ecefY=round(y * 100),
                      ecefZ=round(z * 100), pAcc=min(round(math.hypot(fix.h_acc_m, fix.v_acc_m) * 100), 0xFFFFFFFF),
                      ecefVX=round(vx * 100), ecefVY=round(vy * 100), ecefVZ=round(vz * 100),
                      sAcc=min(round(fix.s_acc_mps * 100), 0xFFFFFFFF), pDOP=round(fix.pdop * 100), reserved1=0,
                      numSV=len(fix.sat_ids), reserved2=0)
    if name == "NAV-TIMEGPS":
        return NavTimeGps(iTOW=itow, fTOW=frac_ns, week=gps_week(t), leapS=gps_utc_offset_s(t), valid=0x07,
                          tAcc=fix.t_acc_ns)
    if name == "NAV-TIMEUTC":
        return NavTimeUtc(iTOW=itow, tAcc=fix.t_acc_ns, nano=t.microsecond * 1000, year=t.year, month=t.month,
                          day=t.day, hour=t.hour, min=t.minute, sec=t.second, valid=0x07 | (3 << 4))  # USNO (GPS)
    raise ValueError(f"not a legacy NAV message: {name!r}")


def geodetic_ecef(lat: float, lon: float, h: float) -> tuple[float, float, float]:
    """WGS-84 geodetic (rad, rad, m) to ECEF (m): the prime-vertical radius N = a / sqrt(1 - e^2 sin^2 lat)."""
    e2 = F_WGS84 * (2.0 - F_WGS84)
    sl = math.sin(lat)
    n = A_WGS84 / math.sqrt(1.0 - e2 * sl * sl)
    return ((n + h) * math.cos(lat) * math.cos(lon), (n + h) * math.cos(lat) * math.sin(lon), (n * (1.0 - e2) + h) * sl)


def build_epoch(fix: GnssFix, output: GnssOutputSet = GnssOutputSet()) -> bytes:
    """The bytes the receiver sends for one epoch: ``output.nmea`` sentences, then ``output.ubx``."""
    t = fix.utc.timetz().replace(tzinfo=None)
    d = fix.utc.date()
    course, speed = _course_speed(fix.vel_enu_mps)
    ok = fix.fix_type >= 2
    tk = output.talker
    v410 = output.version == "4.10"
    out = bytearray()
    for s in output.nmea:
        if s == "RMC":
            out += build_rmc(t, d, fix.lat_deg, fix.lon_deg, speed, course, valid=ok, talker=tk,
                             mode=FAA_MODE.get(fix.quality, "A") if ok else "N", nav_status="V" if v410 else None)
        elif s == "VTG":
            out += (build_vtg(course, speed, FAA_MODE.get(fix.quality, "A"), talker=tk) if ok
                    else build_vtg(None, None, "N", talker=tk))
        elif s == "GGA":
            out += build_gga(t, fix.lat_deg, fix.lon_deg, fix.height_m - fix.geoid_sep_m,
                             fix.geoid_sep_m if fix.geoid_sep_in_gga else None,
                             quality=fix.quality if ok else 0, num_sats=len(fix.sat_ids), hdop=fix.hdop, talker=tk)
        elif s == "GSA":
            if v410 and tk == "GN" and fix.sky:
                # one GSA per system (NMEA 4.10 systemId), each with that system's satellites used
                for sys_tk in dict.fromkeys(e[0] for e in fix.sky):
                    ids = tuple(e[1] for e in fix.sky if e[0] == sys_tk and e[1] in fix.sat_ids)[:12] if ok else ()
                    out += build_gsa(fix.fix_type if ok else 1, ids, fix.pdop if ok else None,
                                     fix.hdop if ok else None, fix.vdop if ok else None, talker=tk,
                                     system_id=NMEA_SYSTEM_ID.get(sys_tk))
            else:
                ids = fix.sat_ids[:12] if ok else ()
                out += build_gsa(fix.fix_type if ok else 1, ids, fix.pdop if ok else None, fix.hdop if ok else None,
                                 fix.vdop if ok else None, talker=tk,
                                 system_id=NMEA_SYSTEM_ID.get(tk, 1) if v410 else None)
        elif s == "GSV":
            systems = list(dict.fromkeys(e[0] for e in fix.sky)) or [tk if tk != "GN" else "GP"]
            for sys_tk in systems:
                sats = [(e[1], e[2], e[3], e[4]) for e in fix.sky if e[0] == sys_tk]
                out += build_gsv(sats, talker=sys_tk if tk == "GN" else tk, signal_id=1 if v410 else None)
        elif s == "GST":
            if ok:
                std_lat, std_lon, std_alt = fix.gst_std_m or (fix.h_acc_m / math.sqrt(2.0),) * 2 + (fix.v_acc_m,)
                h = math.hypot(std_lat, std_lon)
                rms = fix.gst_range_rms_m if fix.gst_range_rms_m is not None else h / max(fix.hdop, 1e-3)
                out += build_gst(t, rms, max(std_lat, std_lon), min(std_lat, std_lon),
                                 0.0 if std_lat >= std_lon else 90.0, std_lat, std_lon, std_alt, talker=tk)
            else:  # no fix: the statistics' fields empty (as u-blox receivers send them without a fix)
                out += build_gst(t, None, None, None, None, None, None, None, talker=tk)
        else:  # ZDA
            out += build_zda(t, d, 0, 0, talker=tk)
    for m in output.ubx:
        if m == "NAV-PVT":
            out += encode_nav_pvt(nav_pvt_from_fix(fix))
        elif m == "NAV-STATUS":
            out += encode_nav_status(nav_status_from_fix(fix))
        else:
            out += encode_ubx(legacy_nav_from_fix(fix, m))
    return bytes(out)
