"""The navigation solution on CAN 2.0B: message table, a struct codec, and the DBC text.

``protocols/psns_nav.dbc`` is generated from :data:`CAN_MESSAGES` (``python -m protocols.can_nav``
prints it) and is what a CAN tool loads; the tests load it with cantools and check that
cantools and :func:`encode_can_frames` produce the same bytes. This module needs no cantools.

Bus: CAN 2.0B, 29-bit identifiers, 500 kbit/s, DLC 8, every signal little-endian (Intel) and
byte-aligned. Per navigation epoch the DSP sends the frames in identifier order, TIME first,
so a receiver pairs the frames of one epoch by arrival (velocity, attitude, sigma and DSP frames
also carry ``seq8``, the low byte of the TIME frame's ``seq``). Cycle: 10 ms (100 Hz) for TIME,
POSITION, HEIGHT_MODE, VELOCITY, ATTITUDE; 100 ms (10 Hz) for the three SIGMA frames and DSP.

Values outside a signal's range saturate at its limit (``seq``, ``time_s`` and
``deadline_misses`` wrap instead), as a CAN node would send them.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Iterable
from dataclasses import dataclass

from .host import NavSolution

__all__ = [
    "CAN_BITRATE",
    "CAN_MESSAGES",
    "MESSAGE_BY_ID",
    "MESSAGE_BY_NAME",
    "CanMessage",
    "CanSignal",
    "can_frame_bits",
    "can_signals_to_nav",
    "dbc_text",
    "decode_can_frame",
    "decode_can_frames",
    "encode_can_frames",
    "nav_to_can_signals",
]

CAN_BITRATE = 500_000


@dataclass(frozen=True, slots=True)
class CanSignal:
    """One signal: byte-aligned little-endian field of ``length`` bits from bit ``start``."""

    name: str
    start: int
    length: int
    signed: bool
    scale: float
    unit: str
    comment: str
    wraps: bool = False
    phys_min: float | None = None  #: physical range if narrower than the raw range
    phys_max: float | None = None
    modulo: int | None = None  #: raw values wrap modulo this (heading: 36000 = 360 deg)

    @property
    def raw_min(self) -> int:
        if self.phys_min is not None:
            return math.ceil(round(self.phys_min / self.scale, 6))
        return -(1 << (self.length - 1)) if self.signed else 0

    @property
    def raw_max(self) -> int:
        if self.phys_max is not None:
            return math.floor(round(self.phys_max / self.scale, 6))
        return (1 << (self.length - 1)) - 1 if self.signed else (1 << self.length) - 1


@dataclass(frozen=True, slots=True)
class CanMessage:
    """One CAN frame of the navigation output."""

    name: str
    frame_id: int  #: 29-bit identifier
    cycle_ms: int
    signals: tuple[CanSignal, ...]
    comment: str

    @property
    def struct(self) -> struct.Struct:
        return _struct_of(self)


def _s(name: str, start: int, length: int, signed: bool, scale: float, unit: str, comment: str,
       wraps: bool = False, lo: float | None = None, hi: float | None = None, modulo: int | None = None) -> CanSignal:
    return CanSignal(name, start, length, signed, scale, unit, comment, wraps, lo, hi, modulo)


def _seq8(start: int = 48) -> CanSignal:
    return _s("seq8", start, 8, False, 1, "", "low byte of PSNS_NAV_TIME.seq", True)


CAN_MESSAGES: tuple[CanMessage, ...] = (
    CanMessage("PSNS_NAV_TIME", 0x0A50100, 10, (
        _s("seq", 0, 32, False, 1, "", "NAV_SOLUTION sequence number", True),
        _s("time_s", 32, 32, False, 0.001, "s", "time of validity (FPGA time), wraps after 49.7 days", True),
    ), "Epoch header: sequence and time of validity"),
    CanMessage("PSNS_NAV_POSITION", 0x0A50101, 10, (
        _s("lat_deg", 0, 32, True, 1e-7, "deg", "WGS-84 latitude", lo=-90, hi=90),
        _s("lon_deg", 32, 32, True, 1e-7, "deg", "WGS-84 longitude", lo=-180, hi=180),
    ), "Geodetic position"),
    CanMessage("PSNS_NAV_HEIGHT_MODE", 0x0A50102, 10, (
        _s("height_m", 0, 32, True, 0.001, "m", "ellipsoidal height"),
        _s("mode", 32, 16, False, 1, "", "NavMode bits; bits 8-11 filter variant"),
        _s("gnss_status", 48, 8, False, 1, "", "GGA fix quality of the last GNSS fix used"),
        _s("psns_status", 56, 8, False, 1, "", "0 none, 1 solar vector used, 2 rejected"),
    ), "Height, mode and aiding status"),
    CanMessage("PSNS_NAV_VELOCITY", 0x0A50103, 10, (
        _s("vel_e_mps", 0, 16, True, 0.01, "m/s", "east velocity"),
        _s("vel_n_mps", 16, 16, True, 0.01, "m/s", "north velocity"),
        _s("vel_u_mps", 32, 16, True, 0.01, "m/s", "up velocity"),
        _seq8(),
    ), "ENU velocity"),
    CanMessage("PSNS_NAV_ATTITUDE", 0x0A50104, 10, (
        _s("roll_deg", 0, 16, True, 0.01, "deg", "roll, right wing down positive", lo=-180, hi=180),
        _s("pitch_deg", 16, 16, True, 0.01, "deg", "pitch, nose up positive", lo=-90, hi=90),
        _s("heading_deg", 32, 16, False, 0.01, "deg", "heading clockwise from true north, [0, 360)",
           lo=0, hi=359.99, modulo=36000),
        _seq8(),
    ), "Attitude"),
    CanMessage("PSNS_NAV_SIGMA_ATT", 0x0A50105, 100, (
        _s("sigma_att_e_deg", 0, 16, False, 0.001, "deg", "1-sigma attitude error about east"),
        _s("sigma_att_n_deg", 16, 16, False, 0.001, "deg", "1-sigma attitude error about north"),
        _s("sigma_att_u_deg", 32, 16, False, 0.001, "deg", "1-sigma attitude error about up (heading)"),
        _seq8(),
    ), "Attitude uncertainty"),
    CanMessage("PSNS_NAV_SIGMA_VEL", 0x0A50106, 100, (
        _s("sigma_vel_e_mps", 0, 16, False, 0.001, "m/s", "1-sigma east velocity"),
        _s("sigma_vel_n_mps", 16, 16, False, 0.001, "m/s", "1-sigma north velocity"),
        _s("sigma_vel_u_mps", 32, 16, False, 0.001, "m/s", "1-sigma up velocity"),
        _seq8(),
    ), "Velocity uncertainty"),
    CanMessage("PSNS_NAV_SIGMA_POS", 0x0A50107, 100, (
        _s("sigma_pos_n_m", 0, 16, False, 0.01, "m", "1-sigma north position"),
        _s("sigma_pos_e_m", 16, 16, False, 0.01, "m", "1-sigma east position"),
        _s("sigma_pos_u_m", 32, 16, False, 0.01, "m", "1-sigma up position"),
        _seq8(),
    ), "Position uncertainty"),
    CanMessage("PSNS_NAV_DSP", 0x0A50108, 100, (
        _s("cpu_load_pct", 0, 16, False, 0.01, "%", "worst tick load of the last second"),
        _s("deadline_misses", 16, 32, False, 1, "", "cumulative deadline misses", True),
        _seq8(),
    ), "DSP health"),
)

MESSAGE_BY_ID = {m.frame_id: m for m in CAN_MESSAGES}
MESSAGE_BY_NAME = {m.name: m for m in CAN_MESSAGES}

_FMT = {(8, False): "B", (8, True): "b", (16, False): "H", (16, True): "h", (32, False): "I", (32, True): "i"}
_STRUCTS: dict[str, struct.Struct] = {}


def _struct_of(m: CanMessage) -> struct.Struct:
    st = _STRUCTS.get(m.name)
    if st is None:
        fmt, pos = "<", 0
        for s in m.signals:
            if s.start != pos:
                raise AssertionError(f"{m.name}.{s.name} is not contiguous")  # pragma: no cover
            fmt += _FMT[(s.length, s.signed)]
            pos += s.length
        fmt += "x" * ((64 - pos) // 8)
        st = _STRUCTS[m.name] = struct.Struct(fmt)
    return st


def _raw(sig: CanSignal, value: float) -> int:
    r = round(value / sig.scale)
    if sig.modulo is not None:
        return r % sig.modulo
    if sig.wraps:
        r &= (1 << sig.length) - 1
        return r - (1 << sig.length) if sig.signed and r > sig.raw_max else r
    return max(sig.raw_min, min(sig.raw_max, r))


def _phys(sig: CanSignal, raw: int) -> float | int:
    return raw if sig.scale == 1 else raw * sig.scale


def _values(n: NavSolution) -> dict[str, float]:
    sg = n.sigma
    return {
        "seq": n.seq, "time_s": n.time_s, "lat_deg": n.lat_deg, "lon_deg": n.lon_deg, "height_m": n.height_m,
        "mode": n.mode, "gnss_status": n.gnss_status, "psns_status": n.psns_status,
        "vel_e_mps": n.vel_enu_mps[0], "vel_n_mps": n.vel_enu_mps[1], "vel_u_mps": n.vel_enu_mps[2],
        "roll_deg": n.roll_deg, "pitch_deg": n.pitch_deg, "heading_deg": n.heading_deg % 360.0,
        "sigma_att_e_deg": sg[0], "sigma_att_n_deg": sg[1], "sigma_att_u_deg": sg[2],
        "sigma_vel_e_mps": sg[3], "sigma_vel_n_mps": sg[4], "sigma_vel_u_mps": sg[5],
        "sigma_pos_n_m": sg[6], "sigma_pos_e_m": sg[7], "sigma_pos_u_m": sg[8],
        "cpu_load_pct": n.cpu_load_pct, "deadline_misses": n.deadline_misses, "seq8": n.seq,
    }


def _raw_signals(n: NavSolution) -> dict[str, dict[str, int]]:
    v = _values(n)
    out: dict[str, dict[str, int]] = {}
    for m in CAN_MESSAGES:
        out[m.name] = {}
        for s in m.signals:
            x = v[s.name]
            if isinstance(x, float) and not math.isfinite(x):
                x = 0.0  # a NaN/inf cannot be sent; 0 is what the DSP's saturating cast gives
            out[m.name][s.name] = _raw(s, x)
    return out


def nav_to_can_signals(n: NavSolution) -> dict[str, dict[str, float | int]]:
    """Physical signal values per message name, already quantised to the signals' LSBs.

    The dict is what ``cantools.database.Database.encode_message(name, signals)`` takes.
    """
    raw = _raw_signals(n)
    return {m.name: {s.name: _phys(s, raw[m.name][s.name]) for s in m.signals} for m in CAN_MESSAGES}


def can_signals_to_nav(signals: dict[str, dict[str, float | int]]) -> NavSolution:
    """Rebuild a :class:`~protocols.host.NavSolution` from the physical signals of all nine messages."""
    missing = [m.name for m in CAN_MESSAGES if m.name not in signals]
    if missing:
        raise ValueError(f"CAN navigation epoch incomplete, missing {missing}")
    v: dict[str, float] = {}
    for m in CAN_MESSAGES:
        v.update(signals[m.name])
    return NavSolution(
        seq=int(v["seq"]), time_s=float(v["time_s"]), lat_deg=float(v["lat_deg"]), lon_deg=float(v["lon_deg"]),
        height_m=float(v["height_m"]),
        vel_enu_mps=(float(v["vel_e_mps"]), float(v["vel_n_mps"]), float(v["vel_u_mps"])),
        roll_deg=float(v["roll_deg"]), pitch_deg=float(v["pitch_deg"]), heading_deg=float(v["heading_deg"]),
        sigma=tuple(float(v[k]) for k in ("sigma_att_e_deg", "sigma_att_n_deg", "sigma_att_u_deg", "sigma_vel_e_mps",
                                          "sigma_vel_n_mps", "sigma_vel_u_mps", "sigma_pos_n_m", "sigma_pos_e_m",
                                          "sigma_pos_u_m")),
        mode=int(v["mode"]), gnss_status=int(v["gnss_status"]), psns_status=int(v["psns_status"]),
        cpu_load_pct=float(v["cpu_load_pct"]), deadline_misses=int(v["deadline_misses"]),
    )


def encode_can_frames(n: NavSolution, names: Iterable[str] | None = None) -> list[tuple[int, bytes]]:
    """``(29-bit id, 8 data bytes)`` for every message (or those in ``names``), in id order."""
    raw = _raw_signals(n)
    want = None if names is None else set(names)
    out = []
    for m in CAN_MESSAGES:
        if want is None or m.name in want:
            r = raw[m.name]
            out.append((m.frame_id, _struct_of(m).pack(*(r[s.name] for s in m.signals))))
    return out


def decode_can_frame(frame_id: int, data: bytes) -> tuple[str, dict[str, float | int]]:
    """``(message name, physical signals)`` of one frame. Raises ``ValueError`` for an unknown id or DLC."""
    m = MESSAGE_BY_ID.get(frame_id)
    if m is None:
        raise ValueError(f"CAN id 0x{frame_id:X} is not a navigation message")
    if len(data) != 8:
        raise ValueError(f"{m.name} needs 8 data bytes, got {len(data)}")
    raw = _struct_of(m).unpack(data)
    return m.name, {s.name: _phys(s, r) for s, r in zip(m.signals, raw)}


def decode_can_frames(frames: Iterable[tuple[int, bytes]]) -> NavSolution:
    """Rebuild one epoch's solution from its frames (all nine messages needed)."""
    return can_signals_to_nav(dict(decode_can_frame(i, d) for i, d in frames))


