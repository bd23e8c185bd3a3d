"""Polarization sensor (PSNS) frames on the RS232 PSNS port (FPGA -> DSP UART2).

Framing (little-endian), shared by the three messages::

    off  size  field
    0    2     sync 0xEB 0x90
    2    1     msg_id
    3    2     payload length N, u16
    5    N     payload
    5+N  2     CRC-16/CCITT-FALSE over bytes 2 .. 4+N (msg_id, length, payload)

Every payload starts with the same 13-byte header::

    0   u16  seq          frame counter, wraps
    2   u32  exposure_us  exposure time, us
    6   u32  latency_us   from the middle of the exposure to the start bit of this frame's first byte, us
    10  u8   status       :class:`PsnsStatus` bits
    11  u16  count        N points (0x10), l units (0x11), points used (0x12)

``0x10`` POLARIZATION_OBS: then ``count`` points of 10 bytes each::

    u16 x_px, u16 y_px    pixel of the observation point (full-resolution, 1-based: column, row)
    i16 aop_cdeg          AOP in 0.01 deg, (-9000, 9000]; the angle of the E-vector's projection on
                          the image plane, measured from the image +y axis towards +x (base paper Eq. 5)
    u16 dop               DOP in 1/65535
    u16 intensity         S0 in DN (12-bit camera: 0..8190 after the (I0+I45+I90+I135)/2 sum)

``0x11`` COMPASS (multi-unit polarization compass): then ``count`` units of 5 bytes::

    u8 unit, i16 aop_cdeg, u16 dop        (AOP in each unit's own sensor frame, same convention)

``0x12`` SOLAR_VECTOR (on-sensor solve): then::

    3 x f32 s_x, s_y, s_z   unit solar vector (sign ambiguous: +-S) in the sensor frame
    f32 quality             lambda_min / lambda_mid of K (smaller is better), 1.0 if invalid

Camera frame (docs/architecture.md, "Conventions"): origin at the imager centre, z along the optical axis, x along
image columns, y along rows; pixel (x, y) looks along ``(Dx (x - (nx+1)/2), Dy (y - (ny+1)/2), f)``.

Each layout is declared once, by the ``construct`` specs below; the ``struct`` codecs are derived from them
(:mod:`protocols.codec`) and fill the dataclasses by field name.
"""

from __future__ import annotations

import enum
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from construct import Array, Bytes, Const, Float32l, Int8ul, Int16sl, Int16ul, Int32ul, Struct, this

from ._fastinit import fast_frozen_init
from .codec import StructCodec, subspec
from .crc import crc16_ccitt
from .stream import BAD_LENGTH, NEED_MORE

__all__ = [
    "COMPASS_SPEC",
    "MSG_COMPASS",
    "MSG_POLARIZATION_OBS",
    "MSG_SOLAR_VECTOR",
    "POINT_FIELDS",
    "POINT_STRUCT_FORMAT",
    "POLARIZATION_OBS_SPEC",
    "PSNS_FRAME_SPEC",
    "PSNS_MAX_PAYLOAD",
    "PSNS_SYNC",
    "SOLAR_VECTOR_SPEC",
    "CompassFrame",
    "CompassUnit",
    "PolarizationObs",
    "PolarizationObsPacked",
    "PolarizationPoint",
    "PsnsFormat",
    "PsnsHeader",
    "PsnsStatus",
    "SolarVectorFrame",
    "encode_compass",
    "encode_polarization_obs",
    "encode_polarization_obs_columns",
    "encode_psns",
    "encode_solar_vector",
    "frame_bytes_obs",
    "max_points",
]

PSNS_SYNC = b"\xeb\x90"
MSG_POLARIZATION_OBS = 0x10
MSG_COMPASS = 0x11
MSG_SOLAR_VECTOR = 0x12
PSNS_MAX_PAYLOAD = 65535
FRAME_OVERHEAD = 7  # sync 2 + id 1 + len 2 + crc 2
HEADER_LEN = 13
POINT_LEN = 10
UNIT_LEN = 5
SOLAR_VECTOR_PAYLOAD_LEN = HEADER_LEN + 16


class PsnsStatus(enum.IntFlag):
    """``status`` bits common to every PSNS frame."""

    VALID = 0x01  #: the measurement is usable (sun above the horizon, enough points)
    SUN_BELOW_HORIZON = 0x02
    SATURATED = 0x04  #: some pixels saturated
    LOW_DOP = 0x08  #: too few points above the DOP threshold
    OCCLUDED = 0x10  #: cloud / occlusion detected


