"""Sensonor STIM210 normal-mode datagrams (RS422), and what the STIM210 and STIM300 share.

STIM210 (gyro only)
-------------------

Source: ``docs/reference/wire-formats.md`` section 1.8 (layouts from the ut-issl/c2a-aobc
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
the ID: 0x90 means a different frame on a STIM300. Each format is declared once, by
:func:`stim210_spec`; its ``struct`` codec is derived from that spec (:mod:`protocols.codec`).

STIM300 (gyro, accelerometers, inclinometers): :mod:`protocols.stim300`, whose names this module
re-exports. Both share the scale factors, the STATUS bits (:class:`StimStatus`) and the counter below.

Utility Mode lines (``$cmd,...,crc`` / ``#resp,...,crc``) carry a CRC-8 written in decimal ASCII
over everything from ``$``/``#`` through the last comma: :func:`utility_mode_crc`.
"""

from __future__ import annotations

import enum
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from dataclasses import fields as dataclass_fields
from operator import itemgetter
from typing import Any

from construct import Array, Bytes, Const, Int8ub, Int16sb, Int16ub, Int24sb, Struct

from ._fastinit import fast_frozen_init
from .codec import StructCodec, subspec
from .crc import crc8_stim, crc8_stim_fast, crc8_stim_rows
from .stim300 import (
    INCL_DV_LSB_MPS,
    INCL_LSB_G,
    PPS_LSB_US,
    STIM300_ACCEL_DV_LSB_MPS,
    STIM300_ACCEL_LSB_G,
    STIM300_DATAGRAMS,
    Stim300Datagram,
    Stim300Format,
    stim300_spec,
)

