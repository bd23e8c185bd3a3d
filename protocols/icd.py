"""Generate ``docs/icd.md``, the interface control document, from the frame specs.

``python -m protocols.icd > docs/icd.md`` rewrites it; ``tests/protocols/test_icd.py`` fails when
the committed file differs from what this module generates, so the document cannot drift from
the code. Byte tables come from the declarative ``construct`` specs (their field docs are
``"scale | unit | meaning"``); frame sizes from the encoders; link budgets from the encoders and
the default line rates below (the defaults of ``emulator/scenario/runtime_schema.py``, checked by
the same test).
"""

from __future__ import annotations

import datetime as dt
import math
import struct
from collections.abc import Sequence
from typing import Any

from construct import Array, BytesInteger, Const, FormatField, Renamed, Struct
from construct import Bytes as _Bytes

from . import can_nav, crc, gnss, host, imu_frame, monitor, nmea, psns, stim, ubx, ubx_cfg
from .icd_lockstep import LOCKSTEP_TEXT
from .icd_nmea import NMEA_PARSE_TEXT

__all__ = ["LINK_BAUD", "budget_rows", "generate", "spec_rows"]

#: Default line rate of every link, baud (8N1 = 10 bits per byte on every UART link).
LINK_BAUD = {"gyro": 460800, "gnss": 9600, "psns": 115200, "host": 460800,
             "uart0": 460800, "uart1": 460800, "uart2": 115200, "uart3": 115200, "monitor": 3_000_000}
#: Rates used by the budget (Hz): the IMU trigger, the NAV_SOLUTION default output rate, the GNSS
#: epoch, the magnetometer (MAG frames) and the PSNS example configuration.
RATE = {"imu": 200.0, "nav": 100.0, "gnss": 1.0, "mag": 100.0, "psns_obs": 5.0, "psns_compass": 10.0,
        "psns_solar": 10.0, "status": 1.0, "text": 10.0}
PSNS_EXAMPLE_POINTS = 100


# -- construct spec -> rows -----------------------------------------------------------------------
def _unwrap(sc: Any) -> tuple[str, str, Any]:
    name, docs = "", ""
    while isinstance(sc, Renamed):
        name = name or (sc.name or "")
        docs = docs or (sc.docs or "")
        sc = sc.subcon
    return name, docs, sc


def _fmt_type(sc: Any) -> tuple[str, int | str]:
    if isinstance(sc, FormatField):
        order = "LE" if sc.fmtstr[0] == "<" else "BE"
        code = sc.fmtstr[1]
        base = {"B": "u8", "b": "s8", "H": "u16", "h": "s16", "L": "u32", "I": "u32", "l": "s32", "i": "s32",
                "Q": "u64", "q": "s64", "f": "f32", "d": "f64"}[code]
        size = struct.calcsize(sc.fmtstr)
        return (base if size == 1 else f"{base} {order}"), size
    if isinstance(sc, BytesInteger):
        t = f"{'s' if sc.signed else 'u'}{8 * sc.length}"
        return f"{t} {'LE' if sc.swapped else 'BE'}", sc.length
    if isinstance(sc, Const):
        t, n = _fmt_type(sc.subcon)
        v = sc.value
        shown = v.hex(" ") if isinstance(v, bytes) else f"0x{v:02X}"
        return f"{t} = {shown}", n
    if isinstance(sc, _Bytes):
        n = sc.length if isinstance(sc.length, int) else "N"
        return f"bytes[{n}]", n
    raise TypeError(f"no ICD type for {sc!r}")


def _doc(docs: str) -> tuple[str, str, str]:
    parts = [p.strip() for p in docs.split(" | ")]
    if len(parts) >= 3:
        return parts[0], parts[1], " | ".join(parts[2:])
    return "", "", docs


def spec_rows(spec: Struct, start: int | str = 0) -> list[tuple[str, str, str, str, str, str, str]]:
    """``(offset, size, type, field, scale, unit, meaning)`` rows of a construct ``Struct``."""
    rows = []
    off: int | str = start
    for sc in spec.subcons:
        name, docs, inner = _unwrap(sc)
        scale, unit, meaning = _doc(docs)
        if isinstance(inner, Array):
            _, _, el = _unwrap(inner.subcon)
            count = inner.count if isinstance(inner.count, int) else "count"
            if isinstance(el, Struct):
                el_size = el.sizeof()
                rows.append((str(off), f"{count} x {el_size}", "struct[]", name, scale, unit,
                             meaning or f"{count} elements, layout below"))
                size: int | str = el_size * count if isinstance(count, int) else f"{el_size}*count"
            else:
                t, n = _fmt_type(el)
                rows.append((str(off), f"{count} x {n}", f"{t} x {count}", name, scale, unit, meaning))
                size = n * count if isinstance(count, int) else f"{n}*count"
        else:
            t, size = _fmt_type(inner)
            rows.append((str(off), str(size), t, name, scale, unit, meaning))
        off = off + size if isinstance(off, int) and isinstance(size, int) else f"{off}+{size}"
    return rows


_SPEC_HEADER = ("offset", "size", "type", "field", "scale", "unit", "meaning")


def _table(rows: Sequence[Sequence[object]], header: tuple[str, ...] = _SPEC_HEADER) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    for r in rows:
        lines.append("| " + " | ".join(str(c).replace("|", "\\|") for c in r) + " |")
    return "\n".join(lines)


def _spec_table(spec: Struct, start: int | str = 0) -> str:
    return _table(spec_rows(spec, start))


# -- sizes and budgets ---------------------------------------------------------------------------
def _sample_nav() -> host.NavSolution:
    return host.NavSolution(1, 1.0, 39.979, 116.339, 50.0, (0.0, 0.0, 0.0), 0.0, 0.0, 30.0, (0.0,) * 9, 6, 1, 0, 10.0,
                            0)


def _gnss_fix() -> gnss.GnssFix:
    return gnss.GnssFix(utc=dt.datetime(2019, 9, 18, 8, 14, 0, tzinfo=dt.UTC), lat_deg=39.979,
                        lon_deg=116.339, height_m=50.0, geoid_sep_m=-8.5, vel_enu_mps=(1.0, 2.0, 0.1))