# Field docs are "scale | unit | meaning" (read by protocols.icd for docs/icd.md).
PSNS_FRAME_SPEC = Struct(
    "sync" / Const(PSNS_SYNC) * " |  | 0xEB 0x90",
    "msg_id" / Int8ul * " |  | 0x10 POLARIZATION_OBS, 0x11 COMPASS, 0x12 SOLAR_VECTOR",
    "length" / Int16ul * "1 | bytes | payload length N (must agree with count)",
    "payload" / Bytes(this.length) * " |  | N bytes",
    "crc" / Int16ul * " |  | CRC-16/CCITT-FALSE over msg_id, length, payload",
)
_HEADER_FIELDS = (
    "seq" / Int16ul * "1 |  | frame counter, wraps",
    "exposure_us" / Int32ul * "1 | us | exposure time",
    "latency_us" / Int32ul * "1 | us | middle of the exposure to the start bit of this frame's first byte",
    "status" / Int8ul * " |  | PsnsStatus bits",
    "count" / Int16ul * "1 |  | N points (0x10), l units (0x11), points used (0x12)",
)
POINT_SPEC = Struct(
    "x_px" / Int16ul * "1 | px | column, 1-based, full resolution",
    "y_px" / Int16ul * "1 | px | row, 1-based",
    "aop_cdeg" / Int16sl * "0.01 | deg | AOP from image +y towards +x, (-90, 90] (Eq. 5)",
    "dop" / Int16ul * "1/65535 |  | degree of polarization",
    "intensity" / Int16ul * "1 | DN | S0 = (I0+I45+I90+I135)/2",
)
UNIT_SPEC = Struct(
    "unit" / Int8ul * " |  | compass unit index",
    "aop_cdeg" / Int16sl * "0.01 | deg | AOP in the unit's frame, from +y towards +x",
    "dop" / Int16ul * "1/65535 |  | degree of polarization",
)
POLARIZATION_OBS_SPEC = Struct(*_HEADER_FIELDS, "points" / Array(this.count, POINT_SPEC) * " |  | count x 10 bytes")
COMPASS_SPEC = Struct(*_HEADER_FIELDS, "units" / Array(this.count, UNIT_SPEC) * " |  | count x 5 bytes")
SOLAR_VECTOR_SPEC = Struct(
    *_HEADER_FIELDS,
    "s" / Array(3, Float32l) * "1 |  | unit solar vector x, y, z in the sensor frame (sign ambiguous)",
    "quality" / Float32l * "1 |  | lambda_min / lambda_mid of K (smaller is better), 1.0 if invalid",
)


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class PsnsHeader:
    seq: int
    exposure_us: int
    latency_us: int
    status: int
    count: int


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class PolarizationPoint:
    """One observation point: pixel (1-based column, row), AOP (0.01 deg), DOP (1/65535), S0 (DN)."""

    x_px: int
    y_px: int
    aop_cdeg: int
    dop: int
    intensity: int


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class PolarizationObs:
    header: PsnsHeader
    points: tuple[PolarizationPoint, ...]

    @property
    def n_points(self) -> int:
        return len(self.points)

    @property
    def point_bytes(self) -> bytes:
        """The points as on the wire (``n_points`` records of :data:`POINT_SPEC`, as
        :class:`PolarizationObsPacked` holds them)."""
        return _encode_points(self.points)


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class PolarizationObsPacked:
    """A POLARIZATION_OBS frame as ``PsnsFormat(packed_points=True)`` decodes it: the points kept as their wire bytes
    (``point_bytes``: records of :data:`POINT_SPEC` back to back, layout :data:`POINT_STRUCT_FORMAT`) instead of a
    :class:`PolarizationPoint` object each, for a receiver that maps them onto an array (the firmware: 225 points
    per frame at 5 Hz). ``points`` gives the objects, the frame's :class:`PolarizationObs` content."""

    header: PsnsHeader
    point_bytes: bytes

    @property
    def n_points(self) -> int:
        return len(self.point_bytes) // POINT_LEN

    @property
    def points(self) -> tuple[PolarizationPoint, ...]:
        """The points as :class:`PolarizationPoint` objects."""
        pts: tuple[PolarizationPoint, ...] = _decode_points(self.point_bytes)
        return pts


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class CompassUnit:
    unit: int
    aop_cdeg: int
    dop: int


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class CompassFrame:
    header: PsnsHeader
    units: tuple[CompassUnit, ...]


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class SolarVectorFrame:
    header: PsnsHeader
    s: tuple[float, float, float]
    quality: float


