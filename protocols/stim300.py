"""Sensonor STIM300 normal-mode datagrams (gyro, accelerometers, inclinometers; RS422).

Source: TS1524 rev. 31 (Tables 5-20 .. 5-23, section 7.5), as summarised in
``docs/reference/wire-formats.md`` sections 1.2-1.7. Full content in wire order (reduced
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

Each datagram ID is declared once, by :func:`stim300_spec`; its ``struct`` codec is derived from that spec
(:mod:`protocols.codec`). The gyro scale factors, :class:`~protocols.stim.StimStatus` and the counter are
those of :mod:`protocols.stim`, which re-exports this module's names.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from construct import Array, Const, Int8ub, Int16sb, Int16ub, Int24sb, Int32ub, Struct

from ._fastinit import fast_frozen_init
from .codec import StructCodec, subspec
from .crc import crc32_mpeg2_fast

__all__ = [
    "INCL_DV_LSB_MPS",
    "INCL_LSB_G",
    "PPS_LSB_US",
    "STIM300_ACCEL_DV_LSB_MPS",
    "STIM300_ACCEL_LSB_G",
    "STIM300_DATAGRAMS",
    "Stim300Datagram",
    "Stim300Format",
    "stim300_spec",
]

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

#: ID -> (clusters present besides the gyro, wire length without CR LF, CRC dummy bytes, PPS or
#: AUX wording). Clusters: "acc", "incl", "temp", "aux" (PPS in r31, AUX ADC in older revisions).
#: r31 Table 5-21/5-22 plus the AUX-era IDs of the vortexntnu and rock drivers
#: (docs/reference/wire-formats.md section 1.4).
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


def _stim300_codecs(ident: int) -> tuple[StructCodec, Any, StructCodec, Any]:
    """The derived codec of one ID, its decoder, its body codec (ident .. latency) and the body encoder."""
    codec = StructCodec(stim300_spec(ident), f"STIM300_{ident:02X}")
    body = StructCodec(subspec(codec.spec, "ident", "latency_us"), f"STIM300_{ident:02X}_BODY")
    return codec, codec.decoder(Stim300Datagram, ignore=("crc",)), body, body.encoder(Stim300Datagram)


#: ID -> (codec, decoder, body codec, body encoder), built once at import
_STIM300_CODECS = {ident: _stim300_codecs(ident) for ident in STIM300_DATAGRAMS}


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
        self._codec, self._decode, self._body, self._encode_body = _STIM300_CODECS[ident]
        self.spec = self._codec.spec
        self.body_len = self._body.size  # ident .. latency: what the CRC covers (with the dummy bytes)
        if self.body_len + 4 != length or (self.body_len + dummy) % 4:
            raise AssertionError(f"STIM300 table inconsistent for 0x{ident:02X}")  # pragma: no cover
        self.wire_len = length  # without CR LF
        self.length = length + (2 if crlf else 0)
        self.dummy = bytes(dummy)

    # FrameFormat protocol ------------------------------------------------------
    def frame_length(self, buf: bytes | bytearray, start: int) -> int:
        return self.length

    def check(self, frame: bytes) -> bool:
        n = self.body_len
        if crc32_mpeg2_fast(frame[:n] + self.dummy) != int.from_bytes(frame[n : n + 4], "big"):
            return False
        return not self.crlf or frame[n + 4 : n + 6] == b"\r\n"

    def parse(self, frame: bytes) -> Stim300Datagram:
        d: Stim300Datagram = self._decode(frame, 0, self.ident)
        return d

    # Encoder -------------------------------------------------------------------
    def build(self, d: Stim300Datagram) -> bytes:
        """Encode a datagram of this ID (CRC with the dummy bytes, CR LF appended if configured).

        Raises ``ValueError`` when a cluster of this ID is missing from ``d`` or a word is out of range.
        """
        for name in self._body.names:
            if getattr(d, name) is None:
                raise ValueError(f"STIM300 0x{self.ident:02X} needs {name}")
        body: bytes = self._encode_body(d)
        out = body + crc32_mpeg2_fast(body + self.dummy).to_bytes(4, "big")
        return out + b"\r\n" if self.crlf else out

    encode = build
