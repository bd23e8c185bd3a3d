"""Host port (DSP UART0 through the FPGA HOST RS422 port): navigation output and commands.

Every host frame (little-endian, :data:`HOST_FRAME_SPEC`) is sync 0xA5 0x5A, msg_id, a u16 payload length N,
N payload bytes and a CRC-16/CCITT-FALSE over msg_id, length and payload. Messages (each payload declared once,
by its ``construct`` spec below, whose field docs give scale, unit and meaning; ``docs/icd.md`` section 7 is
generated from them):

* ``0x01`` NAV_SOLUTION (DSP -> host, at the configured output rate, default 100 Hz): :data:`NAV_SOLUTION_SPEC`,
  102 bytes; later versions may only append fields, and decoders accept a longer payload. The filter variants
  other than the base one (the firmware variants of ``docs/architecture.md``) append the 6-byte VARIANT block
  :data:`NAV_VARIANT_BLOCK_SPEC` (``variant_mode`` per :data:`VARIANT_MODE_MEANING`); the base variant's frame
  stays 102 bytes.
* ``0x02`` STATUS (DSP -> host, at 1 Hz and in answer to REQUEST_STATUS): :data:`STATUS_SPEC`, 64 bytes.
* ``0x03`` ACK (DSP -> host, one per command, within one output period): :data:`ACK_SPEC`, the command's id,
  its token (echoed) and an :class:`AckResult`. REQUEST_STATUS is answered by ACK, then STATUS.
* Commands (host -> DSP; ids >= 0x80; :mod:`protocols.host_commands`, re-exported here), every payload
  starting with a host-chosen u8 token (:data:`COMMAND_SPECS`): 0x81 RESET_FILTER (scope), 0x82
  SELECT_VARIANT (:class:`FilterVariant`), 0x83 SET_OUTPUT_RATE (f32 rate_hz, 200 Hz / k for integer k, at least
  :data:`OUTPUT_RATE_MIN_HZ`; 0 stops the output), 0x84 REQUEST_STATUS.

Text output for terminal users (optional, NMEA 0183 framing with checksum, same port): the
proprietary sentences ``$PSNSPOS`` (time, position, mode), ``$PSNSVEL`` (time, ENU velocity),
``$PSNSATT`` (time, roll, pitch, heading) and ``$PSNSSTA`` (time, variant, rate, CPU load, misses),
see :mod:`protocols.host_text` (re-exported here). Each stays under 82 characters.

The ``struct`` codecs of the hot paths are derived from the specs (:mod:`protocols.codec`) and fill the
dataclasses by field name.
"""

from __future__ import annotations

import enum
from binascii import crc_hqx as _crc_hqx
from dataclasses import dataclass
from typing import Any

from construct import Array, Bytes, Const, Float32l, Float64l, Int8ul, Int16ul, Int32ul, Struct, this

from ._fastinit import fast_frozen_init
from .codec import StructCodec, subspec
from .crc import crc16_ccitt
from .host_commands import (
    CMD_REQUEST_STATUS,
    CMD_RESET_FILTER,
    CMD_SELECT_VARIANT,
    CMD_SET_OUTPUT_RATE,
    COMMAND_PAYLOAD_LEN,
    COMMAND_SPECS,
    OUTPUT_RATE_MIN_HZ,
    HostCommand,
    RequestStatus,
    ResetFilter,
    SelectVariant,
    SetOutputRate,
    command_payload,
    decode_command_payload,
)
from .host_text import TEXT_SENTENCES, HostTextFormat, NavText, encode_nav_text, nav_text_sentences
from .stream import BAD_LENGTH, NEED_MORE