_HEAD = StructCodec(subspec(PSNS_FRAME_SPEC, "msg_id", "length"), "PSNS_HEADER")
_CRC = StructCodec(subspec(PSNS_FRAME_SPEC, "crc", "crc"), "PSNS_CRC")
_HDR = StructCodec(Struct(*_HEADER_FIELDS), "PSNS_PAYLOAD_HEADER")
_PT = StructCodec(POINT_SPEC, "PSNS_POINT")
_UNIT = StructCodec(UNIT_SPEC, "PSNS_UNIT")
_SV = StructCodec(subspec(SOLAR_VECTOR_SPEC, "s", "quality"), "PSNS_SOLAR_VECTOR")
if (_HDR.size, _PT.size, _UNIT.size, HEADER_LEN + _SV.size) != (HEADER_LEN, POINT_LEN, UNIT_LEN,
                                                              SOLAR_VECTOR_PAYLOAD_LEN):  # pragma: no cover
    raise AssertionError("PSNS lengths disagree with the specs")
_decode_header = _HDR.decoder(PsnsHeader)
_decode_points = _PT.decoder(PolarizationPoint, many=True)
#: the ``struct`` format of one point record and its fields in order, derived from :data:`POINT_SPEC` (a receiver
#: that maps ``PolarizationObsPacked.point_bytes`` onto an array)
POINT_STRUCT_FORMAT: str = _PT.struct.format
POINT_FIELDS: tuple[str, ...] = _PT.names
_decode_units = _UNIT.decoder(CompassUnit, many=True)
_decode_solar_vector = _SV.decoder(SolarVectorFrame)
_encode_points = _PT.encoder(PolarizationPoint, many=True)
_encode_point_columns = _PT.columns_packer(PolarizationPoint)
_encode_units = _UNIT.encoder(CompassUnit, many=True)
_pack_header = _HDR.packer
_pack_solar_vector = _SV.packer


def _frame(msg_id: int, payload: bytes) -> bytes:
    if len(payload) > PSNS_MAX_PAYLOAD:
        raise ValueError(f"PSNS payload of {len(payload)} bytes exceeds {PSNS_MAX_PAYLOAD}")
    body = _HEAD.packer(msg_id=msg_id, length=len(payload)) + payload
    return PSNS_SYNC + body + _CRC.packer(crc=crc16_ccitt(body))


def _hdr(h: PsnsHeader, count: int) -> bytes:
    return _pack_header(seq=h.seq & 0xFFFF, exposure_us=h.exposure_us & 0xFFFFFFFF,
                        latency_us=h.latency_us & 0xFFFFFFFF, status=h.status & 0xFF, count=count)


def encode_polarization_obs(h: PsnsHeader, points: tuple[PolarizationPoint, ...] | list[PolarizationPoint]) -> bytes:
    """Whole POLARIZATION_OBS frame (``h.count`` is replaced by ``len(points)``)."""
    return _frame(MSG_POLARIZATION_OBS, _hdr(h, len(points)) + _encode_points(points))


def encode_polarization_obs_columns(h: PsnsHeader, x_px: Sequence[int], y_px: Sequence[int], aop_cdeg: Sequence[int],
                                    dop: Sequence[int], intensity: Sequence[int]) -> bytes:
    """:func:`encode_polarization_obs` of the points ``PolarizationPoint(x_px[i], y_px[i], ...)`` (Python ints),
    the same bytes, from the columns (a camera's arrays as lists) without building the point objects."""
    return _frame(MSG_POLARIZATION_OBS, _hdr(h, len(x_px)) + _encode_point_columns(x_px, y_px, aop_cdeg, dop,
                                                                                   intensity))


def encode_compass(h: PsnsHeader, units: tuple[CompassUnit, ...] | list[CompassUnit]) -> bytes:
    """Whole COMPASS frame (``h.count`` is replaced by ``len(units)``)."""
    return _frame(MSG_COMPASS, _hdr(h, len(units)) + _encode_units(units))


def encode_solar_vector(h: PsnsHeader, s: tuple[float, float, float], quality: float) -> bytes:
    """Whole SOLAR_VECTOR frame."""
    return _frame(MSG_SOLAR_VECTOR, _hdr(h, h.count) + _pack_solar_vector(s=s, quality=quality))