def frame_sizes() -> dict[str, int]:
    """Wire bytes of every frame the budget uses (from the encoders)."""
    h = psns.PsnsHeader(0, 0, 0, 0, 0)
    fix = _gnss_fix()
    return {
        "stim210_m": stim.Stim210Format("m").length,
        "stim300_93": stim.Stim300Format(0x93).length,
        "stim300_a7": stim.Stim300Format(0xA7).length,
        "imu": imu_frame.IMU_FRAME_LEN,
        "mag": imu_frame.MAG_FRAME_LEN,
        "nmea_epoch": len(gnss.build_epoch(fix)),
        "ubx_epoch": len(gnss.build_epoch(fix, gnss.GnssOutputSet(nmea=(), ubx=("NAV-PVT", "NAV-STATUS")))),
        "psns_obs": psns.frame_bytes_obs(PSNS_EXAMPLE_POINTS),
        "psns_compass": len(psns.encode_compass(h, [psns.CompassUnit(i, 0, 0) for i in range(9)])),
        "psns_solar": len(psns.encode_solar_vector(h, (0.0, 0.0, 1.0), 0.0)),
        "nav": len(host.encode_nav_solution(_sample_nav())),
        "status": 7 + host.STATUS_LEN,
        "text": len(host.nav_text_sentences(_sample_nav())),
    }


def budget_rows() -> list[tuple[str, ...]]:
    """``(link, between, frames, bytes/s needed, bytes/s available, load)`` for every link."""
    z = frame_sizes()
    r = RATE

    def row(link: str, between: str, items: list[tuple[str, int, float]]) -> tuple[str, ...]:
        need = sum(n * hz for _, n, hz in items)
        avail = LINK_BAUD[link] / 10
        frames = ", ".join(f"{name} {n} B x {hz:g} Hz" for name, n, hz in items)
        return (link, between, f"{LINK_BAUD[link]}", frames, f"{need:,.0f}", f"{avail:,.0f}",
                f"{100 * need / avail:.1f} %")

    rows = [
        row("gyro", "STIM210 -> FPGA GYRO (RS422)", [("STIM210 0xA5", z["stim210_m"], r["imu"])]),
        row("gyro", "STIM300 preset -> FPGA GYRO (RS422)", [("STIM300 0x93", z["stim300_93"], r["imu"])]),
        row("gyro", "STIM300 full -> FPGA GYRO (RS422)", [("STIM300 0xA7", z["stim300_a7"], r["imu"])]),
        row("uart1", "FPGA -> DSP UART1", [("IMU", z["imu"], r["imu"]), ("MAG", z["mag"], r["mag"])]),
        row("gnss", "receiver -> FPGA GNSS (RS422)", [("NMEA RMC+VTG+GGA+GSA+ZDA", z["nmea_epoch"], r["gnss"])]),
        row("gnss", "receiver -> FPGA GNSS, NMEA + UBX", [("NMEA set", z["nmea_epoch"], r["gnss"]),
                                                          ("NAV-PVT+NAV-STATUS", z["ubx_epoch"], r["gnss"])]),
        row("uart3", "FPGA -> DSP UART3 (FPGA UART core)", [("NMEA set", z["nmea_epoch"], r["gnss"]),
                                                            ("NAV-PVT+NAV-STATUS", z["ubx_epoch"], r["gnss"])]),
        row("psns", "polarization sensor -> FPGA PSNS (RS232)",
            [(f"OBS {PSNS_EXAMPLE_POINTS} points", z["psns_obs"], r["psns_obs"]),
             ("COMPASS 9 units", z["psns_compass"], r["psns_compass"]),
             ("SOLAR_VECTOR", z["psns_solar"], r["psns_solar"])]),
        row("uart2", "FPGA -> DSP UART2", [(f"OBS {PSNS_EXAMPLE_POINTS} points", z["psns_obs"], r["psns_obs"]),
                                           ("COMPASS", z["psns_compass"], r["psns_compass"]),
                                           ("SOLAR_VECTOR", z["psns_solar"], r["psns_solar"])]),
        row("uart0", "DSP UART0 -> FPGA HOST -> host (RS422)", [("NAV_SOLUTION", z["nav"], r["nav"]),
                                                                ("STATUS", z["status"], r["status"])]),
        row("host", "same, with the $PSNS text output on", [("NAV_SOLUTION", z["nav"], r["nav"]),
                                                            ("STATUS", z["status"], r["status"]),
                                                            ("$PSNS text x4", z["text"], r["text"])]),
    ]
    # Monitor: every tapped chunk as one record (1 delimiter + 1 COBS code + 10 header/CRC bytes).
    taps = [("gyro", z["stim210_m"], r["imu"]), ("uart1", z["imu"], r["imu"]), ("mag", z["mag"], r["mag"]),
            ("gnss", z["nmea_epoch"], r["gnss"]), ("uart3", z["nmea_epoch"], r["gnss"]),
            ("psns", z["psns_obs"], r["psns_obs"]), ("uart2", z["psns_obs"], r["psns_obs"]),
            ("host", z["nav"], r["nav"]), ("uart0", z["nav"], r["nav"])]
    rows.append(row("monitor", "FPGA MONITOR -> recorder", [(f"{c} record", monitor.monitor_frame_len(n), hz)
                                                           for c, n, hz in taps]))
    bits = can_nav.can_frame_bits()
    per_s = sum(1000 / m.cycle_ms for m in can_nav.CAN_MESSAGES)
    need = per_s * bits
    rows.append(("can", "DSP -> CAN bus (CAN 2.0B)", f"{can_nav.CAN_BITRATE} bit/s",
                  f"{len(can_nav.CAN_MESSAGES)} frames, {per_s:g} frames/s x {bits} bits (worst-case stuffing)",
                  f"{need:,.0f} bit/s", f"{can_nav.CAN_BITRATE:,} bit/s", f"{100 * need / can_nav.CAN_BITRATE:.1f} %"))
    return rows