__all__ = [
    "ACK_SPEC",
    "CMD_REQUEST_STATUS",
    "CMD_RESET_FILTER",
    "CMD_SELECT_VARIANT",
    "CMD_SET_OUTPUT_RATE",
    "COMMAND_SPECS",
    "FILTER_VARIANT_NAMES",
    "HOST_MAX_PAYLOAD",
    "HOST_SYNC",
    "MSG_ACK",
    "MSG_NAV_SOLUTION",
    "MSG_STATUS",
    "NAV_MODE_VARIANT_MASK",
    "NAV_SOLUTION_SPEC",
    "NAV_VARIANT_BLOCK_ID",
    "NAV_VARIANT_BLOCK_SPEC",
    "OUTPUT_RATE_MIN_HZ",
    "STATUS_SPEC",
    "TEXT_SENTENCES",
    "VARIANT_MODE_MEANING",
    "Ack",
    "AckResult",
    "FilterVariant",
    "HostFormat",
    "HostFrame",
    "HostStatus",
    "HostTextFormat",
    "NavMode",
    "NavSolution",
    "NavText",
    "RequestStatus",
    "ResetFilter",
    "SelectVariant",
    "SetOutputRate",
    "build_host_frame",
    "describe_nav_mode",
    "encode_ack",
    "encode_command",
    "encode_host",
    "encode_nav_solution",
    "encode_nav_text",
    "encode_status",
    "nav_solution_frame",
    "nav_text_sentences",
]

HOST_SYNC = b"\xa5\x5a"
MSG_NAV_SOLUTION = 0x01
MSG_STATUS = 0x02
MSG_ACK = 0x03
#: Largest payload accepted from the header (every defined message is far shorter).
HOST_MAX_PAYLOAD = 1024


class FilterVariant(enum.IntEnum):
    """Firmware filter variants (docs/architecture.md, "Firmware variants"), as carried in STATUS and
    SELECT_VARIANT."""

    BASE = 1  #: bi-direction solar vector KF (the base paper)
    DUAL_VECTOR = 2  #: dual-vector switching over several polarization sensors
    KMEANS_3D = 3  #: K-means sun finding + 3-D attitude
    FEDERATED = 4  #: federated SINS/GNSS + MIMU/polarization filter
    SUN_ELEVATION = 5  #: sun-elevation positioning, multi-unit compass, Sage-Husa KF


#: Scenario names of the variants (``firmware.filter``) -> :class:`FilterVariant`.
FILTER_VARIANT_NAMES = {
    "base": FilterVariant.BASE,
    "dual_vector": FilterVariant.DUAL_VECTOR,
    "kmeans_3d": FilterVariant.KMEANS_3D,
    "federated": FilterVariant.FEDERATED,
    "sun_elevation": FilterVariant.SUN_ELEVATION,
}


class AckResult(enum.IntEnum):
    """``result`` of an ACK."""

    ACCEPTED = 0
    BAD_ARGUMENT = 1  #: value out of range (variant unknown, rate not 200 Hz / k, bad scope)
    NOT_ALLOWED = 2  #: valid but refused now (variant not in this build, filter busy)
    UNKNOWN_COMMAND = 3
    BAD_LENGTH = 4  #: payload length wrong for the command id


class NavMode(enum.IntFlag):
    """``mode`` bits of NAV_SOLUTION."""

    ALIGNING = 0x0001  #: coarse alignment in progress, solution not valid
    NAVIGATING = 0x0002  #: strapdown running
    GNSS_AIDED = 0x0004  #: a GNSS update was applied within the last 2 s
    PSNS_AIDED = 0x0008  #: a solar-vector update was applied within the last 2 s
    DEGRADED = 0x0010  #: inputs missing or rejected (see status bytes)
    # bits 8-11 carry the FilterVariant number (1 BASE .. 5 SUN_ELEVATION): named so that a mode prints as
    # ``ALIGNING|NAVIGATING|GNSS_AIDED|VARIANT_BIT0``, not ``...|256``; :func:`describe_nav_mode` spells it out
    VARIANT_BIT0 = 0x0100  #: FilterVariant number, bit 0
    VARIANT_BIT1 = 0x0200  #: FilterVariant number, bit 1
    VARIANT_BIT2 = 0x0400  #: FilterVariant number, bit 2
    VARIANT_BIT3 = 0x0800  #: FilterVariant number, bit 3


