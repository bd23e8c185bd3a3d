"""Sensonor STIM210 and STIM300 normal-mode datagrams (RS422).

STIM210 (gyro only)
-------------------

Source: ``shared/reference/protocols.md`` section 1.8 (layouts from the ut-issl/c2a-aobc
STIM210 flight driver and its s2e-aobc emulator; scale factors identical to the STIM300,
TS1524 r31 section 7.5.2.2). All multi-byte fields are big-endian two's complement.

===========  ====  =====================================================  ===========
format       ID    layout after the ID                                    bytes
===========  ====  =====================================================  ===========
``s``        0x90  gyro X,Y,Z s24; status u8; CRC-8                        12
``e``        0x92  gyro; status; 3 reserved bytes; CRC-8                   15
``j``        0xA0  gyro; status; temp X,Y,Z s16; CRC-8                     18
``k``        0xA2  gyro; status; counter u8; CRC-8                         13
``l``        0xA4  gyro; status; latency u16 us; CRC-8                     14
``m``        0xA5  gyro; status; counter; latency; CRC-8                   15
``n``        0x99  gyro; status; temps; counter; CRC-8                     19
``o``        0xA6  gyro; status; temps; latency; CRC-8                     20
``p``        0xA8  gyro; status; temps; counter; latency; CRC-8            21
===========  ====  =====================================================  ===========

With ``<CR><LF>`` termination two more bytes follow the CRC (not covered by it).
The CRC-8 (poly 0x07, init 0xFF) covers the ID through the last data byte.

Scale: angular rate 2^-14 deg/s per LSB; incremental angle 2^-21 deg per LSB;
temperature 2^-8 degC; latency 1 us. The counter counts the 2000 Hz internal samples, so at
a 200 Hz external trigger it steps by 10 (mod 256) per datagram.

The decoder is configured per device and format (``Stim210Format("m")``), never guessed from
the ID: 0x90 means a different frame on a STIM300.

STIM300 (gyro, accelerometers, inclinometers)
---------------------------------------------
Source: TS1524 rev. 31 (Tables 5-20 .. 5-23, section 7.5), as summarised in
``shared/reference/protocols.md`` sections 1.2-1.7. Full content in wire order (reduced
datagrams omit absent clusters and keep the order; temperatures only for present clusters)::

    ID u8 | gyro X,Y,Z s24 | STATUS | acc X,Y,Z s24 | STATUS | incl X,Y,Z s24 | STATUS
       | gyro temps 3 x s16 | STATUS | acc temps | STATUS | incl temps | STATUS
       | PPS (r31) or AUX (older revisions) s24 | STATUS | counter u8 | latency u16 us | CRC-32 u32

Big-endian throughout. The CRC-32/MPEG-2 covers the ID through the latency plus 0..3 dummy
0x00 bytes (never sent) that pad the covered bytes to a multiple of four; an optional
``<CR><LF>`` follows the CRC, outside it. :data:`STIM300_DATAGRAMS` lists every ID of the r31
datasheet and the legacy AUX-era IDs (0x97, 0x98..0x9C, 0xAD..0xAF) with their wire lengths
and dummy counts. :class:`Stim300Format` is configured with the ID the unit is set to send.

Scale factors (TS1524 r31 7.5.2.2): gyro as for the STIM210; accelerometer 2^-20 / 2^-19 /
2^-18 / 2^-16 g per LSB for the 5 / 10 / 30 / 80 g ranges (incremental velocity 2^-23 ..
2^-19 m/s); inclinometer 2^-22 g (2^-25 m/s); temperatures 2^-8 degC; PPS 1 us.
STATUS bits (Table 5-23): 7 system integrity error, 6 start-up, 5 outside operating
conditions, 4 overload, 3 channel error, 2/1/0 the Z/Y/X channel concerned.

Utility Mode lines (``$cmd,...,crc`` / ``#resp,...,crc``) carry a CRC-8 written in decimal ASCII
over everything from ``$``/``#`` through the last comma: :func:`utility_mode_crc`.
"""

from __future__ import annotations

import enum
import struct
from dataclasses import dataclass

from construct import Array, Bytes, Const, Int8ub, Int16sb, Int16ub, Int24sb, Int32ub, Struct

