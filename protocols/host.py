"""Host port (DSP UART0 through the FPGA HOST RS422 port): navigation output and commands.

Every host frame (little-endian)::

    off  size  field
    0    2     sync 0xA5 0x5A
    2    1     msg_id
    3    2     payload length N, u16
    5    N     payload
    5+N  2     CRC-16/CCITT-FALSE over bytes 2 .. 4+N (msg_id, length, payload)

Messages:

``0x01`` NAV_SOLUTION (DSP -> host, at the configured output rate, default 100 Hz), payload::

    off  type     field               unit
    0    u32      seq
    4    f64      time_s              s, FPGA time of validity (IMU trigger time)
    12   f64      lat_deg             deg, WGS-84
    20   f64      lon_deg             deg
    28   f32      height_m            m, ellipsoidal
    32   3 x f32  vel_enu_mps         m/s, East, North, Up
    44   3 x f32  roll, pitch, heading  deg (heading clockwise from true north, [0, 360))
    56   9 x f32  sigma               1-sigma: attitude E,N,U (deg), velocity E,N,U (m/s),
                                      position N,E,U (m)
    92   u16      mode                :class:`NavMode` bits; bits 8-11 filter variant
    94   u8       gnss_status         fix quality of the last GNSS fix used (NMEA GGA codes)
    95   u8       psns_status         0 none, 1 valid solar vector used, 2 rejected
    96   u16      cpu_load            0.01 % of the tick budget (worst of the last second)
    98   u32      deadline_misses     cumulative
    (102 bytes)
"""

from __future__ import annotations

import enum
import struct
from dataclasses import dataclass

from construct import Array, Float32l, Float64l, Int8ul, Int16ul, Int32ul, Struct

from .crc import crc16_ccitt
from .stream import BAD_LENGTH, NEED_MORE

__all__ = [
    "HOST_SYNC",
    "MSG_NAV_SOLUTION",
    "NavMode",
    "NavSolution",
    "NAV_SOLUTION_SPEC",
    "HostFrame",
    "HostFormat",
    "build_host_frame",
    "encode_nav_solution",
]

HOST_SYNC = b"\xa5\x5a"
MSG_NAV_SOLUTION = 0x01
HOST_MAX_PAYLOAD = 1024


class NavMode(enum.IntFlag):
    """``mode`` bits of NAV_SOLUTION."""

    ALIGNING = 0x0001  #: coarse alignment in progress, solution not valid
    NAVIGATING = 0x0002  #: strapdown running
    GNSS_AIDED = 0x0004  #: a GNSS update was applied within the last 2 s
    PSNS_AIDED = 0x0008  #: a solar-vector update was applied within the last 2 s
    DEGRADED = 0x0010  #: inputs missing or rejected (see status bytes)


NAV_SOLUTION_SPEC = Struct(
    "seq" / Int32ul,
    "time_s" / Float64l,
    "lat_deg" / Float64l,
    "lon_deg" / Float64l,
    "height_m" / Float32l,
    "vel_enu_mps" / Array(3, Float32l),
    "roll_deg" / Float32l,
    "pitch_deg" / Float32l,
    "heading_deg" / Float32l,
    "sigma" / Array(9, Float32l),
    "mode" / Int16ul,
    "gnss_status" / Int8ul,
    "psns_status" / Int8ul,
    "cpu_load" / Int16ul,
    "deadline_misses" / Int32ul,
)

_NAV = struct.Struct("<Idddf3f3f9fHBBHI")
NAV_SOLUTION_LEN = _NAV.size  # 102


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


@dataclass(frozen=True, slots=True)
class HostFrame:
    """A checked host frame whose message id has no typed decoder here."""

    msg_id: int
    payload: bytes


def build_host_frame(msg_id: int, payload: bytes) -> bytes:
    """Frame ``payload`` as host message ``msg_id`` (sync, id, length, payload, CRC)."""
    if len(payload) > HOST_MAX_PAYLOAD:
        raise ValueError(f"host payload of {len(payload)} bytes exceeds {HOST_MAX_PAYLOAD}")
    body = struct.pack("<BH", msg_id, len(payload)) + payload
    return HOST_SYNC + body + struct.pack("<H", crc16_ccitt(body))


def encode_nav_solution(n: NavSolution) -> bytes:
    """Whole NAV_SOLUTION frame for ``n``."""
    payload = _NAV.pack(
        n.seq & 0xFFFFFFFF,
        n.time_s,
        n.lat_deg,
        n.lon_deg,
        n.height_m,
        *n.vel_enu_mps,
        n.roll_deg,
        n.pitch_deg,
        n.heading_deg,
        *n.sigma,
        n.mode & 0xFFFF,
        n.gnss_status & 0xFF,
        n.psns_status & 0xFF,
        max(0, min(0xFFFF, int(round(n.cpu_load_pct * 100)))),
        n.deadline_misses & 0xFFFFFFFF,
    )
    return build_host_frame(MSG_NAV_SOLUTION, payload)


def _decode_nav(payload: bytes) -> NavSolution:
    if len(payload) != NAV_SOLUTION_LEN:
        raise ValueError(f"NAV_SOLUTION payload must be {NAV_SOLUTION_LEN} bytes, got {len(payload)}")
    v = _NAV.unpack(payload)
    return NavSolution(
        seq=v[0],
        time_s=v[1],
        lat_deg=v[2],
        lon_deg=v[3],
        height_m=v[4],
        vel_enu_mps=(v[5], v[6], v[7]),
        roll_deg=v[8],
        pitch_deg=v[9],
        heading_deg=v[10],
        sigma=tuple(v[11:20]),
        mode=v[20],
        gnss_status=v[21],
        psns_status=v[22],
        cpu_load_pct=v[23] / 100.0,
        deadline_misses=v[24],
    )


class HostFormat:
    """:class:`~protocols.stream.FrameFormat` of host-port frames (both directions)."""

    name = "host"
    sync = HOST_SYNC

    def frame_length(self, buf: bytearray, start: int) -> int:
        if len(buf) - start < 5:
            return NEED_MORE
        n = buf[start + 3] | (buf[start + 4] << 8)
        if n > HOST_MAX_PAYLOAD:
            return BAD_LENGTH
        return 7 + n

    def check(self, frame: bytes) -> bool:
        return crc16_ccitt(frame[2:-2]) == (frame[-2] | (frame[-1] << 8))

    def parse(self, frame: bytes) -> NavSolution | HostFrame:
        msg_id = frame[2]
        payload = frame[5:-2]
        if msg_id == MSG_NAV_SOLUTION:
            return _decode_nav(payload)
        return HostFrame(msg_id, bytes(payload))