#: the NavMode bits that carry the filter variant
NAV_MODE_VARIANT_MASK = 0x0F00


def describe_nav_mode(mode: int) -> str:
    """A NAV_SOLUTION ``mode`` in words: its phase (coarse alignment, fine alignment, navigating), aiding flags
    and filter variant, e.g. ``fine alignment, GNSS-aided, variant BASE``."""
    m = int(mode)
    if m & NavMode.ALIGNING and m & NavMode.NAVIGATING:
        phase = "fine alignment"
    elif m & NavMode.ALIGNING:
        phase = "coarse alignment"
    elif m & NavMode.NAVIGATING:
        phase = "navigating"
    else:
        phase = "idle"
    parts = [phase]
    parts += [name for bit, name in ((NavMode.GNSS_AIDED, "GNSS-aided"), (NavMode.PSNS_AIDED, "PSNS-aided"),
                                     (NavMode.DEGRADED, "degraded")) if m & bit]
    v = (m & NAV_MODE_VARIANT_MASK) >> 8
    if v:
        try:
            parts.append(f"variant {FilterVariant(v).name}")
        except ValueError:
            parts.append(f"variant {v}")
    return ", ".join(parts)


# Field docs are "scale | unit | meaning" (read by protocols.icd for docs/icd.md).
HOST_FRAME_SPEC = Struct(
    "sync" / Const(HOST_SYNC) * " |  | 0xA5 0x5A",
    "msg_id" / Int8ul * " |  | message id",
    "length" / Int16ul * "1 | bytes | payload length N (<= 1024)",
    "payload" / Bytes(this.length) * " |  | N bytes",
    "crc" / Int16ul * " |  | CRC-16/CCITT-FALSE over msg_id, length, payload",
)
NAV_SOLUTION_SPEC = Struct(
    "seq" / Int32ul * "1 |  | solution counter",
    "time_s" / Float64l * "1 | s | time of validity (FPGA time of the IMU trigger)",
    "lat_deg" / Float64l * "1 | deg | WGS-84 latitude",
    "lon_deg" / Float64l * "1 | deg | WGS-84 longitude",
    "height_m" / Float32l * "1 | m | ellipsoidal height",
    "vel_enu_mps" / Array(3, Float32l) * "1 | m/s | velocity East, North, Up",
    "roll_deg" / Float32l * "1 | deg | roll, right wing down positive",
    "pitch_deg" / Float32l * "1 | deg | pitch, nose up positive",
    "heading_deg" / Float32l * "1 | deg | heading clockwise from true north, [0, 360)",
    "sigma" / Array(9, Float32l) * "1 | deg, m/s, m | 1-sigma: attitude E,N,U; velocity E,N,U; position N,E,U",
    "mode" / Int16ul * " |  | NavMode bits; bits 8-11 filter variant",
    "gnss_status" / Int8ul * (" |  | bits 0-6: fix quality of the last GNSS fix (GGA codes); bit 7: the innovation "
                              "gate refused rows of it"),
    "psns_status" / Int8ul * " |  | 0 none, 1 solar vector used, 2 rejected",
    "cpu_load" / Int16ul * "0.01 | % | worst tick of the last second",
    "deadline_misses" / Int32ul * "1 |  | cumulative",
)

#: The frame's CRC-covered header (msg_id, length) and its CRC.
_HEAD = StructCodec(subspec(HOST_FRAME_SPEC, "msg_id", "length"), "HOST_HEADER")
_CRC = StructCodec(subspec(HOST_FRAME_SPEC, "crc", "crc"), "HOST_CRC")
_NAV = StructCodec(NAV_SOLUTION_SPEC, "NAV_SOLUTION")
NAV_SOLUTION_LEN = _NAV.size  # 102

