"""u-blox UBX binary protocol: framing, Fletcher checksum, NAV-PVT, NAV-STATUS and the NAV messages of the
generations before NAV-PVT (NAV-POSLLH, NAV-SOL, NAV-VELNED, NAV-TIMEUTC, NAV-TIMEGPS).

Source: ``docs/reference/wire-formats.md`` sections 2.1-2.2 (u-blox interface descriptions,
e.g. F10 SPG 6.00 UBX-23002975; checked against pyubx2 1.4.0). Every UBX frame::

    off  size  field
    0    2     sync 0xB5 0x62 ("mu b")
    2    1     class        NAV = 0x01
    3    1     id           PVT = 0x07, STATUS = 0x03
    4    2     length N     u16 little-endian, payload bytes only
    6    N     payload      little-endian fields
    6+N  2     CK_A, CK_B   8-bit Fletcher over class, id, length, payload

UBX-NAV-PVT payload (92 bytes, protocol >= 15; frame 100 bytes), u-blox names and raw units::

    0  U4 iTOW ms (GPS time of week)   4  U2 year   6..10 U1 month, day, hour, min, sec (UTC)
    11 X1 valid (b0 validDate, b1 validTime, b2 fullyResolved, b3 validMag)
    12 U4 tAcc ns   16 I4 nano ns   20 U1 fixType (0 none, 1 DR, 2 2D, 3 3D, 4 GNSS+DR, 5 time)
    21 X1 flags (b0 gnssFixOK, b1 diffSoln, b2-4 psmState, b5 headVehValid, b6-7 carrSoln)
    22 X1 flags2 (b5 confirmedAvai, b6 confirmedDate, b7 confirmedTime)   23 U1 numSV
    24 I4 lon 1e-7 deg   28 I4 lat 1e-7 deg   32 I4 height mm (ellipsoid)   36 I4 hMSL mm
    40 U4 hAcc mm   44 U4 vAcc mm   48/52/56 I4 velN/velE/velD mm/s   60 I4 gSpeed mm/s
    64 I4 headMot 1e-5 deg   68 U4 sAcc mm/s   72 U4 headAcc 1e-5 deg   76 U2 pDOP 0.01
    78 X2 flags3 (b0 invalidLlh, b1-4 lastCorrectionAge)   80 U1[4] reserved0 (kept as a U4 here)
    84 I4 headVeh 1e-5 deg   88 I2 magDec 1e-2 deg   90 U2 magAcc 1e-2 deg

UBX-NAV-STATUS payload (16 bytes)::

    0 U4 iTOW ms   4 U1 gpsFix (as fixType)   5 X1 flags (b0 gpsFixOk, b1 diffSoln, b2 wknSet,
    b3 towSet)   6 X1 fixStat   7 X1 flags2   8 U4 ttff ms   12 U4 msss ms (since start-up)

The navigation messages of u-blox 5/6/7 (no NAV-PVT before protocol 14) that later generations still send when
configured (u-blox 6 Receiver Description GPS.G6-SW-10018, sections 35.5-35.13; u-blox M8 Receiver Description
UBX-13003221, 32.17; the same layouts in pyubx2's ``ubxtypes_get``), all little-endian::

    NAV-POSLLH  0x01 0x02  28 bytes  0 U4 iTOW ms  4 I4 lon 1e-7 deg  8 I4 lat 1e-7 deg  12 I4 height mm
                                     (ellipsoid)  16 I4 hMSL mm  20 U4 hAcc mm  24 U4 vAcc mm
    NAV-SOL     0x01 0x06  52 bytes  0 U4 iTOW ms  4 I4 fTOW ns  8 I2 week  10 U1 gpsFix  11 X1 flags (b0
                                     gpsFixOK, b1 diffSoln, b2 wknSet, b3 towSet)  12/16/20 I4 ecefX/Y/Z cm
                                     24 U4 pAcc cm  28/32/36 I4 ecefVX/VY/VZ cm/s  40 U4 sAcc cm/s
                                     44 U2 pDOP 0.01  46 U1 reserved1  47 U1 numSV  48 U4 reserved2
    NAV-VELNED  0x01 0x12  36 bytes  0 U4 iTOW ms  4/8/12 I4 velN/velE/velD cm/s  16 U4 speed cm/s (3-D)
                                     20 U4 gSpeed cm/s  24 I4 heading 1e-5 deg  28 U4 sAcc cm/s
                                     32 U4 cAcc 1e-5 deg
    NAV-TIMEGPS 0x01 0x20  16 bytes  0 U4 iTOW ms  4 I4 fTOW ns  8 I2 week  10 I1 leapS s  11 X1 valid (b0
                                     towValid, b1 weekValid, b2 leapSValid)  12 U4 tAcc ns
    NAV-TIMEUTC 0x01 0x21  20 bytes  0 U4 iTOW ms  4 U4 tAcc ns  8 I4 nano ns  12 U2 year  14..18 U1 month,
                                     day, hour, min, sec  19 X1 valid (b0 validTOW, b1 validWKN, b2 validUTC,
                                     b4-7 utcStandard)

:class:`UbxFormat` decodes NAV-PVT and NAV-STATUS into :class:`NavPvt` / :class:`NavStatus` and
every other checked frame into :class:`UbxFrame`. NAV-PVT is parsed by its known prefix, as the u-blox
descriptions ask of a reader ("the payload may be extended in later versions"): the 84-byte payload of
protocol 14 (u-blox 7: the layout above up to ``pDOP``, then 6 reserved bytes) fills the fields after
``pDOP`` with zero; the 92-byte payload of protocols 15-34 (M8, F9, M10) is parsed whole; a longer one
(a later protocol) is parsed by its first 92 bytes. Any other NAV-PVT length is refused at the header
(a length error).
Frames of an unknown message class are refused at the header, so a stray ``B5 62`` in noise
costs at most six bytes.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any

from construct import Bytes, Const, Int8sl, Int8ul, Int16sl, Int16ul, Int32sl, Int32ul, Struct

from ._fastinit import fast_frozen_init
from .codec import StructCodec
from .stream import BAD_LENGTH, NEED_MORE

__all__ = [
    "CLS_NAV",
    "ID_NAV_POSLLH",
    "ID_NAV_PVT",
    "ID_NAV_SOL",
    "ID_NAV_STATUS",
    "ID_NAV_TIMEGPS",
    "ID_NAV_TIMEUTC",
    "ID_NAV_VELNED",
    "LEGACY_NAV",
    "NAV_POSLLH_SPEC",
    "NAV_PVT_LEN",
    "NAV_PVT_LEN_V14",
    "NAV_PVT_PREFIX_V14",
    "NAV_PVT_SPEC",
    "NAV_SOL_SPEC",
    "NAV_STATUS_LEN",
    "NAV_STATUS_SPEC",
    "NAV_TIMEGPS_SPEC",
    "NAV_TIMEUTC_SPEC",
    "NAV_VELNED_SPEC",
    "UBX_CLASSES",
    "UBX_FRAME_SPEC",
    "UBX_MAX_PAYLOAD",
    "UBX_SYNC",
    "NavPosllh",
    "NavPvt",
    "NavSol",
    "NavStatus",
    "NavTimeGps",
    "NavTimeUtc",
    "NavVelned",
    "UbxFormat",
    "UbxFrame",
    "build_ubx_frame",
    "encode_nav_pvt",
    "encode_nav_status",
    "encode_ubx",
    "legacy_nav_codec",
]

UBX_SYNC = b"\xb5\x62"
#: Largest payload accepted from the header (RXM-RAWX with 64 measurements needs 2064).
UBX_MAX_PAYLOAD = 4096
CLS_NAV = 0x01
ID_NAV_PVT = 0x07
ID_NAV_STATUS = 0x03
NAV_PVT_LEN = 92
#: NAV-PVT payload of protocol 14 (u-blox 7)
NAV_PVT_LEN_V14 = 84
NAV_STATUS_LEN = 16
ID_NAV_POSLLH = 0x02
ID_NAV_SOL = 0x06
ID_NAV_VELNED = 0x12
ID_NAV_TIMEGPS = 0x20
ID_NAV_TIMEUTC = 0x21
#: Message classes of the u-blox protocol (NAV, RXM, INF, ACK, CFG, UPD, MON, AID, TIM, ESF,
#: MGA, LOG, SEC, HNR, NAV2); a header naming any other class is refused at once.
UBX_CLASSES = frozenset({0x01, 0x02, 0x04, 0x05, 0x06, 0x09, 0x0A, 0x0B, 0x0D, 0x10, 0x13, 0x21, 0x27, 0x28, 0x29})
#: Fixed payload lengths of the messages decoded here; others only need the class check.
_FIXED_LEN = {(CLS_NAV, ID_NAV_STATUS): (NAV_STATUS_LEN,), (CLS_NAV, ID_NAV_POSLLH): (28,),
              (CLS_NAV, ID_NAV_SOL): (52,), (CLS_NAV, ID_NAV_VELNED): (36,), (CLS_NAV, ID_NAV_TIMEGPS): (16,),
              (CLS_NAV, ID_NAV_TIMEUTC): (20,)}


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class NavPvt:
    """UBX-NAV-PVT with the u-blox field names and raw integer units (module docstring)."""

    iTOW: int
    year: int
    month: int
    day: int
    hour: int
    min: int
    sec: int
    valid: int
    tAcc: int
    nano: int
    fixType: int
    flags: int
    flags2: int
    numSV: int
    lon: int
    lat: int
    height: int
    hMSL: int
    hAcc: int
    vAcc: int
    velN: int
    velE: int
    velD: int
    gSpeed: int
    headMot: int
    sAcc: int
    headAcc: int
    pDOP: int
    flags3: int
    reserved0: int
    headVeh: int
    magDec: int
    magAcc: int


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class NavStatus:
    """UBX-NAV-STATUS with the u-blox field names and raw units (ms)."""

    iTOW: int
    gpsFix: int
    flags: int
    fixStat: int
    flags2: int
    ttff: int
    msss: int


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class NavPosllh:
    """UBX-NAV-POSLLH (u-blox names, raw units: 1e-7 deg, mm)."""

    iTOW: int
    lon: int
    lat: int
    height: int
    hMSL: int
    hAcc: int
    vAcc: int


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class NavSol:
    """UBX-NAV-SOL (u-blox names, raw units: ms, ns, cm, cm/s, 0.01)."""

    iTOW: int
    fTOW: int
    week: int
    gpsFix: int
    flags: int
    ecefX: int
    ecefY: int
    ecefZ: int
    pAcc: int
    ecefVX: int
    ecefVY: int
    ecefVZ: int
    sAcc: int
    pDOP: int
    reserved1: int
    numSV: int
    reserved2: int


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class NavVelned:
    """UBX-NAV-VELNED (u-blox names, raw units: cm/s, 1e-5 deg)."""

    iTOW: int
    velN: int
    velE: int
    velD: int
    speed: int
    gSpeed: int
    heading: int
    sAcc: int
    cAcc: int


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class NavTimeGps:
    """UBX-NAV-TIMEGPS (u-blox names: ms, ns, weeks, leap seconds s)."""

    iTOW: int
    fTOW: int
    week: int
    leapS: int
    valid: int
    tAcc: int


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class NavTimeUtc:
    """UBX-NAV-TIMEUTC (u-blox names, UTC calendar fields)."""

    iTOW: int
    tAcc: int
    nano: int
    year: int
    month: int
    day: int
    hour: int
    min: int
    sec: int
    valid: int


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class UbxFrame:
    """A checked UBX frame without a typed decoder here."""

    cls: int
    id: int
    payload: bytes


# Field docs are "scale | unit | meaning" (read by protocols.icd for docs/icd.md).
NAV_PVT_SPEC = Struct(
    "iTOW" / Int32ul * "1 | ms | GPS time of week",
    "year" / Int16ul * "1 |  | UTC year",
    "month" / Int8ul * "1 |  | UTC month 1..12",
    "day" / Int8ul * "1 |  | UTC day 1..31",
    "hour" / Int8ul * "1 | h | UTC hour",
    "min" / Int8ul * "1 | min | UTC minute",
    "sec" / Int8ul * "1 | s | UTC second 0..60",
    "valid" / Int8ul * " |  | b0 validDate, b1 validTime, b2 fullyResolved, b3 validMag",
    "tAcc" / Int32ul * "1 | ns | time accuracy",
    "nano" / Int32sl * "1 | ns | fraction of the second, -1e9..1e9",
    "fixType" / Int8ul * " |  | 0 none, 1 DR, 2 2D, 3 3D, 4 GNSS+DR, 5 time only",
    "flags" / Int8ul * " |  | b0 gnssFixOK, b1 diffSoln, b2-4 psmState, b5 headVehValid, b6-7 carrSoln",
    "flags2" / Int8ul * " |  | b5 confirmedAvai, b6 confirmedDate, b7 confirmedTime",
    "numSV" / Int8ul * "1 |  | satellites used",
    "lon" / Int32sl * "1e-7 | deg | longitude",
    "lat" / Int32sl * "1e-7 | deg | latitude",
    "height" / Int32sl * "1 | mm | height above the ellipsoid",
    "hMSL" / Int32sl * "1 | mm | height above mean sea level",
    "hAcc" / Int32ul * "1 | mm | horizontal accuracy",
    "vAcc" / Int32ul * "1 | mm | vertical accuracy",
    "velN" / Int32sl * "1 | mm/s | north velocity",
    "velE" / Int32sl * "1 | mm/s | east velocity",
    "velD" / Int32sl * "1 | mm/s | down velocity",
    "gSpeed" / Int32sl * "1 | mm/s | 2-D ground speed",
    "headMot" / Int32sl * "1e-5 | deg | heading of motion",
    "sAcc" / Int32ul * "1 | mm/s | speed accuracy",
    "headAcc" / Int32ul * "1e-5 | deg | heading accuracy",
    "pDOP" / Int16ul * "0.01 |  | position DOP",
    "flags3" / Int16ul * " |  | b0 invalidLlh, b1-4 lastCorrectionAge",
    "reserved0" / Int32ul * " |  | reserved (U1[4])",
    "headVeh" / Int32sl * "1e-5 | deg | heading of vehicle",
    "magDec" / Int16sl * "1e-2 | deg | magnetic declination",
    "magAcc" / Int16ul * "1e-2 | deg | declination accuracy",
)
NAV_STATUS_SPEC = Struct(
    "iTOW" / Int32ul * "1 | ms | GPS time of week",
    "gpsFix" / Int8ul * " |  | 0 none, 1 DR, 2 2D, 3 3D, 4 GNSS+DR, 5 time only",
    "flags" / Int8ul * " |  | b0 gpsFixOk, b1 diffSoln, b2 wknSet, b3 towSet",
    "fixStat" / Int8ul * " |  | b0 diffCorr, b1 carrSolnValid, b6-7 mapMatching",
    "flags2" / Int8ul * " |  | b0-1 psmState, b3-4 spoofDetState, b6-7 carrSoln",
    "ttff" / Int32ul * "1 | ms | time to first fix",
    "msss" / Int32ul * "1 | ms | since start-up or reset",
)
NAV_POSLLH_SPEC = Struct(
    "iTOW" / Int32ul * "1 | ms | GPS time of week",
    "lon" / Int32sl * "1e-7 | deg | longitude",
    "lat" / Int32sl * "1e-7 | deg | latitude",
    "height" / Int32sl * "1 | mm | height above the ellipsoid",
    "hMSL" / Int32sl * "1 | mm | height above mean sea level",
    "hAcc" / Int32ul * "1 | mm | horizontal accuracy",
    "vAcc" / Int32ul * "1 | mm | vertical accuracy",
)
NAV_SOL_SPEC = Struct(
    "iTOW" / Int32ul * "1 | ms | GPS time of week",
    "fTOW" / Int32sl * "1 | ns | fraction of iTOW, -500000..500000",
    "week" / Int16sl * "1 | weeks | GPS week",
    "gpsFix" / Int8ul * " |  | 0 none, 1 DR, 2 2D, 3 3D, 4 GPS+DR, 5 time only",
    "flags" / Int8ul * " |  | b0 gpsFixOK, b1 diffSoln, b2 wknSet, b3 towSet",
    "ecefX" / Int32sl * "1 | cm | ECEF X",
    "ecefY" / Int32sl * "1 | cm | ECEF Y",
    "ecefZ" / Int32sl * "1 | cm | ECEF Z",
    "pAcc" / Int32ul * "1 | cm | 3-D position accuracy",
    "ecefVX" / Int32sl * "1 | cm/s | ECEF X velocity",
    "ecefVY" / Int32sl * "1 | cm/s | ECEF Y velocity",
    "ecefVZ" / Int32sl * "1 | cm/s | ECEF Z velocity",
    "sAcc" / Int32ul * "1 | cm/s | speed accuracy",
    "pDOP" / Int16ul * "0.01 |  | position DOP",
    "reserved1" / Int8ul * " |  | reserved",
    "numSV" / Int8ul * "1 |  | satellites used",
    "reserved2" / Int32ul * " |  | reserved",
)
NAV_VELNED_SPEC = Struct(
    "iTOW" / Int32ul * "1 | ms | GPS time of week",
    "velN" / Int32sl * "1 | cm/s | north velocity",
    "velE" / Int32sl * "1 | cm/s | east velocity",
    "velD" / Int32sl * "1 | cm/s | down velocity",
    "speed" / Int32ul * "1 | cm/s | 3-D speed",
    "gSpeed" / Int32ul * "1 | cm/s | ground speed",
    "heading" / Int32sl * "1e-5 | deg | heading of motion",
    "sAcc" / Int32ul * "1 | cm/s | speed accuracy",
    "cAcc" / Int32ul * "1e-5 | deg | heading accuracy",
)
NAV_TIMEGPS_SPEC = Struct(
    "iTOW" / Int32ul * "1 | ms | GPS time of week",
    "fTOW" / Int32sl * "1 | ns | fraction of iTOW",
    "week" / Int16sl * "1 | weeks | GPS week",
    "leapS" / Int8sl * "1 | s | GPS - UTC leap seconds",
    "valid" / Int8ul * " |  | b0 towValid, b1 weekValid, b2 leapSValid",
    "tAcc" / Int32ul * "1 | ns | time accuracy",
)
NAV_TIMEUTC_SPEC = Struct(
    "iTOW" / Int32ul * "1 | ms | GPS time of week",
    "tAcc" / Int32ul * "1 | ns | time accuracy",
    "nano" / Int32sl * "1 | ns | fraction of the second, -1e9..1e9",
    "year" / Int16ul * "1 |  | UTC year",
    "month" / Int8ul * "1 |  | UTC month 1..12",
    "day" / Int8ul * "1 |  | UTC day 1..31",
    "hour" / Int8ul * "1 | h | UTC hour",
    "min" / Int8ul * "1 | min | UTC minute",
    "sec" / Int8ul * "1 | s | UTC second 0..60",
    "valid" / Int8ul * " |  | b0 validTOW, b1 validWKN, b2 validUTC, b4-7 utcStandard",
)
#: The whole-frame layout (header + payload + checksum) for documentation and tools.
UBX_FRAME_SPEC = Struct(
    "sync" / Const(UBX_SYNC) * " |  | 0xB5 0x62",
    "cls" / Int8ul * " |  | message class (NAV 0x01)",
    "id" / Int8ul * " |  | message id (PVT 0x07, STATUS 0x03)",
    "length" / Int16ul * "1 | bytes | payload length N",
    "payload" / Bytes(lambda ctx: ctx.length) * " |  | N bytes, little-endian fields",
    "ck_a" / Int8ul * " |  | Fletcher CK_A = sum of class..payload mod 256",
    "ck_b" / Int8ul * " |  | Fletcher CK_B = sum of the running CK_A mod 256",
)

#: bytes protocol 14 shares with the later layout: ``iTOW`` .. ``pDOP`` (derived from the spec)
_PVT_NAMES = [sc.name for sc in NAV_PVT_SPEC.subcons]
NAV_PVT_PREFIX_V14 = Struct(*NAV_PVT_SPEC.subcons[: _PVT_NAMES.index("pDOP") + 1]).sizeof()
_PVT_TAIL_ZERO = bytes(NAV_PVT_LEN - NAV_PVT_PREFIX_V14)
_PVT = StructCodec(NAV_PVT_SPEC, "UBX_NAV_PVT")
_STATUS = StructCodec(NAV_STATUS_SPEC, "UBX_NAV_STATUS")
if (_PVT.size, _STATUS.size) != (NAV_PVT_LEN, NAV_STATUS_LEN):  # pragma: no cover
    raise AssertionError("UBX payload lengths disagree with the specs")
#: NavPvt / NavStatus fields are the specs' fields in order (checked by name): the unpacked tuple is their
#: argument list.
_unpack_pvt = _PVT.unpacker(NavPvt)
_unpack_status = _STATUS.unpacker(NavStatus)
_encode_pvt = _PVT.encoder(NavPvt)
_encode_status = _STATUS.encoder(NavStatus)
#: the legacy NAV messages: id -> (codec, dataclass, unpack, encode), derived from the specs like NAV-PVT's
_LEGACY: dict[int, tuple[StructCodec, type, Any, Any]] = {}
for _mid, _spec, _name, _cls in ((ID_NAV_POSLLH, NAV_POSLLH_SPEC, "UBX_NAV_POSLLH", NavPosllh),
                                 (ID_NAV_SOL, NAV_SOL_SPEC, "UBX_NAV_SOL", NavSol),
                                 (ID_NAV_VELNED, NAV_VELNED_SPEC, "UBX_NAV_VELNED", NavVelned),
                                 (ID_NAV_TIMEGPS, NAV_TIMEGPS_SPEC, "UBX_NAV_TIMEGPS", NavTimeGps),
                                 (ID_NAV_TIMEUTC, NAV_TIMEUTC_SPEC, "UBX_NAV_TIMEUTC", NavTimeUtc)):
    _c = StructCodec(_spec, _name)
    if (CLS_NAV, _mid) not in _FIXED_LEN or _FIXED_LEN[(CLS_NAV, _mid)] != (_c.size,):  # pragma: no cover
        raise AssertionError(f"{_name}: payload length disagrees with the spec")
    _LEGACY[_mid] = (_c, _cls, _c.unpacker(_cls), _c.encoder(_cls))
#: the typed legacy NAV classes by message id (NAV-POSLLH, NAV-SOL, NAV-VELNED, NAV-TIMEGPS, NAV-TIMEUTC)
LEGACY_NAV: dict[int, type] = {mid: v[1] for mid, v in _LEGACY.items()}
_LEGACY_ID = {v[1]: mid for mid, v in _LEGACY.items()}

_accumulate = itertools.accumulate


def build_ubx_frame(cls: int, msg_id: int, payload: bytes) -> bytes:
    """Frame ``payload`` as UBX message (``cls``, ``msg_id``) with its Fletcher checksum."""
    if len(payload) > 0xFFFF:
        raise ValueError(f"UBX payload of {len(payload)} bytes does not fit the u16 length")
    body = bytes((cls & 0xFF, msg_id & 0xFF, len(payload) & 0xFF, len(payload) >> 8)) + payload
    return UBX_SYNC + body + bytes((sum(body) & 0xFF, sum(_accumulate(body)) & 0xFF))


def encode_nav_pvt(p: NavPvt) -> bytes:
    """Whole UBX-NAV-PVT frame (100 bytes). Raises ``ValueError`` for a field out of its range."""
    return build_ubx_frame(CLS_NAV, ID_NAV_PVT, _encode_pvt(p))  # ValueError names the field's range


def encode_nav_status(s: NavStatus) -> bytes:
    """Whole UBX-NAV-STATUS frame (24 bytes)."""
    return build_ubx_frame(CLS_NAV, ID_NAV_STATUS, _encode_status(s))


def legacy_nav_codec(msg_id: int) -> StructCodec:
    """The codec of a legacy NAV message (an id of :data:`LEGACY_NAV`)."""
    return _LEGACY[msg_id][0]


def encode_ubx(obj: Any) -> bytes:
    """Encode any object :class:`UbxFormat` decodes (a legacy NAV message included)."""
    if isinstance(obj, NavPvt):
        return encode_nav_pvt(obj)
    if isinstance(obj, NavStatus):
        return encode_nav_status(obj)
    mid = _LEGACY_ID.get(type(obj))
    if mid is not None:
        return build_ubx_frame(CLS_NAV, mid, _LEGACY[mid][3](obj))
    return build_ubx_frame(obj.cls, obj.id, obj.payload)


class UbxFormat:
    """:class:`~protocols.stream.FrameFormat` of UBX frames (NAV-PVT, NAV-STATUS and the legacy NAV messages
    typed)."""

    name = "ubx"
    sync = UBX_SYNC

    @staticmethod
    def encode(obj: Any) -> bytes:
        """Encode a decoded object back to its frame (:func:`encode_ubx`)."""
        return encode_ubx(obj)

    def frame_length(self, buf: bytes | bytearray, start: int) -> int:
        if len(buf) - start < 6:
            return NEED_MORE
        cls = buf[start + 2]
        if cls not in UBX_CLASSES:
            return BAD_LENGTH
        n = buf[start + 4] | (buf[start + 5] << 8)
        mid = buf[start + 3]
        fixed = _FIXED_LEN.get((cls, mid))
        if (fixed is not None and n not in fixed) or n > UBX_MAX_PAYLOAD:
            return BAD_LENGTH
        if cls == CLS_NAV and mid == ID_NAV_PVT and n != NAV_PVT_LEN_V14 and n < NAV_PVT_LEN:
            return BAD_LENGTH
        return n + 8

    def check(self, frame: bytes) -> bool:
        body = frame[2:-2]
        return frame[-2] == (sum(body) & 0xFF) and frame[-1] == (sum(_accumulate(body)) & 0xFF)

    def parse(self, frame: bytes) -> Any:
        cls, mid = frame[2], frame[3]
        n = len(frame) - 8
        if cls == CLS_NAV:
            if mid == ID_NAV_PVT:
                if n >= NAV_PVT_LEN:
                    return NavPvt(*_unpack_pvt(frame, 6))
                if n == NAV_PVT_LEN_V14:
                    return NavPvt(*_unpack_pvt(bytes(frame[6 : 6 + NAV_PVT_PREFIX_V14]) + _PVT_TAIL_ZERO, 0))
            if mid == ID_NAV_STATUS and n == NAV_STATUS_LEN:
                return NavStatus(*_unpack_status(frame, 6))
            leg = _LEGACY.get(mid)
            if leg is not None:  # length checked at the header (_FIXED_LEN)
                return leg[1](*leg[2](frame, 6))
        return UbxFrame(cls, mid, bytes(frame[6:-2]))