# -- the document ----------------------------------------------------------------------------------
NMEA_FIELDS = {
    "GGA": [("time", "hhmmss.ss", "UTC"), ("lat", "ddmm.mmmmm", "latitude"), ("N/S", "char", ""),
            ("lon", "dddmm.mmmmm", "longitude"), ("E/W", "char", ""),
            ("quality", "digit", "0 invalid, 1 GPS, 2 DGPS, 4 RTK fixed, 5 RTK float, 6 DR"),
            ("numSV", "2 digits", "satellites used"), ("HDOP", "x.xx", ""), ("alt", "m, 3 decimals", "above MSL"),
            ("M", "char", ""), ("sep", "m, 3 decimals", "geoid separation"), ("M", "char", ""),
            ("diffAge", "empty", ""), ("diffStation", "empty", "")],
    "RMC": [("time", "hhmmss.ss", "UTC"), ("status", "A/V", "valid / warning"), ("lat", "ddmm.mmmmm", ""),
            ("N/S", "char", ""), ("lon", "dddmm.mmmmm", ""), ("E/W", "char", ""),
            ("speed", "knots, 3 decimals", "speed over ground"), ("course", "deg, 2 decimals", "true course"),
            ("date", "ddmmyy", "UTC date"), ("magVar", "empty", ""), ("magVarDir", "empty", ""),
            ("mode", "A/D/E/N", "NMEA 2.3 mode indicator")],
    "VTG": [("cogt", "deg, 2 decimals", "course true"), ("T", "char", ""), ("cogm", "deg or empty", "course magnetic"),
            ("M", "char", ""), ("sogn", "knots, 3 decimals", ""), ("N", "char", ""),
            ("sogk", "km/h, 3 decimals", "from the rounded knots"), ("K", "char", ""), ("mode", "A/D/E/N", "")],
    "GSA": [("mode", "M/A", "manual / automatic"), ("fixType", "1/2/3", "none / 2D / 3D"),
            ("sv1..sv12", "2 digits or empty", "satellites used (12 slots)"), ("PDOP", "x.xx", ""),
            ("HDOP", "x.xx", ""), ("VDOP", "x.xx", "")],
    "GSV": [("numMsg", "digit", "sentences in this group"), ("msgNum", "digit", "this sentence's number"),
            ("numSV", "2 digits", "satellites in view"),
            ("svid/elv/az/cno x 1..4", "2 / 2 / 3 / 2 digits", "NMEA 4.10 number, elevation deg, azimuth deg, "
             "C/N0 dBHz (empty: not tracked)"), ("signalId", "hex digit", "NMEA 4.10 only (1 = L1 C/A, L1OF)")],
    "ZDA": [("time", "hhmmss.ss", "UTC"), ("day", "dd", ""), ("month", "mm", ""), ("year", "yyyy", ""),
            ("ltzh", "hh (sign)", "local zone hours"), ("ltzn", "mm", "local zone minutes")],
}


#: What the firmware accepts on the GNSS input, what it refuses and under which counter (docs/icd.md 5.1.1).
GNSS_INPUT_TEXT = f"""#### 5.1.1 GNSS input: accepted, refused, counted

What the firmware (`firmware_model/tasks/gnss.py`) takes from real receivers, and the counter each refusal goes to
(firmware counters and the `uart3` decoder counters, in `summary.json` under `firmware` and in the monitor):

| input | outcome | counted in |
|---|---|---|
| CR LF line end | accepted | `uart3.frames` |
| LF-only line end (loggers, some receivers) | accepted | `uart3.lf_only` (never a CRC error) |
| sentence of 83..{nmea.NMEA_RX_MAX_LEN} characters (`$PUBX,00` 110, u-blox high-precision GGA 84) | accepted \
| `uart3.frames`; a longer line: `uart3.length_errors` |
| bad checksum | dropped | `uart3.crc_errors` |
| GGA, GNS (NMEA 4.10 mode per constellation) | 3-D position | `gnss_fixes` |
| RMC | horizontal velocity (speed, course), date (status A only, 5.1.3); its position when the epoch has no GGA/GNS \
| - |
| RMC alone, GGA without altitude, GSA fix type 2, NAV-PVT fixType 2 | 2-D fix: horizontal position only \
(no height row) | `gnss_2d_fixes` |
| GGA quality 6, GNS mode E, RMC mode E, NAV-PVT fixType 1 (dead reckoning) | never a measurement | `gnss_dr_refused` |
| GGA quality 0, RMC V, GNS N, NAV-PVT fixType 0/5 | no fix | `gnss_no_fix_epochs` |
| NAV-PVT with gnssFixOK clear | no fix | `gnss_pvt_ignored_flags` |
| NAV-PVT 84 (u-blox 7), 92 (M8, F9), > 92 bytes | position, 3-D velocity, UTC | `gnss_pvt` |
| NAV-PVT of another length, unknown UBX class | refused at the header | `uart3.length_errors` |
| NAV-POSLLH, NAV-SOL, NAV-VELNED, NAV-TIMEUTC, NAV-TIMEGPS, NAV-STATUS (u-blox 5/6/7) | one epoch per iTOW (5.1.3) \
| `gnss_legacy_ubx` |
| ZDA (date, time); GST, GBS, GRS, GLL (time) | open the epoch, UTC (5.1.3) | - |
| GST latitude and longitude error (m) | the fix's sigmas times ``max(1, HDOP / hdop_ref, GST / sheet)`` (D-5.51) \
| `input_rejected_gst_range` above 10 km |
| other UBX (ACK, MON ...) | not used | `gnss_ubx_other` |
| other NMEA (VTG, GSV, TXT, proprietary) | not used | `gnss_nmea_other` |
| out-of-range field (latitude, height, speed, date ...) | refused | `input_rejected_<reason>` |

Epochs. Messages with the same UTC are one epoch and give one measurement, however many writes they arrive in
(`gnss_epochs`, `gnss_epochs_split`). An epoch closes when a message of a later UTC arrives, when every message
kind of the previous whole epoch has arrived (the stream's composition, learned as gpsd learns its cycle), or
`gnss_epoch_hold_s` (0.5 s) after its first byte (`gnss_epoch_timeouts`); content for an epoch already closed is
dropped (`gnss_late_messages`).

Time tags. With a PPS latched within the last 2 s, an epoch at UTC S + f is valid at the PPS edge of second S
plus f: the latest PPS edge + f + whole seconds at or before the arrival of its first message (`gnss_tag_pps`).
Without PPS the tag comes from the epoch's own UTC: the UTC-to-FPGA offset is the
smallest (first-byte time - UTC) over the last 32 epochs (the first byte's time is the UART's time stamp of the
chunk minus its bytes at the line rate), and the tag is UTC + offset - `gnss_latency_s`, the receiver's configured
latency from epoch to first byte (scenario `sensors.gnss.latency_s`) (`gnss_tag_utc`); a step of the receiver's
clock is followed as 5.1.3 says (`gnss_utc_offset_resets`). A fix without UTC is tagged at its first byte minus
the latency (`gnss_no_utc`). Never the tick that parsed it.

"""

