"""Sensonor STIM210 normal-mode datagrams (gyro, RS422).

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
"""

from __future__ import annotations

import struct
from dataclasses import dataclass

from construct import Array, Bytes, Const, Int8ub, Int16sb, Int16ub, Int24sb, Struct

from .crc import crc8_stim

__all__ = [
    "STIM210_FORMATS",
    "GYRO_RATE_LSB_DPS",
    "GYRO_ANGLE_LSB_DEG",
    "TEMP_LSB_DEGC",
    "STIM_COUNTER_HZ",
    "StimDatagram",
    "Stim210Format",
    "stim210_spec",
]

#: deg/s per LSB, angular-rate output (TS1524 r31 7.5.2.2; same on STIM210).
GYRO_RATE_LSB_DPS = 2.0**-14
#: deg per LSB, incremental-angle output.
GYRO_ANGLE_LSB_DEG = 2.0**-21
#: degC per LSB of the s16 temperature words.
TEMP_LSB_DEGC = 2.0**-8
#: Internal sample rate counted by the datagram counter, Hz.
STIM_COUNTER_HZ = 2000

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
        "ident" / Const(ident, Int8ub),
        "gyro" / Array(3, Int24sb) * "X, Y, Z, 2^-14 deg/s or 2^-21 deg per LSB",
        "status" / Int8ub * "STATUS, TS1524 Table 5-23",
    ]
    for g in groups:
        if g == "reserved":
            fields.append("reserved" / Bytes(3))
        elif g == "temperature":
            fields.append("temperature" / Array(3, Int16sb) * "2^-8 degC per LSB")
        elif g == "counter":
            fields.append("counter" / Int8ub * "2000 Hz sample counter, wraps")
        elif g == "latency":
            fields.append("latency_us" / Int16ub * "us")
    fields.append("crc" / Int8ub * "CRC-8 poly 0x07 init 0xFF over ident..last data byte")
    return Struct(*fields)


def _s24(b: bytes, i: int) -> int:
    v = (b[i] << 16) | (b[i + 1] << 8) | b[i + 2]
    return v - 0x1000000 if v & 0x800000 else v


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

    # FrameFormat protocol ------------------------------------------------------
    def frame_length(self, buf: bytearray, start: int) -> int:
        return self.length

    def check(self, frame: bytes) -> bool:
        n = self.body_len
        if crc8_stim(frame[:n]) != frame[n]:
            return False
        return not self.crlf or frame[n + 1 : n + 3] == b"\r\n"

    def parse(self, frame: bytes) -> StimDatagram:
        off = self._off
        temp = None
        if "temperature" in off:
            temp = struct.unpack_from(">3h", frame, off["temperature"])
        return StimDatagram(
            ident=frame[0],
            gyro=(_s24(frame, 1), _s24(frame, 4), _s24(frame, 7)),
            status=frame[10],
            counter=frame[off["counter"]] if "counter" in off else None,
            latency_us=struct.unpack_from(">H", frame, off["latency"])[0] if "latency" in off else None,
            temperature=temp,
            reserved=bytes(frame[off["reserved"] : off["reserved"] + 3]) if "reserved" in off else None,
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

