"""The quirks corpus: byte streams of what real GNSS receivers send, each with where the behaviour comes from.

Every entry writes one receiver epoch (UTC ``utc``, the synthetic truth's position) in the layout of the
receiver it names, byte for byte: the checksums, field counts, decimals and line ends are those of the
source; only the time and the position are the test's. :mod:`tests.firmware_model.test_quirks` feeds every
stream through the firmware and asserts its outcome (``expect``: counters of the firmware and its UART3
decoder after the run).
"""

from __future__ import annotations

import datetime as dt
from collections.abc import Callable
from dataclasses import dataclass, field

from protocols.crc import nmea_checksum
from protocols.gnss import GnssFix, nav_pvt_from_fix
from protocols.nmea_build import format_lat, format_lon
from protocols.ubx import build_ubx_frame, encode_nav_pvt


def frame(body: str, eol: str = "\r\n") -> bytes:
    """``$`` + body + ``*`` + checksum + line end, without the 82-character limit of the builders."""
    return f"${body}*{nmea_checksum(body.encode('ascii')):02X}{eol}".encode("ascii")


def _t(utc: dt.datetime) -> str:
    return utc.strftime("%H%M%S.") + f"{utc.microsecond // 10000:02d}"


def _ll(lat: float, lon: float, decimals: int = 5) -> str:
    a, ns = format_lat(lat, decimals)
    o, ew = format_lon(lon, decimals)
    return f"{a},{ns},{o},{ew}"


def gga(utc: dt.datetime, lat: float, lon: float, h: float, quality: int = 1, talker: str = "GP",
        decimals: int = 5, alt: str | None = None, eol: str = "\r\n") -> bytes:
    alt = f"{h:.1f}" if alt is None else alt
    return frame(f"{talker}GGA,{_t(utc)},{_ll(lat, lon, decimals)},{quality},08,1.01,{alt},M,0.0,M,,", eol)


def rmc(utc: dt.datetime, lat: float, lon: float, status: str = "A", mode: str = "A", talker: str = "GP",
        nav_status: str | None = None, eol: str = "\r\n") -> bytes:
    tail = f",{nav_status}" if nav_status is not None else ""
    return frame(f"{talker}RMC,{_t(utc)},{status},{_ll(lat, lon)},0.004,,{utc:%d%m%y},,,{mode}{tail}", eol)


@dataclass(frozen=True)
class Quirk:
    name: str
    #: where the behaviour comes from (a receiver manual, a public log or issue, a peer library's test data)
    source: str
    epoch: Callable[[dt.datetime, float, float, float], bytes]
    #: expected outcome: counter name -> ("==" | ">=", value per epoch (x epochs) or absolute with "abs")
    expect: dict[str, tuple[str, float]] = field(default_factory=dict)


def _pubx00(utc: dt.datetime, lat: float, lon: float, h: float) -> bytes:
    # u-blox 6/M8 receiver description, PUBX,00 (POSITION): 20 fields after the address; the layout and number
    # formats of the example in coverclock/com-diag-hazer's PUBX unit test (a real NEO-M8 log line, 110 chars)
    return frame(f"PUBX,00,{_t(utc)},{_ll(lat, lon)},{h:.3f},G3,6528077,4616048,1.234,290.12,2.345,,"
                 "1.23,4.56,7.89,4,0,0")


def _nav_pvt(n: int) -> Callable[[dt.datetime, float, float, float], bytes]:
    def epoch(utc: dt.datetime, lat: float, lon: float, h: float) -> bytes:
        p = encode_nav_pvt(nav_pvt_from_fix(GnssFix(utc=utc, lat_deg=lat, lon_deg=lon, height_m=h)))[6:-2]
        if n == 84:  # protocol 14: the shared prefix, then 6 reserved bytes
            p = p[:78] + bytes(6)
        elif n > 92:  # a later protocol with a longer payload: 8 more bytes
            p = p + bytes(n - 92)
        return build_ubx_frame(0x01, 0x07, p)
    return epoch