#: First byte of the optional VARIANT block appended to NAV_SOLUTION by the filter variants.
NAV_VARIANT_BLOCK_ID = 0x56
NAV_VARIANT_BLOCK_SPEC = Struct(
    "block_id" / Const(bytes((NAV_VARIANT_BLOCK_ID,))) * " |  | 0x56 ('V'): VARIANT block",
    "block_len" / Int8ul * "1 | bytes | 4 (bytes after this field)",
    "variant_mode" / Int8ul * " |  | variant-specific mode (VARIANT_MODE_MEANING)",
    "psns_units" / Int8ul * "1 |  | polarization sensors judged (l)",
    "psns_q_mask" / Int16ul * " |  | bit i = q_i: sensor i judged reliable",
)
_VARIANT_BLOCK = StructCodec(NAV_VARIANT_BLOCK_SPEC, "NAV_VARIANT_BLOCK")
#: ``variant_mode`` per :class:`FilterVariant` (NAV_SOLUTION VARIANT block and STATUS).
VARIANT_MODE_MEANING = {
    "DUAL_VECTOR": "0 no polarization update, 1 polarization-error-vector (one reliable sensor), "
                   "2 sun-error-vector (two or more)",
    "KMEANS_3D": "0 no attitude fix yet, 1 attitude fix used, 2 refused (sun outside the field of view, "
                 "no low-DOP cluster)",
    "FEDERATED": "bit 0 SINS/GNSS sub-filter fused, bit 1 MIMU/polarization sub-filter fused (2: GNSS isolated)",
    "SUN_ELEVATION": "0 no update, 1 sun-elevation update used, 2 rejected",
}


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class NavSolution:
    """Decoded NAV_SOLUTION (see module docstring for units)."""

    seq: int
    time_s: float
    lat_deg: float
    lon_deg: float
    height_m: float
    vel_enu_mps: tuple[float, float, float]
    roll_deg: float
    pitch_deg: float
    heading_deg: float
    sigma: tuple[float, ...]
    mode: int
    gnss_status: int
    psns_status: int
    cpu_load_pct: float
    deadline_misses: int
    #: VARIANT block (None: absent, the base variant's 102-byte frame); see the module docstring.
    variant_mode: int | None = None
    psns_units: int = 0
    psns_q_mask: int = 0


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class HostFrame:
    """A checked host frame whose message id has no typed decoder here."""

    msg_id: int
    payload: bytes


def _cpu_load_pct(raw: int) -> float:
    """``cpu_load`` on the wire (0.01 %) -> percent."""
    return raw / 100.0


def _pct(v: float) -> int:
    """Percent -> 0.01 % units, clamped to u16."""
    return max(0, min(0xFFFF, round(v * 100)))


_pack_head = _HEAD.packer
_pack_crc = _CRC.packer
_pack_crc16 = _CRC.struct.pack  # one u16: the derived format, called directly on the hot path
_NAV_RENAME = {"cpu_load": "cpu_load_pct"}
#: The CRC-covered body of a NAV_SOLUTION frame without VARIANT block (header and payload in one pack),
#: from the NavSolution fields as arguments: the firmware's 100 Hz output path builds no object.
_pack_nav_body = StructCodec(Struct(*_HEAD.spec.subcons, *NAV_SOLUTION_SPEC.subcons), "NAV_SOLUTION_BODY").encoder(
    NavSolution, rename=_NAV_RENAME, fixed={"msg_id": MSG_NAV_SOLUTION, "length": NAV_SOLUTION_LEN}, from_args=True)
_pack_nav = _NAV.encoder(NavSolution, rename=_NAV_RENAME, from_args=True)
_pack_variant_block = _VARIANT_BLOCK.packer
_decode_nav_fields = _NAV.decoder(NavSolution, rename=_NAV_RENAME, convert={"cpu_load": _cpu_load_pct})
_decode_variant_block = _VARIANT_BLOCK.decode_fast