#: What the firmware makes of what real receivers send: clock steps, dates, fix quality, heights, u-blox generations
#: (docs/icd.md 5.1.3; issue 37 items 1-5).
GNSS_RECEIVER_TEXT = """#### 5.1.3 Receiver quirks: clock steps, dates, fix quality, heights, u-blox generations

Clock steps. Every epoch gives a sample of (first-byte time - epoch time), whatever message opens it: ZDA, GST, GBS,
GRS and GLL open an epoch as GGA does (SiRF, Ashtech, GlobalSat and Septentrio bursts open with ZDA or GST). The
sample is tight when the opening message is the first of its chunk and bounded from above by the chunk's arrival
otherwise, so the minimum over the window stays a lower envelope. A sample more than `gnss_clock_step_tol_s`
(0.75 s: above a 9600-baud burst and the write jitter, below a leap second) from the time base is a step of the
receiver's clock, either sign, any size: the epoch is refused, neither its fix nor its time used
(`gnss_clock_step_refused`), until `gnss_clock_rebase_epochs` (N = 5) consecutive epochs agree on the new offset
(within the same tolerance); the N-th re-bases the offset and is used (`gnss_clock_steps`). One epoch never
moves the time base or UTC. An epoch whose tag is later than the arrival of its own bytes is refused
(`gnss_tag_future`), one older than `gnss_max_age_s` (1.5 s) at its close too (`gnss_tag_stale`); UTC set from an
epoch that old is counted `utc_stale_pps` with a PPS tag and `utc_stale_tag` without.

Leap seconds. UBX epochs are placed by their GPS time of week (iTOW) on the UTC time of day with the receiver's
own GPS - UTC: NAV-TIMEGPS `leapS` when `leapSValid`, or a NAV-PVT / NAV-TIMEUTC UTC (valid, fully resolved)
against its iTOW; 18 s (IERS Bulletin C, since 2017) until the receiver says. Once the receiver has reported it,
the offset's time scale is GPS time (UTC + leap seconds), which does not step at a leap second
(`gnss_leap_changes` counts the changes). An NMEA-only stream sees a leap second as a 1 s clock step, refused for
N epochs and re-based.

Dates. UTC (for the sun ephemeris) comes from ZDA (date and time), RMC with status A (a void RMC carries the
receiver's RTC date, or nothing), NAV-PVT with validDate, validTime and fullyResolved (and, where the receiver
reports confirmedAvai, confirmedDate and confirmedTime), and NAV-TIMEUTC with validUTC; a GGA + ZDA stream gives
UTC. A date outside the firmware's GPS week era (GPS week `gnss_era_start_week` = 2048, 2019-04-07, to 1024 weeks
later: a receiver that rolled over, such as the 2019 RMC `...,220899`, or an RTC date years back) is refused, as
gpsd reads a week before its build week as a rollover; so is a date and time more than `gnss_date_jump_tol_s`
(1 day) from the firmware's running UTC clock (`gnss_date_refused`). A smaller clock step is followed once the time
base re-based on it. gpsd (its generated `BUILD_WEEK` / `BUILD_ROLLOVERS`) and NTP's `gpsweekadj` add 1024 weeks to a
week before their build week; the firmware refuses the date instead, since an NMEA date cannot tell a rollover from
an RTC date.

Fix quality. What each receiver indication does:

| indication | meaning | outcome | counted in |
|---|---|---|---|
| GGA quality 1, 2, 3, 4, 5; GNS mode A, D, P, R, F | GNSS fix | used | `gnss_fixes` |
| GGA quality 6; GNS/RMC mode E; UBX fixType 1 | dead reckoning | not used | `gnss_dr_refused` |
| GGA quality 7; GNS/RMC mode M | manual input | not used | `gnss_manual_refused` |
| GGA quality 8; GNS/RMC mode S (Garmin demo mode) | simulator | not used | `gnss_sim_refused` |
| GGA quality above 8; UBX fixType 6, 7 (reserved) | unknown | not used | `gnss_fix_type_unknown` |
| GGA/GNS with 3 satellites | no 3-D solution | horizontal position only | `gnss_few_sats`, `gnss_2d_fixes` |
| GGA/GNS with 0-2 satellites | no solution | not used | `gnss_few_sats` |
| NAV-SOL with fewer than 4 (3-D) or 3 (2-D) satellites | no solution | not used | `gnss_few_sats` |
| GGA quality 0; RMC status V or mode N; GNS mode N; GSA fix type 1; UBX fixType 0, 5; NAV-SOL/STATUS without \
gpsFixOK | no fix (any message of the epoch) | not used | `gnss_no_fix_epochs` |
| GSA fix type 2; UBX fixType 2 | 2-D fix | horizontal position only | `gnss_2d_fixes` |

Heights. GGA and GNS carry the height above MSL and the geoid separation N (h = H + N). An empty separation field
(seven receiver families leave it empty) is filled from the firmware's own geoid table (`firmware_model/geoid.py`:
EGM96 at 5-degree nodes, whole metres, bilinear; against the 15' grid 1.4 m mean error where |N| >= 30 m, 95 % within
4.8 m, 1.9 m rms over the globe, but up to 10-20 m where the geoid changes ~10 m per degree, as over New Guinea;
`tools/make_geoid_table.py --check`), counted in `gnss_geoid_filled`; MSL is never taken as the ellipsoidal height.
The filled height keeps the receiver's vertical sigma (`gnss_pos_sigma_v_m`, 7.5 m), which covers the table's error
at 95 % of sites. The emulated
receiver reports EGM96 from proj-data's 15' grid (`egm96_15.gtx`) unless the scenario fixes
`sensors.gnss.geoid_sep_m`; `sensors.gnss.geoid_sep_field: empty` leaves the field empty.

u-blox generations. Without NAV-PVT (u-blox 5/6/7, or an M8/F9 configured so) the NAV messages of one iTOW form
one epoch (`gnss_legacy_ubx`): NAV-POSLLH the position (ellipsoidal height), NAV-VELNED the 3-D velocity, NAV-SOL
the fix type (gpsFix with gpsFixOK), satellites, and the ECEF position and velocity when NAV-POSLLH / NAV-VELNED
are absent, NAV-STATUS the fix type, NAV-TIMEUTC the UTC date and time, NAV-TIMEGPS the leap seconds. NAV-POSLLH /
NAV-VELNED without a NAV-SOL or NAV-STATUS saying "fix" are not used. The emulated u-blox sends this set with
`sensors.gnss.ubx: [NAV-SOL, NAV-POSLLH, NAV-VELNED, NAV-TIMEUTC, NAV-TIMEGPS, NAV-STATUS]`.

"""


def _psns_max_points_table() -> str:
    rows = []
    for hz in (1, 2, 5, 10, 20, 25, 50):
        n = psns.max_points(115200, hz)
        rows.append((f"{hz}", f"{11520 / hz:,.0f}", f"{n}", f"{psns.frame_bytes_obs(n)}",
                     f"{100 * psns.frame_bytes_obs(n) * hz / 11520:.1f} %"))
    return _table(rows, ("frame rate, Hz", "line bytes per frame period", "largest N", "frame bytes", "line load"))