from ._fastinit import fast_frozen_init
from .crc import crc8_stim, crc32_mpeg2

__all__ = [
    "STIM210_FORMATS",
    "GYRO_RATE_LSB_DPS",
    "GYRO_ANGLE_LSB_DEG",
    "TEMP_LSB_DEGC",
    "STIM_COUNTER_HZ",
    "StimDatagram",
    "Stim210Format",
    "stim210_spec",
    "STIM300_DATAGRAMS",
    "STIM300_ACCEL_LSB_G",
    "STIM300_ACCEL_DV_LSB_MPS",
    "INCL_LSB_G",
    "INCL_DV_LSB_MPS",
    "PPS_LSB_US",
    "StimStatus",
    "Stim300Datagram",
    "Stim300Format",
    "stim300_spec",
    "counter_step",
    "utility_mode_crc",
]

#: deg/s per LSB, angular-rate output (TS1524 r31 7.5.2.2; same on STIM210).
GYRO_RATE_LSB_DPS = 2.0**-14
#: deg per LSB, incremental-angle output.
GYRO_ANGLE_LSB_DEG = 2.0**-21
#: degC per LSB of the s16 temperature words.
TEMP_LSB_DEGC = 2.0**-8
#: Internal sample rate counted by the datagram counter, Hz.
STIM_COUNTER_HZ = 2000
#: STIM300 accelerometer LSB, g, per range option (TS1524 r31 7.5.2.2; 2 g was dropped in r31).
STIM300_ACCEL_LSB_G = {5: 2.0**-20, 10: 2.0**-19, 30: 2.0**-18, 80: 2.0**-16}
#: STIM300 accelerometer LSB in incremental-velocity output, m/s per sample, per range option.
STIM300_ACCEL_DV_LSB_MPS = {5: 2.0**-23, 10: 2.0**-22, 30: 2.0**-21, 80: 2.0**-19}
#: STIM300 inclinometer LSB, g (acceleration output).
INCL_LSB_G = 2.0**-22
#: STIM300 inclinometer LSB, m/s per sample (incremental-velocity output).
INCL_DV_LSB_MPS = 2.0**-25
#: STIM300 PPS word (r31, "time since detection" option), us per LSB.
PPS_LSB_US = 1


class StimStatus(enum.IntFlag):
    """STATUS byte bits of STIM datagrams (TS1524 r31 Table 5-23)."""

    X_CHANNEL = 0x01
    Y_CHANNEL = 0x02
    Z_CHANNEL = 0x04
    CHANNEL_ERROR = 0x08  #: error in the measurement channel(s) flagged in bits 0-2
    OVERLOAD = 0x10  #: overload in the channel(s) flagged in bits 0-2
    OUTSIDE_OPERATING_CONDITIONS = 0x20
    STARTUP = 0x40  #: gyro stabilisation after Init Mode: data not valid
    SYSTEM_INTEGRITY_ERROR = 0x80


def counter_step(sample_rate_hz: float) -> int:
    """Datagram-counter step between consecutive datagrams at ``sample_rate_hz``.

    The counter counts the 2000 Hz internal samples (TS1524 r31 7.5.2.2.18), so it steps by
    ``2000 / rate``: 1 at 2000 Hz, 16 at 125 Hz and 10 for a 200 Hz external trigger.
    """
    step = STIM_COUNTER_HZ / sample_rate_hz
    if step != int(step) or step < 1:
        raise ValueError(f"{sample_rate_hz} Hz does not divide the {STIM_COUNTER_HZ} Hz internal rate")
    return int(step)


def utility_mode_crc(text: str | bytes) -> int:
    """CRC-8 of a STIM Utility Mode line, from ``$``/``#`` through the last comma (sent in decimal).

    TS1524 r31 Figure 10-2: ``utility_mode_crc("$isn,") == 28`` and
    ``utility_mode_crc("#isn,0,N2558184602002,") == 32``.
    """
    return crc8_stim(text.encode("ascii") if isinstance(text, str) else text)