def build_host_frame(msg_id: int, payload: bytes) -> bytes:
    """Frame ``payload`` as host message ``msg_id`` (sync, id, length, payload, CRC)."""
    if len(payload) > HOST_MAX_PAYLOAD:
        raise ValueError(f"host payload of {len(payload)} bytes exceeds {HOST_MAX_PAYLOAD}")
    body = _pack_head(msg_id=msg_id, length=len(payload)) + payload
    return HOST_SYNC + body + _pack_crc(crc=crc16_ccitt(body))


def encode_nav_solution(n: NavSolution) -> bytes:
    """Whole NAV_SOLUTION frame for ``n``."""
    return nav_solution_frame(n.seq, n.time_s, n.lat_deg, n.lon_deg, n.height_m, n.vel_enu_mps, n.roll_deg,
                              n.pitch_deg, n.heading_deg, n.sigma, n.mode, n.gnss_status, n.psns_status,
                              n.cpu_load_pct, n.deadline_misses, n.variant_mode, n.psns_units, n.psns_q_mask)


def nav_solution_frame(seq: int, time_s: float, lat_deg: float, lon_deg: float, height_m: float,
                       vel_enu_mps: tuple[float, float, float], roll_deg: float, pitch_deg: float,
                       heading_deg: float, sigma: tuple[float, ...], mode: int, gnss_status: int, psns_status: int,
                       cpu_load_pct: float, deadline_misses: int, variant_mode: int | None = None,
                       psns_units: int = 0, psns_q_mask: int = 0) -> bytes:
    """Whole NAV_SOLUTION frame from its fields (the :class:`NavSolution` fields, in order), without building a
    :class:`NavSolution` first: the firmware's 100 Hz output path. :func:`encode_nav_solution` calls it."""
    load = round(cpu_load_pct * 100)  # 0.01 % units, clamped to u16
    load = 0 if load < 0 else 0xFFFF if load > 0xFFFF else load
    # the wire wraps the counters and mode bytes (the same argument list twice: _pack_nav_body, _pack_nav)
    seq &= 0xFFFFFFFF
    mode &= 0xFFFF
    gnss_status &= 0xFF
    psns_status &= 0xFF
    deadline_misses &= 0xFFFFFFFF
    if variant_mode is None:  # the base variant's 102-byte frame: header and payload in one pack
        body = _pack_nav_body(seq, time_s, lat_deg, lon_deg, height_m, vel_enu_mps, roll_deg, pitch_deg, heading_deg,
                              sigma, mode, gnss_status, psns_status, load, deadline_misses)
        return HOST_SYNC + body + _pack_crc16(_crc_hqx(body, 0xFFFF))
    payload = _pack_nav(seq, time_s, lat_deg, lon_deg, height_m, vel_enu_mps, roll_deg, pitch_deg, heading_deg,
                        sigma, mode, gnss_status, psns_status, load, deadline_misses) + _pack_variant_block(
        block_len=4, variant_mode=variant_mode & 0xFF, psns_units=psns_units & 0xFF, psns_q_mask=psns_q_mask & 0xFFFF)
    return build_host_frame(MSG_NAV_SOLUTION, payload)


def _decode_nav(payload: bytes) -> NavSolution:
    if len(payload) < NAV_SOLUTION_LEN:
        raise ValueError(f"NAV_SOLUTION payload must be at least {NAV_SOLUTION_LEN} bytes, got {len(payload)}")
    if (len(payload) >= NAV_SOLUTION_LEN + _VARIANT_BLOCK.size and payload[NAV_SOLUTION_LEN] == NAV_VARIANT_BLOCK_ID
            and payload[NAV_SOLUTION_LEN + 1] == 4):
        blk = _decode_variant_block(payload, NAV_SOLUTION_LEN)
        nav: NavSolution = _decode_nav_fields(payload, 0, blk["variant_mode"], blk["psns_units"], blk["psns_q_mask"])
        return nav
    base: NavSolution = _decode_nav_fields(payload)
    return base