def _nmea_nav_output(w: Any) -> None:
    """Section 7.1: the firmware's NMEA 0183 navigation output (builders: protocols.nmea_build, protocols.nmea_nav)."""
    import datetime as _dt

    from . import nmea_build, nmea_nav

    tm, day = _dt.time(8, 14, 30), _dt.date(2019, 9, 18)
    w("### 7.1 NMEA navigation output\n")
    w("`firmware.nmea` makes the firmware write NMEA 0183 sentences of its navigation solution: on the host port "
      "after the tick's NAV_SOLUTION frame, or alone on a second host port (`links.host_nmea`: routed to a DSP UART "
      "with a free transmitter, or, without a route of its own, sharing UART0, where the FPGA splits UART0's output "
      "frame by frame, each checked by its own CRC or checksum, binary frames to `host` and NMEA/`$PSNS` sentences to "
      "`host_nmea`: docs/runtime.md; a reader that sniffs binary protocols, such as gpsd, can take a NAV_SOLUTION "
      "frame for a Trimble TSIP packet and stop reporting the NMEA fixes, so give it the second port). Position, "
      "velocity and time (GGA, RMC, VTG, ZDA) at `rate_hz`, heading and attitude (HDT, THS, PASHR) at "
      "`attitude_rate_hz`, both on IMU ticks (the rates divide the IMU rate). In a tick with both, the heading "
      "group comes first: gpsd ends its reporting cycle at the last timed sentence of a burst. Nothing before GNSS "
      "gave UTC; before the first solution GGA quality 0, RMC `V`, THS `V` and ZDA only. Talker `firmware.nmea."
      "talker` (default GN).\n")
    rows = [
        ("GGA", "UTC of the tick (hhmmss.ss, to 10 ms), lat/lon (ddmm.mmmmm: 1e-5 arc-minute, 1.85 cm), quality 1 "
                "GNSS-aided / 6 dead reckoning, 12 satellites, HDOP 1.00, altitude = WGS-84 ellipsoidal height "
                "(m, 3 decimals) with geoid separation 0.000 (the firmware has no geoid model)",
         nmea_build.build_gga(tm, 39.979, 116.339, 50.0, 0.0, quality=1, num_sats=12, hdop=1.0, talker="GN")),
        ("RMC", "UTC, A, lat/lon, horizontal speed (knots, 3 decimals), course over ground = atan2(v_E, v_N) (deg "
                "true, 2 decimals), date, mode A / E",
         nmea_build.build_rmc(tm, day, 39.979, 116.339, 10.0, 30.0, mode="A", talker="GN")),
        ("VTG", "course (deg true), speed in knots and km/h, mode A / E",
         nmea_build.build_vtg(30.0, 10.0, mode="A", talker="GN")),
        ("ZDA", "UTC, day, month, year, zone 00:00", nmea_build.build_zda(tm, day, talker="GN")),
        ("HDT", "heading from the attitude quaternion (deg true, 2 decimals, [0, 360))",
         nmea_nav.build_hdt(30.25, talker="GN")),
        ("THS", "heading and mode A (GNSS-aided) / E (dead reckoning) / V (no solution)",
         nmea_nav.build_ths(30.25, "A", talker="GN")),
        ("PASHR", "UTC (hhmmss.sss), heading (deg true), T, roll (deg, positive right wing down), pitch (deg, nose "
                  "up), heave 0.00 m, roll / pitch / heading 1-sigma (deg, 3 decimals: the filter's level and "
                  "azimuth misalignment), aiding 1 GNSS / 0 none, IMU flag 0",
         nmea_nav.build_pashr(tm, 30.25, 0.5, -1.25, 0.0, 0.012, 0.011, 0.095, aiding=1)),
    ]
    w(_table([(k, d, "`" + s.decode().strip() + "`") for k, d, s in rows], ("sentence", "fields", "example")) + "\n")
    w("PASHR is the Ashtech/Applanix attitude layout (`$PASHR,hhmmss.sss,HHH.HH,T,RRR.RR,PPP.PP,heave,rr.rrr,pp.ppp,"
      "hh.hhh,aiding,imu*hh`) that Applanix POS MV and Hemisphere units emit and pynmea2 reads as `ASHRATT` (the "
      "tests read it back with pynmea2); gpsd 3.22 reports the heading of HDT as an ATT record. Cycle cost per "
      "sentence: 4 cycles per character plus the DP scaling of its "
      "values (`firmware_model.c674x.nmea_sentence`), and the course, speed and Euler angles (MATHLIB atan2, "
      "sqrt, asin).\n")