#: format letter -> (datagram ID, optional field groups in wire order)
STIM210_FORMATS: dict[str, tuple[int, tuple[str, ...]]] = {
    "s": (0x90, ()),
    "e": (0x92, ("reserved",)),
    "j": (0xA0, ("temperature",)),
    "k": (0xA2, ("counter",)),
    "l": (0xA4, ("latency",)),
    "m": (0xA5, ("counter", "latency")),
    "n": (0x99, ("temperature", "counter")),
    "o": (0xA6, ("temperature", "latency")),
    "p": (0xA8, ("temperature", "counter", "latency")),
}

_GROUP_SIZE = {"reserved": 3, "temperature": 6, "counter": 1, "latency": 2}


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class StimDatagram:
    """One decoded STIM normal-mode gyro datagram (raw integer words).

    ``gyro`` holds the three s24 words (X, Y, Z); multiply by :data:`GYRO_RATE_LSB_DPS`
    (rate output) or :data:`GYRO_ANGLE_LSB_DEG` (incremental angle). ``temperature`` holds
    s16 words in 2^-8 degC. Fields absent from the configured format are ``None``.
    """

    ident: int
    gyro: tuple[int, int, int]
    status: int
    counter: int | None = None
    latency_us: int | None = None
    temperature: tuple[int, int, int] | None = None
    reserved: bytes | None = None


def stim210_spec(fmt: str) -> Struct:
    """The declarative ``construct`` layout of one STIM210 format, CRC byte included."""
    ident, groups = STIM210_FORMATS[fmt]
    fields = [
        "ident" / Const(ident, Int8ub) * f" |  | datagram ID 0x{ident:02X}",
        "gyro" / Array(3, Int24sb) * "2^-14 / 2^-21 | deg/s / deg | X, Y, Z (rate / incremental angle)",
        "status" / Int8ub * " |  | STATUS, TS1524 Table 5-23",
    ]
    for g in groups:
        if g == "reserved":
            fields.append("reserved" / Bytes(3) * " |  | reserved")
        elif g == "temperature":
            fields.append("temperature" / Array(3, Int16sb) * "2^-8 | degC | X, Y, Z")
        elif g == "counter":
            fields.append("counter" / Int8ub * "1 |  | 2000 Hz sample counter, wraps")
        elif g == "latency":
            fields.append("latency_us" / Int16ub * "1 | us | sampling to transmission / ExtTrig")
    fields.append("crc" / Int8ub * " |  | CRC-8 poly 0x07 init 0xFF over ident..last data byte")
    return Struct(*fields)


def _s24(b: bytes, i: int) -> int:
    v = (b[i] << 16) | (b[i + 1] << 8) | b[i + 2]
    return v - 0x1000000 if v & 0x800000 else v


# s24 BE at i: the i32 BE at i holds it in its top three bytes; >> 8 sign-extends it (needs one
# byte after the field, which every datagram has: STATUS follows each s24 group).
_I32BE = struct.Struct(">i").unpack_from
_T3 = struct.Struct(">3h").unpack_from