# -- STATUS, ACK, commands -------------------------------------------------------------------

STATUS_SPEC = Struct(
    "seq" / Int32ul * "1 |  | status counter",
    "time_s" / Float64l * "1 | s | FPGA time",
    "filter_variant" / Int8ul * " |  | FilterVariant",
    "variant_mode" / Int8ul * " |  | as in the NAV_SOLUTION VARIANT block, 0 for the base variant",
    "mode" / Int16ul * " |  | NavMode bits",
    "output_rate_hz" / Float32l * "1 | Hz | NAV_SOLUTION rate in force",
    "gnss_status" / Int8ul * " |  | as in NAV_SOLUTION",
    "psns_status" / Int8ul * " |  | as in NAV_SOLUTION",
    "cpu_load" / Int16ul * "0.01 | % | worst tick of the last second",
    "cpu_load_max" / Int16ul * "0.01 | % | worst tick since start",
    "fw_version" / Int16ul * " |  | major << 8 | minor",
    "deadline_misses" / Int32ul * "1 |  | cumulative",
    "uart1_frames" / Int32ul * "1 |  | IMU/MAG frames decoded",
    "uart1_errors" / Int32ul * "1 |  | checksum + length + parse errors",
    "uart2_frames" / Int32ul * "1 |  | PSNS frames decoded",
    "uart2_errors" / Int32ul * "1 |  | checksum + length + parse errors",
    "uart3_frames" / Int32ul * "1 |  | GNSS frames decoded",
    "uart3_errors" / Int32ul * "1 |  | checksum + length + parse errors",
    "commands_accepted" / Int32ul * "1 |  | cumulative",
    "commands_rejected" / Int32ul * "1 |  | cumulative",
)
ACK_SPEC = Struct(
    "command_id" / Int8ul * " |  | id of the acknowledged command",
    "token" / Int8ul * " |  | echo of the command's token",
    "result" / Int8ul * " |  | AckResult",
)

_STATUS = StructCodec(STATUS_SPEC, "STATUS")
#: The u32 counters of STATUS (they wrap on the wire).
_STATUS_COUNTERS = ("deadline_misses", "uart1_frames", "uart1_errors", "uart2_frames", "uart2_errors",
                    "uart3_frames", "uart3_errors", "commands_accepted", "commands_rejected")
STATUS_LEN = _STATUS.size  # 64
_ACK = StructCodec(ACK_SPEC, "ACK")


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class HostStatus:
    """Decoded STATUS (see module docstring for units)."""

    seq: int
    time_s: float
    filter_variant: int
    mode: int
    output_rate_hz: float
    gnss_status: int
    psns_status: int
    cpu_load_pct: float
    cpu_load_max_pct: float
    fw_version: int
    deadline_misses: int
    uart1_frames: int
    uart1_errors: int
    uart2_frames: int
    uart2_errors: int
    uart3_frames: int
    uart3_errors: int
    commands_accepted: int
    commands_rejected: int
    variant_mode: int = 0


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class Ack:
    """ACK of one command: the command's id, its token and an :class:`AckResult`."""

    command_id: int
    token: int
    result: int



#: Wrap an integer to its wire width, as the encoders do for counters and ids.
_u8, _u16, _u32 = (0xFF).__and__, (0xFFFF).__and__, (0xFFFFFFFF).__and__

_PCT = {"cpu_load": "cpu_load_pct", "cpu_load_max": "cpu_load_max_pct"}
_decode_status_fields = _STATUS.decoder(HostStatus, rename=_PCT,
                                        convert={"cpu_load": _cpu_load_pct, "cpu_load_max": _cpu_load_pct})