__all__ = [
    "GYRO_ANGLE_LSB_DEG",
    "GYRO_DEVICES",
    "GYRO_RATE_LSB_DPS",
    "INCL_DV_LSB_MPS",
    "INCL_LSB_G",
    "PPS_LSB_US",
    "STATUS_SAMPLE_INVALID",
    "STIM210_FORMATS",
    "STIM300_ACCEL_DV_LSB_MPS",
    "STIM300_ACCEL_LSB_G",
    "STIM300_DATAGRAMS",
    "STIM_COUNTER_HZ",
    "TEMP_LSB_DEGC",
    "Stim210Format",
    "Stim300Datagram",
    "Stim300Format",
    "StimDatagram",
    "StimStatus",
    "counter_step",
    "gyro_port_format",
    "overload_status",
    "stim210_spec",
    "stim300_spec",
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


#: STATUS bits that make a datagram's measurement not a valid sample (TS1524 r31 Table 5-23,
#: docs/reference/wire-formats.md 1.6): an overload (the output is clipped at the range), an error in a
#: measurement channel, the start-up stabilisation ("data not valid") and a system integrity error. Bit 5,
#: outside operating conditions, leaves the sample valid (the unit still measures, outside its specified
#: temperature or supply); the channel bits 0-2 only name the channel of bits 3 and 4.
STATUS_SAMPLE_INVALID = (StimStatus.OVERLOAD | StimStatus.CHANNEL_ERROR | StimStatus.STARTUP
                         | StimStatus.SYSTEM_INTEGRITY_ERROR)


def overload_status(x: bool, y: bool, z: bool) -> int:
    """The STATUS byte of a sample whose channels ``x``, ``y``, ``z`` exceed the range (0 when none does):
    :attr:`StimStatus.OVERLOAD` with the channel bits 0-2 naming them (TS1524 r31 Table 5-23)."""
    bits = (StimStatus.X_CHANNEL if x else 0) | (StimStatus.Y_CHANNEL if y else 0) | (StimStatus.Z_CHANNEL if z else 0)
    return int(StimStatus.OVERLOAD | bits) if bits else 0


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


def _stim210_codecs(fmt: str) -> tuple[StructCodec, Callable[..., Any], Callable[..., bytes]]:
    """The derived codec of one format, its decoder and its body encoder (ident .. last data byte) from the
    datagram's fields as arguments."""
    spec = stim210_spec(fmt)
    codec = StructCodec(spec, f"STIM210_{fmt}")
    last = [sc.name for sc in spec.subcons][-2]
    body = StructCodec(subspec(spec, "ident", last), f"STIM210_{fmt}_BODY")
    # Absent optional groups encode as zeros; counters and STATUS wrap to their byte.
    absent_as_zero = {
        "counter": lambda v: (v or 0) & 0xFF, "latency_us": lambda v: v or 0,
        "temperature": lambda v: v or (0, 0, 0), "reserved": lambda v: b"\x00\x00\x00" if v is None else v,
    }
    # from the datagram's fields as arguments (those the format carries, in StimDatagram's order): a sender that
    # has the values needs no datagram object (Stim210Format.build_values)
    encode = body.encoder(StimDatagram, convert={
        "status": (0xFF).__and__, **{k: f for k, f in absent_as_zero.items() if k in body.names}}, from_args=True)
    return codec, codec.decoder(StimDatagram, ignore=("crc",)), encode


#: format letter -> (codec, decoder, body encoder), built once at import
_STIM210_CODECS = {fmt: _stim210_codecs(fmt) for fmt in STIM210_FORMATS}
#: the fields of :class:`StimDatagram`, in order (the parameters of :meth:`Stim210Format.build_values` after ident)
_BUILD_FIELDS = tuple(f.name for f in dataclass_fields(StimDatagram))


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
        codec, self._decode, self._encode_body = _STIM210_CODECS[fmt]
        # the fields of build_values' arguments that this format carries: the body encoder's parameters (in
        # StimDatagram's order; ident is the format's constant)
        args = _BUILD_FIELDS[1:]
        self._pick = itemgetter(*(i for i, n in enumerate(args) if n in codec.names))
        self.spec = codec.spec
        self.body_len = codec.size - 1  # ident .. last data byte: what the CRC-8 covers
        self.length = codec.size + (2 if crlf else 0)

    # FrameFormat protocol ------------------------------------------------------
    def frame_length(self, buf: bytes | bytearray, start: int) -> int:
        return self.length

    def check(self, frame: bytes) -> bool:
        n = self.body_len
        if crc8_stim_fast(frame[:n]) != frame[n]:
            return False
        return not self.crlf or frame[n + 1 : n + 3] == b"\r\n"

    def parse(self, frame: bytes) -> StimDatagram:
        d: StimDatagram = self._decode(frame, 0, self.ident)
        return d

    # Encoder -------------------------------------------------------------------
    def build(self, d: StimDatagram) -> bytes:
        """Encode a datagram of this format (CRC computed, CR LF appended if configured).

        Absent optional fields encode as zeros; a gyro word outside s24 raises ``ValueError``.
        """
        return self.build_values(d.gyro, d.status, d.counter, d.latency_us, d.temperature, d.reserved)

    def build_values(self, gyro: Sequence[int], status: int, counter: int | None = None,
                     latency_us: int | None = None, temperature: Sequence[int] | None = None,
                     reserved: bytes | None = None) -> bytes:
        """:meth:`build` of ``StimDatagram(self.ident, gyro, status, ...)`` from the fields, without the object
        (the gyro model's sender, once per datagram); fields this format does not carry are ignored."""
        body: bytes = self._encode_body(*self._pick((gyro, status, counter, latency_us, temperature, reserved)))
        return body + bytes((crc8_stim_fast(body),)) + (b"\r\n" if self.crlf else b"")

    def build_window(self, gyro: Sequence[Sequence[int]], status: Sequence[int],
                     counter: Sequence[int | None] | None = None, latency_us: Sequence[int | None] | None = None,
                     temperature: Sequence[Sequence[int] | None] | None = None,
                     reserved: Sequence[bytes | None] | None = None) -> bytes:
        """The datagrams of a window of samples, back to back (``len(gyro) * self.length`` bytes): row ``i`` is
        the datagram of ``(gyro[i], status[i], counter[i], latency_us[i], temperature[i], reserved[i])``, i.e.
        :meth:`build_values` of that row (a window of one is exactly that call).

        Each argument is a column (one entry per sample; ``None``: the field is absent, encoded as zeros as
        :meth:`build` does). The bodies are packed by the same derived encoder; their CRC-8s are computed a
        column at a time over the whole window (:func:`~protocols.crc.crc8_stim_rows`) and the CRC column (and
        the CR LF columns) are written with extended slices (docs/decisions/performance.md D-10.E21).
        A gyro word outside s24 raises ``ValueError``."""
        n = len(gyro)
        if n == 1:  # a window of one: the row's datagram (its CRC-8 remembered, crc8_stim_fast)
            return self.build_values(gyro[0], status[0], None if counter is None else counter[0],
                                     None if latency_us is None else latency_us[0],
                                     None if temperature is None else temperature[0],
                                     None if reserved is None else reserved[0])
        none = (None,) * n
        enc, pick = self._encode_body, self._pick
        bodies = b"".join([enc(*pick(r)) for r in zip(
            gyro, status, none if counter is None else counter, none if latency_us is None else latency_us,
            none if temperature is None else temperature, none if reserved is None else reserved, strict=True)])
        nb = self.body_len
        size = self.length
        out = bytearray(n * size)
        for i in range(nb):
            out[i::size] = bodies[i::nb]
        out[nb::size] = crc8_stim_rows(bodies, nb, nb)
        if self.crlf:
            out[nb + 1::size] = b"\r" * n
            out[nb + 2::size] = b"\n" * n
        return bytes(out)

    encode = build


#: IMUs that can sit on the gyro port: the STIM210 (datagram format letter) or the STIM300 (datagram ID)
GYRO_DEVICES = ("stim210", "stim300")


def gyro_port_format(device: str = "stim210", fmt: str = "m", ident: int = 0x93) -> Stim210Format | Stim300Format:
    """The datagram format on the gyro port: a STIM210 of format letter ``fmt`` or a STIM300 sending ID ``ident``."""
    if device == "stim300":
        return Stim300Format(ident)
    if device == "stim210":
        return Stim210Format(fmt)
    raise ValueError(f"unknown gyro-port device {device!r}; expected one of {GYRO_DEVICES}")