class Stim210Format:
    """:class:`~protocols.stream.FrameFormat` for one configured STIM210 datagram format.

    Parameters
    ----------
    fmt:
        Format letter of the ``d`` service command (``"s"``, ``"m"``, ...).
    crlf:
        True when the unit is configured for ``<CR><LF>`` termination.
    """

    def __init__(self, fmt: str = "m", crlf: bool = False) -> None:
        if fmt not in STIM210_FORMATS:
            raise ValueError(f"unknown STIM210 format {fmt!r}; expected one of {sorted(STIM210_FORMATS)}")
        self.fmt = fmt
        self.crlf = crlf
        self.ident, self.groups = STIM210_FORMATS[fmt]
        self.name = f"stim210-{fmt}"
        self.sync = bytes([self.ident])
        self.body_len = 1 + 9 + 1 + sum(_GROUP_SIZE[g] for g in self.groups)
        self.length = self.body_len + 1 + (2 if crlf else 0)
        self.spec = stim210_spec(fmt)
        # Offsets of the optional groups, for the fast parser.
        off = 11
        self._off: dict[str, int] = {}
        for g in self.groups:
            self._off[g] = off
            off += _GROUP_SIZE[g]
        # (counter, latency, temperature, reserved) offsets for the fast parser; 0 = absent
        self._opt = tuple(self._off.get(g, 0) for g in ("counter", "latency", "temperature", "reserved"))

    # FrameFormat protocol ------------------------------------------------------
    def frame_length(self, buf: bytearray, start: int) -> int:
        return self.length

    def check(self, frame: bytes) -> bool:
        n = self.body_len
        if crc8_stim(frame[:n]) != frame[n]:
            return False
        return not self.crlf or frame[n + 1 : n + 3] == b"\r\n"

    def parse(self, frame: bytes) -> StimDatagram:
        oc, ol, ot, orr = self._opt
        return StimDatagram(
            frame[0],
            (_I32BE(frame, 1)[0] >> 8, _I32BE(frame, 4)[0] >> 8, _I32BE(frame, 7)[0] >> 8),
            frame[10],
            frame[oc] if oc else None,
            ((frame[ol] << 8) | frame[ol + 1]) if ol else None,
            _T3(frame, ot) if ot else None,
            bytes(frame[orr : orr + 3]) if orr else None,
        )

    # Encoder -------------------------------------------------------------------
    def build(self, d: StimDatagram) -> bytes:
        """Encode a datagram of this format (CRC computed, CR LF appended if configured)."""
        out = bytearray([self.ident])
        for w in d.gyro:
            if not -0x800000 <= w <= 0x7FFFFF:
                raise ValueError(f"gyro word {w} outside s24")
            out += (w & 0xFFFFFF).to_bytes(3, "big")
        out.append(d.status & 0xFF)
        for g in self.groups:
            if g == "reserved":
                out += d.reserved if d.reserved is not None else b"\x00\x00\x00"
            elif g == "temperature":
                out += struct.pack(">3h", *(d.temperature or (0, 0, 0)))
            elif g == "counter":
                out.append((d.counter or 0) & 0xFF)
            elif g == "latency":
                out += struct.pack(">H", d.latency_us or 0)
        out.append(crc8_stim(out))
        if self.crlf:
            out += b"\r\n"
        return bytes(out)

    encode = build



# --------------------------------------------------------------------------------------------
# STIM300
# --------------------------------------------------------------------------------------------

#: ID -> (clusters present besides the gyro, wire length without CR LF, CRC dummy bytes, PPS or
#: AUX wording). Clusters: "acc", "incl", "temp", "aux" (PPS in r31, AUX ADC in older revisions).
#: r31 Table 5-21/5-22 plus the AUX-era IDs of the vortexntnu and rock drivers (protocols.md 1.4).
STIM300_DATAGRAMS: dict[int, tuple[tuple[str, ...], int, int, str]] = {
    0x90: ((), 18, 2, "r31"),
    0x91: (("acc",), 28, 0, "r31"),
    0x92: (("incl",), 28, 0, "r31"),
    0x93: (("acc", "incl"), 38, 2, "r31"),
    0x94: (("temp",), 25, 3, "r31"),
    0xA5: (("acc", "temp"), 42, 2, "r31"),
    0xA6: (("incl", "temp"), 42, 2, "r31"),
    0xA7: (("acc", "incl", "temp"), 59, 1, "r31"),
    0xF0: (("aux",), 22, 2, "r31 PPS"),
    0xF1: (("acc", "aux"), 32, 0, "r31 PPS"),
    0xF2: (("incl", "aux"), 32, 0, "r31 PPS"),
    0xF3: (("acc", "incl", "aux"), 42, 2, "r31 PPS"),
    0xF4: (("temp", "aux"), 29, 3, "r31 PPS"),
    0xF5: (("acc", "temp", "aux"), 46, 2, "r31 PPS"),
    0xF6: (("incl", "temp", "aux"), 46, 2, "r31 PPS"),
    0xF7: (("acc", "incl", "temp", "aux"), 63, 1, "r31 PPS"),
    0x97: (("acc", "incl", "temp"), 59, 1, "rev B (= 0xA7)"),
    0x98: (("aux",), 22, 2, "legacy AUX (= 0xF0)"),
    0x99: (("acc", "aux"), 32, 0, "legacy AUX (= 0xF1)"),
    0x9A: (("incl", "aux"), 32, 0, "legacy AUX (= 0xF2)"),
    0x9B: (("acc", "incl", "aux"), 42, 2, "legacy AUX (= 0xF3)"),
    0x9C: (("temp", "aux"), 29, 3, "legacy AUX (= 0xF4)"),
    0xAD: (("acc", "temp", "aux"), 46, 2, "legacy AUX (= 0xF5)"),
    0xAE: (("incl", "temp", "aux"), 46, 2, "legacy AUX (= 0xF6)"),
    0xAF: (("acc", "incl", "temp", "aux"), 63, 1, "legacy AUX (= 0xF7)"),
}


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class Stim300Datagram:
    """One decoded STIM300 normal-mode datagram (raw integer words, see module docstring).

    ``gyro``, ``accel``, ``incl`` are s24 words X, Y, Z; ``*_temp`` are s16 words in 2^-8 degC;
    ``aux`` is the s24 PPS word (r31) or AUX ADC word (older revisions). Every cluster has its
    own STATUS byte. Clusters absent from the configured datagram are ``None``.
    """

    ident: int
    gyro: tuple[int, int, int]
    gyro_status: int
    counter: int
    latency_us: int
    accel: tuple[int, int, int] | None = None
    accel_status: int | None = None
    incl: tuple[int, int, int] | None = None
    incl_status: int | None = None
    gyro_temp: tuple[int, int, int] | None = None
    gyro_temp_status: int | None = None
    accel_temp: tuple[int, int, int] | None = None
    accel_temp_status: int | None = None
    incl_temp: tuple[int, int, int] | None = None
    incl_temp_status: int | None = None
    aux: int | None = None
    aux_status: int | None = None