def generate() -> str:
    z = frame_sizes()
    out: list[str] = []
    w = out.append
    w("# psns-hil interface control document\n")
    w("Generated by `python -m protocols.icd > docs/icd.md` from the frame specs in `protocols/` "
      "(`tests/protocols/test_icd.py` fails when this file is out of date). Every byte table below is "
      "read from the module's declarative `construct` spec; every size from its encoder; golden vectors "
      "of every frame are in `tests/vectors/`.\n")
    w("## 1. Conventions\n")
    w("* Every UART link is asynchronous 8N1: 10 bits on the line per byte. Line rates are the scenario "
      "defaults (`links`, `fpga.uarts`) and can be changed per scenario; the budget below uses the defaults.\n"
      "* Byte order: STIM datagrams are big-endian (the sensor's order, TS1524 r31); every frame defined by "
      "this project (FPGA, PSNS, host, monitor, CAN) is little-endian, the C6747's native order; UBX is "
      "little-endian (u-blox).\n"
      "* `u16 LE` = unsigned 16-bit little-endian, `s24 BE` = signed (two's complement) 24-bit big-endian, "
      "`f32`/`f64` = IEEE 754. Physical value = raw x scale.\n"
      "* Streams are framed by sync bytes, lengths and checksums; the one `StreamDecoder` resynchronises "
      "at header + 1 after any failed candidate and counts garbage bytes, checksum, length and parse errors.\n")
    w("Checksums (`protocols/crc.py`; check value = CRC of ASCII `123456789`):\n")
    w(_table([
        ("CRC-8", "poly 0x07, init 0xFF, no reflection, no xor", "0xFB",
         "STIM210 datagram; STIM Utility Mode (decimal)"),
        ("CRC-16/CCITT-FALSE", "poly 0x1021, init 0xFFFF, no reflection, no xor", "0x29B1",
         "FPGA IMU/MAG, PSNS, host, monitor frames"),
        ("CRC-32/MPEG-2", "poly 0x04C11DB7, init 0xFFFFFFFF, no reflection, no xor", "0x0376E6E7",
         "STIM300 datagram (+ dummy 0x00 bytes to a multiple of 4)"),
        ("NMEA XOR", "XOR of the bytes between `$` and `*`, two upper-case hex digits", "-", "NMEA, $PSNS text"),
        ("UBX Fletcher-8", "CK_A += b, CK_B += CK_A over class..payload", "-", "UBX"),
    ], ("name", "definition", "check", "used by")) + "\n")
    assert crc.crc8_stim(b"123456789") == 0xFB and crc.crc16_ccitt(b"123456789") == 0x29B1

    w("## 2. Ports, links and bandwidth budget\n")
    w("```\n"
      " PSNS camera --RS232 psns--> FPGA PSNS port --uart2--> DSP UART2\n"
      " STIM gyro   --RS422 gyro--> FPGA GYRO port --\\\n"
      " accelerometers --ADC (24 bit)--> FPGA -------+--> IMU/MAG frames --uart1--> DSP UART1\n"
      " magnetometer --------------------> FPGA -----/\n"
      " GNSS rx     --RS422 gnss--> FPGA GNSS port --uart3--> DSP UART3 (FPGA UART core, EMIFA)   PPS -> FPGA latch\n"
      " host        <-RS422 host--> FPGA HOST port <-uart0--> DSP UART0\n"
      " DSP --CAN 2.0B--> CAN bus;  FPGA MONITOR port: every channel above, tagged and time-stamped\n"
      "```\n")
    w(f"Rates used: IMU trigger {RATE['imu']:g} Hz, NAV_SOLUTION {RATE['nav']:g} Hz (default output rate), "
      f"GNSS epoch {RATE['gnss']:g} Hz, MAG {RATE['mag']:g} Hz, PSNS observation frames {RATE['psns_obs']:g} Hz "
      f"with {PSNS_EXAMPLE_POINTS} points, compass and solar-vector frames {RATE['psns_compass']:g} Hz, "
      f"STATUS {RATE['status']:g} Hz, text output {RATE['text']:g} Hz. Bytes/s available = baud / 10.\n")
    w(_table(budget_rows(), ("link", "between", "baud", "frames", "needed, B/s", "available, B/s", "load")) + "\n")
    w("Decode cost is measured by `make bench` (`benchmarks/bench_decoders.py`): every decoder runs at "
      "20x or more of its link's full line rate.\n")
    w("Largest POLARIZATION_OBS point count N on the RS232 PSNS link at 115200 baud (`protocols.psns.max_points`, "
      "frame = 7 + 13 + 10 N bytes):\n")
    w(_psns_max_points_table() + "\n")

    # -- STIM ----------------------------------------------------------------------------------
    w("## 3. Gyro / IMU datagrams (link `gyro`, RS422, 460800 baud, one datagram per 5 ms ExtTrig)\n")
    w("The FPGA strobes the STIM external trigger at 200 Hz; the datagram follows within 86 us. The "
      "datagram counter counts 2000 Hz internal samples, so it steps by **10** per datagram "
      "(`protocols.stim.counter_step(200) == 10`). The decoder is configured per device and format "
      "(`Stim210Format('m')`, `Stim300Format(0x93)`), never from the ID: 0x90 is a different frame on each.\n")
    w("### 3.1 STIM210 normal-mode datagrams (big-endian; docs/reference/wire-formats.md section 1.8)\n")
    rows: list[tuple[str, ...]] = []
    for letter, (ident, groups) in stim.STIM210_FORMATS.items():
        f = stim.Stim210Format(letter)
        rows.append((f"d {letter}", f"0x{ident:02X}", ", ".join(("gyro", "status", *groups)), str(f.length),
                     str(f.length + 2)))
    w(_table(rows, ("format", "ID", "content", "bytes", "with CR LF")) + "\n")
    w("Format `m` (0xA5, the default gyro format):\n")
    w(_spec_table(stim.stim210_spec("m")) + "\n")
    w("Format `p` (0xA8, every optional field):\n")
    w(_spec_table(stim.stim210_spec("p")) + "\n")
    w("### 3.2 STIM300 normal-mode datagrams (big-endian; TS1524 r31 Tables 5-20..5-23)\n")
    rows = [(f"0x{i:02X}", ", ".join(("rate", *g)), str(n), str(d), str(n + 2), era)
            for i, (g, n, d, era) in stim.STIM300_DATAGRAMS.items()]
    w(_table(rows, ("ID", "content", "bytes", "CRC dummy bytes", "with CR LF", "revision")) + "\n")
    w("Full content, ID 0xF7 (r31, PPS) / 0xAF (AUX era); reduced IDs omit absent clusters in the same order:\n")
    w(_spec_table(stim.stim300_spec(0xF7)) + "\n")
    w("STATUS byte: b7 system integrity error, b6 start-up, b5 outside operating conditions, b4 overload, "
      "b3 channel error, b2/b1/b0 Z/Y/X channel. Accelerometer LSB per range (g): "
      + ", ".join(f"{k} g: 2^{int(math.log2(v))}" for k, v in stim.STIM300_ACCEL_LSB_G.items())
      + "; incremental velocity (m/s): "
      + ", ".join(f"{k} g: 2^{int(math.log2(v))}" for k, v in stim.STIM300_ACCEL_DV_LSB_MPS.items())
      + ". Utility Mode lines carry a CRC-8 in decimal: `$isn,` -> 28, `#isn,0,N2558184602002,` -> 32.\n")

    # -- FPGA ----------------------------------------------------------------------------------
    w("## 4. Accelerometer acquisition and the FPGA frames (link `uart1`, FPGA -> DSP UART1, 460800 baud)\n")
    w(f"ADC: 24-bit two's complement, +-{imu_frame.ADC_VREF_V} V reference: "
      f"{imu_frame.ADC_VOLTS_PER_LSB * 1e9:.5f} nV per LSB. Accelerometer sensitivity (V/g) x, y, z: "
      + ", ".join(f"{v:g}" for v in imu_frame.ACCEL_VOLTS_PER_G)
      + " (x: Colibrys MS9030 90 mV/g; y, z: +-25 g over +-2.7 V). g per LSB: "
      + ", ".join(f"{imu_frame.ADC_VOLTS_PER_LSB / v * 1e6:.3f} ug" for v in imu_frame.ACCEL_VOLTS_PER_G)
      + ". The code is the boxcar mean over the trigger interval.\n")
    w(f"### 4.1 IMU frame (msg_type 0x01, {imu_frame.IMU_FRAME_LEN} bytes, 200 Hz)\n")
    w(_spec_table(imu_frame.IMU_FRAME_SPEC) + "\n")
    w(f"### 4.2 MAG frame (msg_type 0x02, {imu_frame.MAG_FRAME_LEN} bytes, at the magnetometer rate)\n")
    w(_spec_table(imu_frame.MAG_FRAME_SPEC) + "\n")
    w("`FpgaStatus`: " + ", ".join(f"0x{int(m):02X} {m.name}" for m in imu_frame.FpgaStatus)
      + ". `MagStatus`: " + ", ".join(f"0x{int(m):02X} {m.name}" for m in imu_frame.MagStatus) + ".\n")

    # -- GNSS ----------------------------------------------------------------------------------
    w("## 5. GNSS (link `gnss`, RS422, 9600 baud; through the FPGA to `uart3` at 115200)\n")
    w(f"One epoch per second by default (`protocols.gnss.build_epoch`; `rate_hz` up to 20): the default NMEA set "
      f"RMC, VTG, GGA, GSA, ZDA is {z['nmea_epoch']} bytes ({z['nmea_epoch'] * 10 / 9600 * 1000:.0f} ms of line "
      f"time at 9600 baud); UBX NAV-PVT + NAV-STATUS add {z['ubx_epoch']} bytes. PPS rises at every whole UTC "
      "second (1 Hz at any navigation rate); the FPGA latches its counter on it and the IMU frame carries the "
      "latch. An external receiver's PPS comes from a modem line of a real serial port (`serial:///dev/ttyUSB0?"
      "pps=dcd` or `pps=cts`, waited for with TIOCMIWAIT); a pty carries no modem lines, so a receiver on "
      "`pty://gnss` has no PPS (the port reports it).\n")
    w("### 5.1 NMEA 0183 sentences\n")
    w("`$` + talker (GP, GN, ...) + type + comma-separated fields + `*` + XOR checksum (2 hex digits) + CR LF, "
      f"at most {nmea.NMEA_MAX_LEN} characters.\n")
    for kind, fields in NMEA_FIELDS.items():
        w(f"{kind}:\n")
        w(_table([(str(i + 1), n, f, m) for i, (n, f, m) in enumerate(fields)], ("field", "name", "format", "meaning"))
          + "\n")
    w(GNSS_INPUT_TEXT)
    w(NMEA_PARSE_TEXT)
    w(GNSS_RECEIVER_TEXT)
    w("### 5.2 UBX frame\n")
    w(_spec_table(ubx.UBX_FRAME_SPEC) + "\n")
    w(f"UBX-NAV-PVT payload (class 0x01, id 0x07, {ubx.NAV_PVT_LEN} bytes, frame {ubx.NAV_PVT_LEN + 8} bytes; "
      f"read by its prefix: protocol 14 (u-blox 7) sends {ubx.NAV_PVT_LEN_V14} bytes, the layout below up to pDOP "
      f"(the first {ubx.NAV_PVT_PREFIX_V14} bytes) then 6 reserved bytes, and the fields after pDOP read as 0; "
      f"a longer payload of a later protocol is read by its first {ubx.NAV_PVT_LEN} bytes; any other length is a "
      "length error):\n")
    w(_spec_table(ubx.NAV_PVT_SPEC) + "\n")
    w(f"UBX-NAV-STATUS payload (class 0x01, id 0x03, {ubx.NAV_STATUS_LEN} bytes):\n")
    w(_spec_table(ubx.NAV_STATUS_SPEC) + "\n")
    for title, mid, spec in (("NAV-POSLLH", ubx.ID_NAV_POSLLH, ubx.NAV_POSLLH_SPEC),
                             ("NAV-SOL", ubx.ID_NAV_SOL, ubx.NAV_SOL_SPEC),
                             ("NAV-VELNED", ubx.ID_NAV_VELNED, ubx.NAV_VELNED_SPEC),
                             ("NAV-TIMEGPS", ubx.ID_NAV_TIMEGPS, ubx.NAV_TIMEGPS_SPEC),
                             ("NAV-TIMEUTC", ubx.ID_NAV_TIMEUTC, ubx.NAV_TIMEUTC_SPEC)):
        w(f"UBX-{title} payload (class 0x01, id 0x{mid:02X}, {spec.sizeof()} bytes; u-blox 5/6/7, and M8/F9 "
          "configured so: 5.1.3):\n")
        w(_spec_table(spec) + "\n")
    w("### 5.3 UBX from the host to the receiver (`protocols/ubx_cfg.py`)\n")
    w("The modelled u-blox answers on its own link as a real one does: a poll (the message with an empty payload; "
      "CFG-PRT with a 1-byte portID, CFG-MSG with class and id) is answered with the message, and every CFG "
      "message with ACK-ACK or, when it cannot be applied (another port, an unknown message, a rate above 20 Hz), "
      "ACK-NAK. CFG-MSG rates (send every N epochs on UART1) and CFG-PRT's outProtoMask change the output at the "
      "next epoch, CFG-RATE at the next whole UTC second; a CFG-PRT baud rate is acknowledged and reported back, "
      "the line itself stays at `links.gnss.baud`. MON-VER reports a u-blox M8 (\"ROM CORE 3.01 (107888)\", "
      "PROTVER=18.00). Counted in the summary's `devices`: `gnss_host_polls`, `gnss_host_acks`, `gnss_host_naks`, "
      "`gnss_host_ignored`.\n")
    for title, spec in (("ACK-ACK (0x05 0x01) / ACK-NAK (0x05 0x00)", ubx_cfg.ACK_SPEC),
                        ("CFG-PRT (0x06 0x00), UART port", ubx_cfg.CFG_PRT_SPEC),
                        ("CFG-MSG (0x06 0x01); the 3-byte set form is class, id, rate on this port",
                         ubx_cfg.CFG_MSG_SPEC),
                        ("CFG-RATE (0x06 0x08)", ubx_cfg.CFG_RATE_SPEC),
                        (f"MON-VER (0x0A 0x04): then {ubx_cfg.MON_VER_EXT_LEN}-byte extension strings",
                         ubx_cfg.MON_VER_HEAD_SPEC)):
        w(f"{title}:\n")
        w(_spec_table(spec) + "\n")

    # -- PSNS ----------------------------------------------------------------------------------
    w("## 6. Polarization sensor (link `psns`, RS232, 115200 baud; through the FPGA to `uart2`)\n")
    w("Frame (the payload length must equal 13 + 10 N for observations, 13 + 5 l for compass frames, 29 for the "
      "solar vector; a disagreeing length is refused after 18 bytes):\n")
    w(_spec_table(psns.PSNS_FRAME_SPEC) + "\n")
    w("Payload of 0x10 POLARIZATION_OBS (offsets within the payload; frame offset = 5 + payload offset):\n")
    w(_spec_table(psns.POLARIZATION_OBS_SPEC) + "\n")
    w("Each point (10 bytes):\n")
    w(_spec_table(psns.POINT_SPEC) + "\n")
    w("Payload of 0x11 COMPASS:\n")
    w(_spec_table(psns.COMPASS_SPEC) + "\n")
    w("Each unit (5 bytes):\n")
    w(_spec_table(psns.UNIT_SPEC) + "\n")
    w("Payload of 0x12 SOLAR_VECTOR:\n")
    w(_spec_table(psns.SOLAR_VECTOR_SPEC) + "\n")
    w("Time tag (docs/architecture.md, \"Conventions\"): exposure middle = reception time of the last byte - "
      "frame bytes x 10 / baud - latency_us. `PsnsStatus`: "
      + ", ".join(f"0x{int(m):02X} {m.name}" for m in psns.PsnsStatus) + ".\n")

    # -- Host ----------------------------------------------------------------------------------
    w("## 7. Host port (DSP UART0 <-> FPGA HOST, RS422, 460800 baud)\n")
    w("Frame (both directions):\n")
    w(_spec_table(host.HOST_FRAME_SPEC) + "\n")
    w(_table([("0x01", "NAV_SOLUTION", "DSP -> host", f"{host.NAV_SOLUTION_LEN}", "output rate (default 100 Hz)"),
              ("0x02", "STATUS", "DSP -> host", f"{host.STATUS_LEN}", "1 Hz and on REQUEST_STATUS"),
              ("0x03", "ACK", "DSP -> host", "3", "one per command"),
              ("0x81", "RESET_FILTER", "host -> DSP", "2", "command"),
              ("0x82", "SELECT_VARIANT", "host -> DSP", "2", "command"),
              ("0x83", "SET_OUTPUT_RATE", "host -> DSP", "5", "command"),
              ("0x84", "REQUEST_STATUS", "host -> DSP", "1", "command")],
             ("msg_id", "message", "direction", "payload bytes", "when")) + "\n")
    w("NAV_SOLUTION payload (offsets within the payload, frame offset = 5 + payload offset; new fields are only "
      "ever appended, decoders accept longer payloads):\n")
    w(_spec_table(host.NAV_SOLUTION_SPEC) + "\n")
    w("Optional VARIANT block, appended after the 102 bytes above by the filter variants other than the base one "
      "(payload offsets 102..107; the base variant's frame is unchanged):\n")
    w(_spec_table(host.NAV_VARIANT_BLOCK_SPEC) + "\n")
    w("`variant_mode` per variant: " + "; ".join(f"{k}: {v}" for k, v in host.VARIANT_MODE_MEANING.items()) + ".\n")
    w("`NavMode`: " + ", ".join(f"0x{int(m):04X} {m.name}" for m in host.NavMode) + "; bits 8-11 the "
      "`FilterVariant`: " + ", ".join(f"{int(v)} {v.name}" for v in host.FilterVariant) + ".\n")
    w("STATUS payload:\n")
    w(_spec_table(host.STATUS_SPEC) + "\n")
    w("ACK payload (`AckResult`: " + ", ".join(f"{int(v)} {v.name}" for v in host.AckResult) + "):\n")
    w(_spec_table(host.ACK_SPEC) + "\n")
    for cid, name in ((host.CMD_RESET_FILTER, "RESET_FILTER"), (host.CMD_SELECT_VARIANT, "SELECT_VARIANT"),
                      (host.CMD_SET_OUTPUT_RATE, "SET_OUTPUT_RATE"), (host.CMD_REQUEST_STATUS, "REQUEST_STATUS")):
        w(f"0x{cid:02X} {name} payload:\n")
        w(_spec_table(host.COMMAND_SPECS[cid]) + "\n")
    w("Optional text output for terminal users (NMEA framing and checksum on the same port; "
      "`protocols.host.nav_text_sentences`), every sentence `$PSNS<kind>,time_s,...`:\n")
    rows = [(f"$PSNS{k}", "time_s (s, 3 decimals), " + ", ".join(f"{n} ({f})" for n, f in zip(names, fmts)))
            for k, (names, fmts) in host.TEXT_SENTENCES.items()]
    w(_table(rows, ("sentence", "fields after the address (Python format spec)")) + "\n")
    w("Example: `" + host.nav_text_sentences(_sample_nav()).decode().split("\r\n")[0] + "`\n")
    _nmea_nav_output(w)

    # -- CAN -----------------------------------------------------------------------------------
    w(f"## 8. CAN (CAN 2.0B, 29-bit ids, {can_nav.CAN_BITRATE} bit/s; `protocols/psns_nav.dbc`)\n")
    w("Intel byte order, DLC 8. Per epoch the frames go out in id order, TIME first; `seq8` pairs frames of one "
      "epoch. Values beyond a signal's range saturate (seq, time_s, deadline_misses wrap; heading modulo 360 deg).\n")
    for m in can_nav.CAN_MESSAGES:
        w(f"`{m.name}` id 0x{m.frame_id:07X}, every {m.cycle_ms} ms ({1000 / m.cycle_ms:g} Hz): {m.comment}\n")
        w(_table([(f"{s.start}", f"{s.length}", f"{'s' if s.signed else 'u'}{s.length} LE", s.name, f"{s.scale:g}",
                   s.unit, s.comment) for s in m.signals],
                 ("start bit", "bits", "type", "signal", "scale", "unit", "meaning")) + "\n")

    # -- Monitor -------------------------------------------------------------------------------
    w(f"## 9. FPGA monitor multiplex (link `monitor`, {LINK_BAUD['monitor']} baud)\n")
    w("Each chunk of bytes crossing an FPGA port becomes one record, COBS-encoded and preceded by a 0x00 "
      "delimiter (`00 A 00 B 00 C ...`); 0x00 never occurs inside a record, so a reader joins mid-stream at the "
      "next 0x00. Channels: " + ", ".join(f"{v} {k}" for k, v in monitor.MONITOR_CHANNELS.items())
      + "; direction 0 towards the DSP, 1 away from it. Record before COBS:\n")
    w(_spec_table(monitor.MONITOR_RECORD_SPEC) + "\n")

    # -- Lockstep firmware interface -----------------------------------------------------------
    w(LOCKSTEP_TEXT)
    return "\n".join(out)


if __name__ == "__main__":  # pragma: no cover
    print(generate(), end="")