CORPUS: tuple[Quirk, ...] = (
    Quirk("lf_only", "LF-only line ends: producers fixed in public issues fhorinek/SkyDrop#220 (Digifly/LK8EX1 "
          "lines ended by LF) and waterlinked/examples#8 (no CR LF); NMEA 0183 wants CR LF (gpsd NMEA.txt)",
          lambda u, a, o, h: gga(u, a, o, h, eol="\n") + rmc(u, a, o, eol="\n"),
          {"lf_only": (">=", 2), "crc_errors": ("==", 0), "gnss_updates": (">=", 0.6)}),
    Quirk("pubx00_long", "u-blox $PUBX,00 (u-blox 6 / M8 receiver descriptions, NMEA PUBX POSITION): 110 "
          "characters, over the 82 of NMEA 0183; layout as coverclock/com-diag-hazer tests/pubx.c",
          lambda u, a, o, h: gga(u, a, o, h) + rmc(u, a, o) + _pubx00(u, a, o, h),
          {"length_errors": ("==", 0), "gnss_nmea_other": (">=", 1), "gnss_updates": (">=", 0.6)}),
    Quirk("ublox_high_precision_gga", "u-blox CFG-NMEA highPrec (M8 receiver description): 7 decimals of "
          "minutes in GGA/RMC, a GGA of 84 characters",
          lambda u, a, o, h: frame(f"GNGGA,{_t(u)},{_ll(a, o, 7)},1,12,0.58,{h:.3f},M,47.512,M,,") + rmc(u, a, o),
          {"length_errors": ("==", 0), "gnss_updates": (">=", 0.6)}),
    Quirk("gns_multi_gnss", "NMEA 4.10 GNS with one mode character per constellation (GPS, GLONASS, Galileo, "
          "BeiDou) and navStatus, as u-blox M8/F9 send with talker GN",
          lambda u, a, o, h: frame(f"GNGNS,{_t(u)},{_ll(a, o)},AANN,10,0.90,{h:.1f},0.0,,,V".replace(",V", ",S"))
          + rmc(u, a, o, talker="GN", nav_status="V"),
          {"gnss_updates": (">=", 0.6), "gnss_2d_fixes": ("==", 0)}),
    Quirk("rmc_only", "RMC alone (the 'recommended minimum'; gpsd NMEA.txt: some units ship with RMC only): "
          "horizontal position and velocity, no height",
          lambda u, a, o, h: rmc(u, a, o),
          {"gnss_updates": (">=", 0.6), "gnss_2d_fixes": (">=", 0.9)}),
    Quirk("fix_2d", "a 2-D fix: GSA fix type 2 (NMEA 0183 GSA; receivers with < 4 satellites hold the height)",
          lambda u, a, o, h: gga(u, a, o, h) + rmc(u, a, o)
          + frame("GPGSA,A,2,02,05,06,,,,,,,,,,2.10,1.90,0.90"),
          {"gnss_updates": (">=", 0.6), "gnss_2d_fixes": (">=", 0.9)}),
    Quirk("dead_reckoning", "GGA quality 6 (estimated / dead reckoning) and RMC mode E (NMEA 2.3), as a receiver "
          "with sensor fusion sends in a tunnel: never a measurement",
          lambda u, a, o, h: gga(u, a, o, h, quality=6) + rmc(u, a, o, mode="E"),
          {"gnss_updates": ("==", 0), "gnss_dr_refused": (">=", 0.9)}),
    Quirk("nmea_4_10_rmc", "NMEA 4.10 RMC with the navStatus field (13th) as u-blox protocol 23.01+ sends",
          lambda u, a, o, h: gga(u, a, o, h) + rmc(u, a, o, nav_status="V"),
          {"gnss_updates": (">=", 0.6), "parse_errors": ("==", 0)}),
    Quirk("cold_start_no_fix", "u-blox NEO-6M power-up before its first fix (captured output at "
          "http://chris.cnie.de/avr/neo-6.html): $GPTXT banners, GGA and RMC with empty time and position",
          lambda u, a, o, h: frame("GPTXT,01,01,02,u-blox ag - www.u-blox.com") + frame("GPRMC,,V,,,,,,,,,,N")
          + frame("GPGGA,,,,,,0,00,99.99,,,,,,"),
          {"gnss_updates": ("==", 0), "gnss_fixes": ("==", 0), "gnss_no_fix_epochs": (">=", 0.4),
           "gnss_nmea_other": (">=", 1), "crc_errors": ("==", 0), "parse_errors": ("==", 0)}),
    Quirk("gsa_per_system_4_10", "NMEA 4.10 multi-GNSS: one GNGSA per system with systemId (1 GPS, 2 GLONASS; "
          "GLONASS satellites 65-96), as u-blox M8/F9 send with NMEA 4.10",
          lambda u, a, o, h: rmc(u, a, o, talker="GN", nav_status="V") + gga(u, a, o, h, talker="GN")
          + frame("GNGSA,A,3,02,05,06,12,,,,,,,,,1.50,0.90,1.20,1")
          + frame("GNGSA,A,3,65,66,72,,,,,,,,,,1.50,0.90,1.20,2"),
          {"gnss_updates": (">=", 0.6), "gnss_2d_fixes": ("==", 0), "parse_errors": ("==", 0)}),
    Quirk("nav_pvt_u_blox_7", "UBX-NAV-PVT protocol 14 (u-blox 7 receiver description): 84-byte payload",
          _nav_pvt(84), {"gnss_updates": (">=", 0.6), "gnss_pvt": (">=", 0.9), "length_errors": ("==", 0)}),
    Quirk("nav_pvt_m8", "UBX-NAV-PVT protocol 15-23 (u-blox M8 receiver description): 92-byte payload",
          _nav_pvt(92), {"gnss_updates": (">=", 0.6), "gnss_pvt": (">=", 0.9)}),
    Quirk("nav_pvt_f9_extended", "UBX-NAV-PVT read by its prefix: the u-blox descriptions reserve the right to "
          "extend a payload ('the payload may be longer in later versions'); 100 bytes",
          _nav_pvt(100), {"gnss_updates": (">=", 0.6), "gnss_pvt": (">=", 0.9), "length_errors": ("==", 0)}),
)
