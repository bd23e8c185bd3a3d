"""UBX messages a host sends a u-blox receiver and its answers: ACK-ACK/NAK, CFG-PRT, CFG-MSG, CFG-RATE, MON-VER.

Layouts from the u-blox M8 receiver description (UBX-13003221, sections UBX-ACK, UBX-CFG-MSG, UBX-CFG-PRT,
UBX-CFG-RATE, UBX-MON-VER); the field names are u-blox's (and pyubx2's, which the tests decode with). A poll is
the message with an empty payload (CFG-PRT: an empty payload or the 1-byte ``portID``; CFG-MSG: the 2-byte
``msgClass``, ``msgID``); the receiver answers a poll with the message itself, and every CFG message (poll or set)
with ACK-ACK, or ACK-NAK when it cannot apply it.

====================  ======  ====== ===============================================================
message               class   id     payload
====================  ======  ====== ===============================================================
ACK-NAK / ACK-ACK     0x05    0x00/1 :data:`ACK_SPEC` (2 bytes: the acknowledged class and id)
CFG-PRT (UART)        0x06    0x00   :data:`CFG_PRT_SPEC` (20 bytes)
CFG-MSG               0x06    0x01   :data:`CFG_MSG_SPEC` (8 bytes, a rate per port) or class, id, rate (3)
CFG-RATE              0x06    0x08   :data:`CFG_RATE_SPEC` (6 bytes)
MON-VER               0x0A    0x04   :data:`MON_VER_HEAD_SPEC` (40 bytes) + 30-byte extension strings
====================  ======  ====== ===============================================================
"""

from __future__ import annotations

from dataclasses import dataclass

from construct import Bytes, Int8ul, Int16ul, Int32ul, Struct

from ._fastinit import fast_frozen_init
from .codec import StructCodec
from .ubx import build_ubx_frame

__all__ = [
    "ACK_SPEC",
    "CFG_MSG_SPEC",
    "CFG_PRT_SPEC",
    "CFG_RATE_SPEC",
    "CLS_ACK",
    "CLS_CFG",
    "CLS_MON",
    "ID_ACK_ACK",
    "ID_ACK_NAK",
    "ID_CFG_MSG",
    "ID_CFG_PRT",
    "ID_CFG_RATE",
    "ID_MON_VER",
    "MON_VER_EXT_LEN",
    "MON_VER_HEAD_SPEC",
    "Ack",
    "CfgMsg",
    "CfgPrt",
    "CfgRate",
    "MonVer",
    "decode_cfg_msg",
    "decode_cfg_prt",
    "decode_cfg_rate",
    "decode_mon_ver",
    "encode_ack",
    "encode_cfg_msg",
    "encode_cfg_prt",
    "encode_cfg_rate",
    "encode_mon_ver",
]

CLS_ACK, ID_ACK_NAK, ID_ACK_ACK = 0x05, 0x00, 0x01
CLS_CFG, ID_CFG_PRT, ID_CFG_MSG, ID_CFG_RATE = 0x06, 0x00, 0x01, 0x08
CLS_MON, ID_MON_VER = 0x0A, 0x04
#: bytes of each MON-VER extension string (NUL padded)
MON_VER_EXT_LEN = 30

ACK_SPEC = Struct(
    "clsID" / Int8ul * " |  | class of the acknowledged message",
    "msgID" / Int8ul * " |  | id of the acknowledged message",
)
CFG_PRT_SPEC = Struct(
    "portID" / Int8ul * " |  | 1 = UART1, 2 = UART2, 3 = USB, 4 = SPI, 0 = I2C",
    "reserved0" / Int8ul * " |  | reserved",
    "txReady" / Int16ul * " |  | TX-ready pin: b0 en, b1 pol, b2-6 pin, b7-15 thres",
    "mode" / Int32ul * " |  | b6-7 charLen (3 = 8 bit), b9-11 parity (4 = none), b12-13 nStopBits (0 = 1)",
    "baudRate" / Int32ul * "1 | Bd | baud rate",
    "inProtoMask" / Int16ul * " |  | b0 UBX, b1 NMEA, b2 RTCM2, b5 RTCM3",
    "outProtoMask" / Int16ul * " |  | b0 UBX, b1 NMEA, b5 RTCM3",
    "flags" / Int16ul * " |  | b1 extendedTxTimeout",
    "reserved1" / Int16ul * " |  | reserved",
)
CFG_MSG_SPEC = Struct(
    "msgClass" / Int8ul * " |  | message class",
    "msgID" / Int8ul * " |  | message id",
    "rateDDC" / Int8ul * "1 | epochs | send every N navigation epochs on I2C (0 = off)",
    "rateUART1" / Int8ul * "1 | epochs | ... on UART1",
    "rateUART2" / Int8ul * "1 | epochs | ... on UART2",
    "rateUSB" / Int8ul * "1 | epochs | ... on USB",
    "rateSPI" / Int8ul * "1 | epochs | ... on SPI",
    "reserved" / Int8ul * "1 | epochs | reserved port",
)
CFG_RATE_SPEC = Struct(
    "measRate" / Int16ul * "1 | ms | time between measurements",
    "navRate" / Int16ul * "1 | cycles | measurements per navigation solution",
    "timeRef" / Int16ul * " |  | 0 UTC, 1 GPS, 2 GLONASS, 3 BeiDou, 4 Galileo",
)
MON_VER_HEAD_SPEC = Struct(
    "swVersion" / Bytes(30) * " |  | software version, NUL-terminated",
    "hwVersion" / Bytes(10) * " |  | hardware version, NUL-terminated",
)


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class Ack:
    """The payload of ACK-ACK and ACK-NAK: the acknowledged message (``clsID``, ``msgID``)."""

    clsID: int
    msgID: int


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class CfgPrt:
    """UBX-CFG-PRT for a UART port (u-blox field names, raw values)."""

    portID: int
    reserved0: int
    txReady: int
    mode: int
    baudRate: int
    inProtoMask: int
    outProtoMask: int
    flags: int
    reserved1: int


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class CfgMsg:
    """UBX-CFG-MSG: the output rate of one message on each of the six ports."""

    msgClass: int
    msgID: int
    rateDDC: int
    rateUART1: int
    rateUART2: int
    rateUSB: int
    rateSPI: int
    reserved: int


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class CfgRate:
    """UBX-CFG-RATE: ``measRate`` ms between measurements, ``navRate`` measurements per solution."""

    measRate: int
    navRate: int
    timeRef: int


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class MonVer:
    """UBX-MON-VER: software and hardware versions and the extension strings (decoded, NULs stripped)."""

    swVersion: str
    hwVersion: str
    extensions: tuple[str, ...]