_encode_status_payload = _STATUS.encoder(HostStatus, rename=_PCT, convert={
    "seq": _u32, "filter_variant": _u8, "variant_mode": _u8, "mode": _u16, "gnss_status": _u8, "psns_status": _u8,
    "cpu_load": _pct, "cpu_load_max": _pct, "fw_version": _u16,
    **{f: _u32 for f in _STATUS_COUNTERS},
})
_decode_ack = _ACK.decoder(Ack)
_encode_ack_payload = _ACK.encoder(Ack, convert=dict.fromkeys(_ACK.names, _u8))


def encode_status(st: HostStatus) -> bytes:
    """Whole STATUS frame for ``st`` (counters wrap to their wire width, loads clamp)."""
    return build_host_frame(MSG_STATUS, _encode_status_payload(st))


def _decode_status(payload: bytes) -> HostStatus:
    if len(payload) < STATUS_LEN:
        raise ValueError(f"STATUS payload must be at least {STATUS_LEN} bytes, got {len(payload)}")
    st: HostStatus = _decode_status_fields(payload)
    return st


def encode_command(c: HostCommand) -> bytes:
    """Whole command frame (host -> DSP) for one of the command dataclasses."""
    return build_host_frame(*command_payload(c))


def encode_ack(a: Ack) -> bytes:
    """Whole ACK frame."""
    return build_host_frame(MSG_ACK, _encode_ack_payload(a))




#: message id -> smallest payload length (NAV_SOLUTION and STATUS may grow by appending)
_MIN_LEN = {MSG_NAV_SOLUTION: NAV_SOLUTION_LEN, MSG_STATUS: STATUS_LEN, MSG_ACK: _ACK.size, **COMMAND_PAYLOAD_LEN}
_EXACT = {MSG_ACK, *COMMAND_PAYLOAD_LEN}




def encode_host(obj: NavSolution | HostStatus | Ack | HostCommand | HostFrame) -> bytes:
    """Encode any object :class:`HostFormat` decodes (the inverse of its ``parse``)."""
    if isinstance(obj, NavSolution):
        return encode_nav_solution(obj)
    if isinstance(obj, HostStatus):
        return encode_status(obj)
    if isinstance(obj, Ack):
        return encode_ack(obj)
    if isinstance(obj, HostFrame):
        return build_host_frame(obj.msg_id, obj.payload)
    return encode_command(obj)


class HostFormat:
    """:class:`~protocols.stream.FrameFormat` of host-port frames (both directions).

    Typed results: :class:`NavSolution`, :class:`HostStatus`, :class:`Ack` and the command
    dataclasses; a checked frame with another id comes out as :class:`HostFrame`. A header
    whose length is too short for its (known) id is refused at once.
    """

    name = "host"
    sync = HOST_SYNC

    @staticmethod
    def encode(obj: Any) -> bytes:
        """Encode a decoded object back to its frame (:func:`encode_host`)."""
        return encode_host(obj)

    def frame_length(self, buf: bytes | bytearray, start: int) -> int:
        if len(buf) - start < 5:
            return NEED_MORE
        n = buf[start + 3] | (buf[start + 4] << 8)
        msg_id = buf[start + 2]
        want = _MIN_LEN.get(msg_id)
        if n > HOST_MAX_PAYLOAD or (want is not None and (n < want or (n != want and msg_id in _EXACT))):
            return BAD_LENGTH
        return 7 + n

    def check(self, frame: bytes) -> bool:
        return crc16_ccitt(frame[2:-2]) == (frame[-2] | (frame[-1] << 8))

    def parse(self, frame: bytes) -> NavSolution | HostStatus | Ack | HostCommand | HostFrame:
        msg_id = frame[2]
        payload = frame[5:-2]
        if msg_id == MSG_NAV_SOLUTION:
            return _decode_nav(payload)
        if msg_id == MSG_STATUS:
            return _decode_status(payload)
        if msg_id == MSG_ACK:
            ack: Ack = _decode_ack(payload)
            return ack
        if msg_id in COMMAND_PAYLOAD_LEN:
            return decode_command_payload(msg_id, payload)
        return HostFrame(msg_id, bytes(payload))