def _stim300_layout(ident: int) -> list[tuple[str, str]]:
    """Wire order of (field, kind) for one ID; kind is s24x3, s16x3, s24, u8 or u16."""
    groups = STIM300_DATAGRAMS[ident][0]
    acc, incl, temp, aux = ("acc" in groups), ("incl" in groups), ("temp" in groups), ("aux" in groups)
    out = [("gyro", "s24x3"), ("gyro_status", "u8")]
    if acc:
        out += [("accel", "s24x3"), ("accel_status", "u8")]
    if incl:
        out += [("incl", "s24x3"), ("incl_status", "u8")]
    if temp:
        out += [("gyro_temp", "s16x3"), ("gyro_temp_status", "u8")]
        if acc:
            out += [("accel_temp", "s16x3"), ("accel_temp_status", "u8")]
        if incl:
            out += [("incl_temp", "s16x3"), ("incl_temp_status", "u8")]
    if aux:
        out += [("aux", "s24"), ("aux_status", "u8")]
    out += [("counter", "u8"), ("latency_us", "u16")]
    return out


_KIND_SIZE = {"s24x3": 9, "s16x3": 6, "s24": 3, "u8": 1, "u16": 2}
_KIND_DOC = {
    "gyro": "2^-14 / 2^-21 | deg/s / deg | X, Y, Z (rate / incremental angle)",
    "accel": "2^-20, 2^-19, 2^-18, 2^-16 | g | X, Y, Z for the 5 / 10 / 30 / 80 g range",
    "incl": "2^-22 | g | X, Y, Z",
    "gyro_temp": "2^-8 | degC | X, Y, Z",
    "accel_temp": "2^-8 | degC | X, Y, Z",
    "incl_temp": "2^-8 | degC | X, Y, Z",
    "aux": "1 | us | PPS: time since the PPS edge (r31); AUX ADC word in older revisions",
    "counter": "1 |  | 2000 Hz sample counter, wraps; steps 2000/rate per datagram",
    "latency_us": "1 | us | sampling to transmission start (or ExtTrig)",
}


def stim300_spec(ident: int) -> Struct:
    """The declarative ``construct`` layout of one STIM300 datagram ID (CRC included, no CR LF)."""
    if ident not in STIM300_DATAGRAMS:
        raise ValueError(f"unknown STIM300 datagram ID 0x{ident:02X}")
    fields = ["ident" / Const(ident, Int8ub) * f" |  | datagram ID 0x{ident:02X}"]
    kinds = {"s24x3": Array(3, Int24sb), "s16x3": Array(3, Int16sb), "s24": Int24sb, "u8": Int8ub, "u16": Int16ub}
    for name, kind in _stim300_layout(ident):
        doc = _KIND_DOC.get(name, " |  | STATUS, TS1524 Table 5-23")
        fields.append(name / kinds[kind] * doc)
    dummy = STIM300_DATAGRAMS[ident][2]
    fields.append("crc" / Int32ub * f" |  | CRC-32/MPEG-2 over ident..latency + {dummy} dummy 0x00 byte(s)")
    return Struct(*fields)


