"""FPGA MONITOR port: every channel's bytes, tagged, time-stamped and COBS-framed.

The virtual FPGA mirrors each chunk of bytes that crosses one of its ports onto the MONITOR
port as one record. A record, before framing (little-endian)::

    off  size  field      type  meaning
    0    1     channel    u8    :data:`MONITOR_CHANNELS` (gyro 0, gnss 1, psns 2, host 3, uart0..3 4..7, mag 8)
    1    1     direction  u8    0 = towards the DSP, 1 = away from the DSP
    2    4     t_us       u32   FPGA 1 MHz counter when the chunk's last byte passed, us (wraps after 71.6 min)
    6    2     length     u16   N, bytes of data (at most :data:`MONITOR_MAX_DATA`)
    8    N     data             the bytes as they crossed the port
    8+N  2     crc        u16   CRC-16/CCITT-FALSE over bytes 0 .. 7+N

Framing: the record (with its CRC) is COBS-encoded (Cheshire & Baker, "Consistent Overhead
Byte Stuffing", IEEE/ACM Trans. Networking 7(2), 1999: no 0x00 inside, one code byte per
254 data bytes) and sent between two 0x00 delimiters::

    0x00 | COBS(record + crc) | 0x00

A reader that joins mid-stream drops bytes up to the next 0x00 and is in step from the next
record on; a damaged record costs that record only. Runs of delimiters are allowed
(``00 00`` between two records is what back-to-back :func:`encode_monitor` outputs give).
Overhead per record: 2 delimiters + 1 COBS code byte (+1 per 254 bytes) + 10 header/CRC bytes.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass
from typing import Any

from construct import Bytes, Int8ul, Int16ul, Int32ul, Struct, this

from ._fastinit import fast_frozen_init
from .crc import crc16_ccitt
from .stream import BAD_LENGTH, NEED_MORE

__all__ = [
    "MONITOR_CHANNELS",
    "MONITOR_MAX_DATA",
    "MONITOR_RECORD_SPEC",
    "DIR_TO_DSP",
    "DIR_FROM_DSP",
    "MonitorRecord",
    "MonitorFormat",
    "encode_monitor",
    "cobs_encode",
    "cobs_decode",
    "monitor_frame_len",
]

MONITOR_CHANNELS = {"gyro": 0, "gnss": 1, "psns": 2, "host": 3, "uart0": 4, "uart1": 5, "uart2": 6, "uart3": 7, "mag": 8}
DIR_TO_DSP = 0
DIR_FROM_DSP = 1
#: Largest data chunk in one record; longer chunks are split by the sender.
MONITOR_MAX_DATA = 1024
_HDR = struct.Struct("<BBIH")
_REC_OVERHEAD = _HDR.size + 2  # header + CRC
#: Longest frame on the wire: delimiters + COBS(MONITOR_MAX_DATA + 10).
_MAX_FRAME = 2 + (MONITOR_MAX_DATA + _REC_OVERHEAD) + (MONITOR_MAX_DATA + _REC_OVERHEAD) // 254 + 1

MONITOR_RECORD_SPEC = Struct(
    "channel" / Int8ul * "MONITOR_CHANNELS id",
    "direction" / Int8ul * "0 towards the DSP, 1 away from the DSP",
    "t_us" / Int32ul * "us, FPGA counter at the chunk's last byte",
    "length" / Int16ul * "bytes of data",
    "data" / Bytes(this.length) * "the bytes as they crossed the port",
    "crc" / Int16ul * "CRC-16/CCITT-FALSE over channel..data",
)


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class MonitorRecord:
    """One tapped chunk: channel id, direction (0 to / 1 from the DSP), FPGA time (us), bytes."""

    channel: int
    direction: int
    t_us: int
    data: bytes


def cobs_encode(data: bytes) -> bytes:
    """COBS-encode ``data``: the result holds no 0x00 byte and is at most ``len/254 + 1`` longer."""
    out = bytearray()
    for part in bytes(data).split(b"\x00"):
        # Each zero-free part becomes blocks of <= 254 bytes; a 0xFF code means "254 bytes, no zero".
        while len(part) >= 254:
            out.append(0xFF)
            out += part[:254]
            part = part[254:]
        out.append(len(part) + 1)
        out += part
    return bytes(out)


def cobs_decode(enc: bytes) -> bytes:
    """Inverse of :func:`cobs_encode`. Raises ``ValueError`` on a malformed block."""
    out = bytearray()
    i = 0
    n = len(enc)
    while i < n:
        code = enc[i]
        if code == 0:
            raise ValueError("COBS: zero byte inside a frame")
        j = i + code
        if j > n:
            raise ValueError("COBS: block runs past the end of the frame")
        out += enc[i + 1 : j]
        if code != 0xFF and j < n:
            out.append(0)
        i = j
    return bytes(out)


def monitor_frame_len(n_data: int) -> int:
    """Most wire bytes of one record carrying ``n_data`` bytes (delimiters included).

    Exact when the record holds no 0x00 byte and its length is not a multiple of 254
    (COBS then spends ``len // 254 + 1`` code bytes); a 0x00 in the record costs nothing extra.
    """
    n = n_data + _REC_OVERHEAD
    return 2 + n + n // 254 + 1


def encode_monitor(rec: MonitorRecord) -> bytes:
    """The framed record: ``00 | COBS(record + CRC) | 00``. ``t_us`` wraps at 2^32 like the FPGA counter."""
    if len(rec.data) > MONITOR_MAX_DATA:
        raise ValueError(f"monitor record of {len(rec.data)} bytes exceeds {MONITOR_MAX_DATA}; split it")
    body = _HDR.pack(rec.channel & 0xFF, rec.direction & 0xFF, rec.t_us & 0xFFFFFFFF, len(rec.data)) + bytes(rec.data)
    body += crc16_ccitt(body).to_bytes(2, "little")
    return b"\x00" + cobs_encode(body) + b"\x00"


class MonitorFormat:
    """:class:`~protocols.stream.FrameFormat` of the MONITOR port (yields :class:`MonitorRecord`).

    A candidate starts at a 0x00, takes any further 0x00 of the same run, and ends with the
    next 0x00 after some non-zero bytes. The check decodes the COBS block and verifies the
    length field and the CRC.
    """

    name = "monitor"
    sync = b"\x00"

    @staticmethod
    def encode(obj: Any) -> bytes:
        """Encode a decoded object back to its frame (:func:`encode_monitor`)."""
        return encode_monitor(obj)

    def frame_length(self, buf: bytearray, start: int) -> int:
        i = start + 1
        n = len(buf)
        while i < n and buf[i] == 0:
            i += 1
        if i >= n:
            return NEED_MORE
        end = buf.find(b"\x00", i, i + _MAX_FRAME)
        if end < 0:
            return NEED_MORE if n - i < _MAX_FRAME else BAD_LENGTH
        return end + 1 - start

    def check(self, frame: bytes) -> bool:
        try:
            body = cobs_decode(frame.lstrip(b"\x00")[:-1])
        except ValueError:
            return False
        if len(body) < _REC_OVERHEAD or len(body) != _REC_OVERHEAD + (body[6] | (body[7] << 8)):
            return False
        return crc16_ccitt(body[:-2]) == (body[-2] | (body[-1] << 8))

    def parse(self, frame: bytes) -> MonitorRecord:
        body = cobs_decode(frame.lstrip(b"\x00")[:-1])
        ch, d, t, _ = _HDR.unpack_from(body, 0)
        return MonitorRecord(ch, d, t, body[_HDR.size : -2])
