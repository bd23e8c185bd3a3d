"""Host port commands (host -> DSP, ids >= 0x80): ids, payload specs, dataclasses and their derived codecs.

Every payload starts with a host-chosen u8 token, echoed in the ACK (:mod:`protocols.host`, which frames
these payloads and re-exports every name here). Each payload is declared once, by its ``construct`` spec in
:data:`COMMAND_SPECS`; the ``struct`` codecs are derived from it (:mod:`protocols.codec`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from construct import Float32l, Int8ul, Struct

from ._fastinit import fast_frozen_init
from .codec import StructCodec

__all__ = [
    "CMD_REQUEST_STATUS",
    "CMD_RESET_FILTER",
    "CMD_SELECT_VARIANT",
    "CMD_SET_OUTPUT_RATE",
    "COMMAND_PAYLOAD_LEN",
    "COMMAND_SPECS",
    "OUTPUT_RATE_MIN_HZ",
    "HostCommand",
    "RequestStatus",
    "ResetFilter",
    "SelectVariant",
    "SetOutputRate",
    "command_payload",
    "decode_command_payload",
]

CMD_RESET_FILTER = 0x81
CMD_SELECT_VARIANT = 0x82
CMD_SET_OUTPUT_RATE = 0x83
CMD_REQUEST_STATUS = 0x84

#: The lowest SET_OUTPUT_RATE rate accepted (besides 0, which stops the output), Hz: one NAV_SOLUTION every 10 s.
#: A rate below it, not finite, above the IMU rate or not the IMU rate / k is refused with BAD_ARGUMENT
#: (docs/decisions/protocols.md D-3.11).
OUTPUT_RATE_MIN_HZ = 0.1

# Field docs are "scale | unit | meaning" (read by protocols.icd for docs/icd.md).
COMMAND_SPECS = {
    CMD_RESET_FILTER: Struct("token" / Int8ul * " |  | host-chosen, echoed in ACK",
                             "scope" / Int8ul * " |  | 0 restart alignment, 1 reset covariance only"),
    CMD_SELECT_VARIANT: Struct("token" / Int8ul * " |  | host-chosen, echoed in ACK",
                               "variant" / Int8ul * " |  | FilterVariant 1..5"),
    CMD_SET_OUTPUT_RATE: Struct("token" / Int8ul * " |  | host-chosen, echoed in ACK",
                                "rate_hz" / Float32l * "1 | Hz | 200/k for integer k, >= 0.1 Hz; 0 stops the output"),
    CMD_REQUEST_STATUS: Struct("token" / Int8ul * " |  | host-chosen, echoed in ACK"),
}


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class ResetFilter:
    """RESET_FILTER: ``scope`` 0 restarts alignment, 1 resets the covariance only."""

    token: int
    scope: int = 0


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class SelectVariant:
    """SELECT_VARIANT: switch to :class:`FilterVariant` ``variant`` (the filter restarts)."""

    token: int
    variant: int


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class SetOutputRate:
    """SET_OUTPUT_RATE: NAV_SOLUTION rate, Hz (200 Hz / k, at least :data:`OUTPUT_RATE_MIN_HZ`; 0 stops the
    output)."""

    token: int
    rate_hz: float


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class RequestStatus:
    """REQUEST_STATUS: answered by ACK and one STATUS frame."""

    token: int


HostCommand = ResetFilter | SelectVariant | SetOutputRate | RequestStatus


_CODECS = {cid: StructCodec(spec, f"COMMAND_0x{cid:02X}") for cid, spec in COMMAND_SPECS.items()}
_u8 = (0xFF).__and__
#: command id -> (dataclass, decoder, encoder), all by field name from COMMAND_SPECS
_COMMAND_CODECS: dict[int, tuple[type, Any, Any]] = {
    cid: (cls, _CODECS[cid].decoder(cls),
          _CODECS[cid].encoder(cls, convert={f: _u8 for f in _CODECS[cid].names if f != "rate_hz"}))
    for cid, cls in ((CMD_RESET_FILTER, ResetFilter), (CMD_SELECT_VARIANT, SelectVariant),
                     (CMD_SET_OUTPUT_RATE, SetOutputRate), (CMD_REQUEST_STATUS, RequestStatus))
}
_COMMAND_ID = {cls: cid for cid, (cls, _, _) in _COMMAND_CODECS.items()}

#: command id -> exact payload length
COMMAND_PAYLOAD_LEN = {cid: codec.size for cid, codec in _CODECS.items()}


def command_payload(c: HostCommand) -> tuple[int, bytes]:
    """``(command id, payload)`` of one of the command dataclasses (u8 fields wrap to their byte)."""
    cid = _COMMAND_ID.get(type(c))
    if cid is None:
        raise TypeError(f"not a host command: {c!r}")
    payload: bytes = _COMMAND_CODECS[cid][2](c)
    return cid, payload


def decode_command_payload(msg_id: int, payload: bytes) -> HostCommand:
    """The command dataclass of a command payload (its length checked by the frame's header)."""
    cmd: HostCommand = _COMMAND_CODECS[msg_id][1](payload)
    return cmd