def can_frame_bits(dlc: int = 8, extended: bool = True, worst_case_stuffing: bool = True) -> int:
    """Bits on the bus for one data frame including the 3-bit interframe space.

    Extended frame: 67 bits of overhead (SOF, 29-bit id, SRR, IDE, RTR, r1, r0, DLC, CRC 15,
    delimiters, ACK, EOF 7, IFS 3) + 8 DLC bits of data; stuffing adds at most one bit per four
    of the 54 + 8 DLC stuffable bits (Davis et al., Real-Time Systems 35, 2007).
    """
    overhead, stuffable = (67, 54) if extended else (47, 34)
    bits = overhead + 8 * dlc
    if worst_case_stuffing:
        bits += (stuffable + 8 * dlc - 1) // 4
    return bits


def _fmt_num(x: float) -> str:
    return repr(int(x)) if float(x).is_integer() else repr(x).replace("e-0", "e-").upper().replace("E-", "E-")


def dbc_text() -> str:
    """The DBC file for :data:`CAN_MESSAGES` (what ``protocols/psns_nav.dbc`` holds)."""
    lines = [
        'VERSION "psns-hil nav 1"',
        "",
        "NS_ :",
        "    CM_",
        "    BA_DEF_",
        "    BA_",
        "    VAL_",
        "    BA_DEF_DEF_",
        "",
        "BS_:",
        "",
        "BU_: PSNS_DSP HOST",
        "",
    ]
    for m in CAN_MESSAGES:
        lines.append(f"BO_ {m.frame_id | 0x80000000} {m.name}: 8 PSNS_DSP")
        for s in m.signals:
            lo = s.raw_min * s.scale
            hi = s.raw_max * s.scale
            lines.append(
                f" SG_ {s.name} : {s.start}|{s.length}@1{'-' if s.signed else '+'} ({_fmt_num(s.scale)},0) "
                f'[{_fmt_num(round(lo, 9))}|{_fmt_num(round(hi, 9))}] "{s.unit}" HOST'
            )
        lines.append("")
    lines.append('CM_ "Navigation solution of the psns-hil DSP on CAN 2.0B (generated by protocols/can_nav.py).";')
    for m in CAN_MESSAGES:
        lines.append(f'CM_ BO_ {m.frame_id | 0x80000000} "{m.comment}";')
        for s in m.signals:
            lines.append(f'CM_ SG_ {m.frame_id | 0x80000000} {s.name} "{s.comment}";')
    lines += [
        'BA_DEF_ BO_ "GenMsgCycleTime" INT 0 10000;',
        'BA_DEF_ BO_ "VFrameFormat" ENUM "StandardCAN","ExtendedCAN";',
        'BA_DEF_ "BusType" STRING ;',
        'BA_DEF_ "Baudrate" INT 10000 1000000;',
        'BA_DEF_DEF_ "GenMsgCycleTime" 0;',
        'BA_DEF_DEF_ "VFrameFormat" "ExtendedCAN";',
        'BA_DEF_DEF_ "BusType" "CAN";',
        f'BA_DEF_DEF_ "Baudrate" {CAN_BITRATE};',
        'BA_ "BusType" "CAN";',
        f'BA_ "Baudrate" {CAN_BITRATE};',
    ]
    for m in CAN_MESSAGES:
        lines.append(f'BA_ "GenMsgCycleTime" BO_ {m.frame_id | 0x80000000} {m.cycle_ms};')
        lines.append(f'BA_ "VFrameFormat" BO_ {m.frame_id | 0x80000000} 1;')
    lines.append(f"VAL_ {0x0A50102 | 0x80000000} psns_status 0 \"none\" 1 \"solar vector used\" 2 \"rejected\" ;")
    lines.append(f"VAL_ {0x0A50102 | 0x80000000} gnss_status 0 \"invalid\" 1 \"GPS\" 2 \"DGPS\" 4 \"RTK fixed\" "
                 f"5 \"RTK float\" 6 \"dead reckoning\" ;")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":  # pragma: no cover
    print(dbc_text(), end="")