class Stim300Format:
    """:class:`~protocols.stream.FrameFormat` for one configured STIM300 datagram ID.

    Parameters
    ----------
    ident:
        The datagram ID the unit is configured to send (a key of :data:`STIM300_DATAGRAMS`,
        e.g. 0x93 for rate + acceleration + inclination).
    crlf:
        True when the unit is configured for ``<CR><LF>`` termination.
    """

    def __init__(self, ident: int = 0x93, crlf: bool = False) -> None:
        if ident not in STIM300_DATAGRAMS:
            raise ValueError(f"unknown STIM300 datagram ID 0x{ident:02X}; expected one of "
                             + ", ".join(f"0x{k:02X}" for k in sorted(STIM300_DATAGRAMS)))
        groups, length, dummy, _ = STIM300_DATAGRAMS[ident]
        self.ident = ident
        self.groups = groups
        self.crlf = crlf
        self.name = f"stim300-{ident:02x}"
        self.sync = bytes([ident])
        self.layout = _stim300_layout(ident)
        self.body_len = 1 + sum(_KIND_SIZE[k] for _, k in self.layout)
        if self.body_len + 4 != length or (self.body_len + dummy) % 4:
            raise AssertionError(f"STIM300 table inconsistent for 0x{ident:02X}")  # pragma: no cover
        self.wire_len = length  # without CR LF
        self.length = length + (2 if crlf else 0)
        self.dummy = bytes(dummy)
        self.spec = stim300_spec(ident)
        off = 1
        self._offsets: list[tuple[str, str, int]] = []
        for name, kind in self.layout:
            self._offsets.append((name, kind, off))
            off += _KIND_SIZE[kind]

    # FrameFormat protocol ------------------------------------------------------
    def frame_length(self, buf: bytearray, start: int) -> int:
        return self.length

    def check(self, frame: bytes) -> bool:
        n = self.body_len
        if crc32_mpeg2(frame[:n] + self.dummy) != int.from_bytes(frame[n : n + 4], "big"):
            return False
        return not self.crlf or frame[n + 4 : n + 6] == b"\r\n"

    def parse(self, frame: bytes) -> Stim300Datagram:
        kw: dict[str, object] = {}
        for name, kind, off in self._offsets:
            if kind == "s24x3":
                kw[name] = (_I32BE(frame, off)[0] >> 8, _I32BE(frame, off + 3)[0] >> 8, _I32BE(frame, off + 6)[0] >> 8)
            elif kind == "u8":
                kw[name] = frame[off]
            elif kind == "s16x3":
                kw[name] = struct.unpack_from(">3h", frame, off)
            elif kind == "u16":
                kw[name] = (frame[off] << 8) | frame[off + 1]
            else:  # s24
                kw[name] = _s24(frame, off)
        return Stim300Datagram(ident=frame[0], **kw)  # type: ignore[arg-type]

    # Encoder -------------------------------------------------------------------
    def build(self, d: Stim300Datagram) -> bytes:
        """Encode a datagram of this ID (CRC with the dummy bytes, CR LF appended if configured).

        Raises ``ValueError`` when a cluster of this ID is missing from ``d`` or a word is out of range.
        """
        out = bytearray([self.ident])
        for name, kind in self.layout:
            v = getattr(d, name)
            if v is None:
                raise ValueError(f"STIM300 0x{self.ident:02X} needs {name}")
            if kind == "s24x3":
                for w in v:
                    out += _p24be(w)
            elif kind == "u8":
                out.append(v & 0xFF)
            elif kind == "s16x3":
                out += struct.pack(">3h", *v)
            elif kind == "u16":
                out += struct.pack(">H", v)
            else:
                out += _p24be(v)
        out += crc32_mpeg2(bytes(out) + self.dummy).to_bytes(4, "big")
        if self.crlf:
            out += b"\r\n"
        return bytes(out)

    encode = build


def _p24be(v: int) -> bytes:
    if not -0x800000 <= v <= 0x7FFFFF:
        raise ValueError(f"value {v} outside s24")
    return (v & 0xFFFFFF).to_bytes(3, "big")