_ACK = StructCodec(ACK_SPEC, "UBX_ACK")
_PRT = StructCodec(CFG_PRT_SPEC, "UBX_CFG_PRT")
_MSG = StructCodec(CFG_MSG_SPEC, "UBX_CFG_MSG")
_RATE = StructCodec(CFG_RATE_SPEC, "UBX_CFG_RATE")
_VER = StructCodec(MON_VER_HEAD_SPEC, "UBX_MON_VER")
_enc_ack = _ACK.encoder(Ack)
_enc_prt, _dec_prt = _PRT.encoder(CfgPrt), _PRT.unpacker(CfgPrt)
_enc_msg, _dec_msg = _MSG.encoder(CfgMsg), _MSG.unpacker(CfgMsg)
_enc_rate, _dec_rate = _RATE.encoder(CfgRate), _RATE.unpacker(CfgRate)
_MON_VER_HEAD = _VER.size


def encode_ack(cls: int, msg_id: int, ok: bool = True) -> bytes:
    """Whole ACK-ACK (``ok``) or ACK-NAK frame for the message (``cls``, ``msg_id``)."""
    return build_ubx_frame(CLS_ACK, ID_ACK_ACK if ok else ID_ACK_NAK, _enc_ack(Ack(cls, msg_id)))


def encode_cfg_prt(p: CfgPrt) -> bytes:
    """Whole CFG-PRT frame (28 bytes)."""
    return build_ubx_frame(CLS_CFG, ID_CFG_PRT, _enc_prt(p))


def decode_cfg_prt(payload: bytes) -> CfgPrt:
    """CFG-PRT from its 20-byte payload (``ValueError`` for another length)."""
    if len(payload) != _PRT.size:
        raise ValueError(f"CFG-PRT payload of {len(payload)} bytes, expected {_PRT.size}")
    return CfgPrt(*_dec_prt(payload, 0))


def encode_cfg_msg(m: CfgMsg) -> bytes:
    """Whole CFG-MSG frame with the rates of all six ports (16 bytes)."""
    return build_ubx_frame(CLS_CFG, ID_CFG_MSG, _enc_msg(m))


def decode_cfg_msg(payload: bytes, port: int = 1) -> CfgMsg:
    """CFG-MSG from an 8-byte payload, or the 3-byte form (class, id, rate on the current ``port``)."""
    if len(payload) == _MSG.size:
        return CfgMsg(*_dec_msg(payload, 0))
    if len(payload) == 3:
        rates = [0] * 6
        rates[port] = payload[2]
        return CfgMsg(payload[0], payload[1], *rates)
    raise ValueError(f"CFG-MSG payload of {len(payload)} bytes, expected 3 or {_MSG.size}")


def encode_cfg_rate(r: CfgRate) -> bytes:
    """Whole CFG-RATE frame (14 bytes)."""
    return build_ubx_frame(CLS_CFG, ID_CFG_RATE, _enc_rate(r))


def decode_cfg_rate(payload: bytes) -> CfgRate:
    if len(payload) != _RATE.size:
        raise ValueError(f"CFG-RATE payload of {len(payload)} bytes, expected {_RATE.size}")
    return CfgRate(*_dec_rate(payload, 0))


def _c(s: str, n: int) -> bytes:
    b = s.encode("ascii")
    if len(b) >= n:
        raise ValueError(f"{s!r} does not fit {n} bytes with its NUL")
    return b.ljust(n, b"\0")


def encode_mon_ver(v: MonVer) -> bytes:
    """Whole MON-VER frame: the 40-byte head (:data:`MON_VER_HEAD_SPEC`) and 30 bytes per extension."""
    payload = _c(v.swVersion, 30) + _c(v.hwVersion, 10) + b"".join(_c(e, MON_VER_EXT_LEN) for e in v.extensions)
    return build_ubx_frame(CLS_MON, ID_MON_VER, payload)


def decode_mon_ver(payload: bytes) -> MonVer:
    if len(payload) < _MON_VER_HEAD or (len(payload) - _MON_VER_HEAD) % MON_VER_EXT_LEN:
        raise ValueError(f"MON-VER payload of {len(payload)} bytes is not 40 + 30 n")
    ext = payload[_MON_VER_HEAD:]
    return MonVer(payload[:30].split(b"\0")[0].decode("ascii", "replace"),
                  payload[30:40].split(b"\0")[0].decode("ascii", "replace"),
                  tuple(ext[i:i + MON_VER_EXT_LEN].split(b"\0")[0].decode("ascii", "replace")
                        for i in range(0, len(ext), MON_VER_EXT_LEN)))