def encode_psns(obj: PolarizationObs | PolarizationObsPacked | CompassFrame | SolarVectorFrame) -> bytes:
    """Encode any object :class:`PsnsFormat` decodes (the inverse of its ``parse``)."""
    if isinstance(obj, PolarizationObs):
        return encode_polarization_obs(obj.header, obj.points)
    if isinstance(obj, PolarizationObsPacked):
        return _frame(MSG_POLARIZATION_OBS, _hdr(obj.header, obj.n_points) + obj.point_bytes)
    if isinstance(obj, CompassFrame):
        return encode_compass(obj.header, obj.units)
    return encode_solar_vector(obj.header, obj.s, obj.quality)


def frame_bytes_obs(n_points: int) -> int:
    """Wire bytes of a POLARIZATION_OBS frame with ``n_points`` points."""
    return FRAME_OVERHEAD + HEADER_LEN + POINT_LEN * n_points


def max_points(baud: int, rate_hz: float, bits_per_byte: int = 10) -> int:
    """Largest POLARIZATION_OBS point count that fits a line of ``baud`` at ``rate_hz`` frames/s.

    ``bits_per_byte`` is 10 for 8N1 (start + 8 data + stop). Example: 115200 baud at 5 Hz
    gives 2304 bytes per frame period, so (2304 - 7 - 13) // 10 = 228 points.
    """
    budget = int(baud / bits_per_byte / rate_hz)
    return max(0, (budget - FRAME_OVERHEAD - HEADER_LEN) // POINT_LEN)


class PsnsFormat:
    """:class:`~protocols.stream.FrameFormat` of PSNS frames (all three messages).

    ``packed_points``: POLARIZATION_OBS parses to :class:`PolarizationObsPacked` (the points' bytes as they came)
    instead of :class:`PolarizationObs` (each point an object); the same frames, checked the same way.
    """

    name = "psns"
    sync = PSNS_SYNC

    def __init__(self, packed_points: bool = False) -> None:
        self.packed_points = packed_points

    @staticmethod
    def encode(obj: Any) -> bytes:
        """Encode a decoded object back to its frame (:func:`encode_psns`)."""
        return encode_psns(obj)

    def frame_length(self, buf: bytes | bytearray, start: int) -> int:
        # The payload length must agree with the header's count (bytes 16-17), so a corrupt
        # length is refused after 18 bytes instead of holding the stream for up to 64 KiB.
        avail = len(buf) - start
        if avail < 5:
            return NEED_MORE
        msg_id = buf[start + 2]
        n = buf[start + 3] | (buf[start + 4] << 8)
        if msg_id == MSG_SOLAR_VECTOR:
            return FRAME_OVERHEAD + n if n == SOLAR_VECTOR_PAYLOAD_LEN else BAD_LENGTH
        if msg_id == MSG_POLARIZATION_OBS:
            item = POINT_LEN
        elif msg_id == MSG_COMPASS:
            item = UNIT_LEN
        else:
            return BAD_LENGTH
        if n < HEADER_LEN or (n - HEADER_LEN) % item:
            return BAD_LENGTH
        if avail < 18:
            return NEED_MORE
        if n != HEADER_LEN + item * (buf[start + 16] | (buf[start + 17] << 8)):
            return BAD_LENGTH
        return FRAME_OVERHEAD + n

    def check(self, frame: bytes) -> bool:
        return crc16_ccitt(frame[2:-2]) == (frame[-2] | (frame[-1] << 8))

    def parse(self, frame: bytes) -> PolarizationObs | PolarizationObsPacked | CompassFrame | SolarVectorFrame:
        msg_id = frame[2]
        payload = frame[5:-2]
        h: PsnsHeader = _decode_header(payload)
        body = payload[HEADER_LEN:]
        if msg_id == MSG_POLARIZATION_OBS:
            if len(body) != h.count * POINT_LEN:
                raise ValueError(f"POLARIZATION_OBS: {h.count} points need {h.count * POINT_LEN} bytes, "
                                 f"got {len(body)}")
            if self.packed_points:
                return PolarizationObsPacked(h, body)
            return PolarizationObs(h, _decode_points(body))
        if msg_id == MSG_COMPASS:
            if len(body) != h.count * UNIT_LEN:
                raise ValueError(f"COMPASS: {h.count} units need {h.count * UNIT_LEN} bytes, got {len(body)}")
            return CompassFrame(h, _decode_units(body))
        if len(body) != _SV.size:
            raise ValueError(f"SOLAR_VECTOR payload must be {SOLAR_VECTOR_PAYLOAD_LEN} bytes")
        sv: SolarVectorFrame = _decode_solar_vector(body, 0, h)
        return sv
