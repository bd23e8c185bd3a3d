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
254 data bytes) and preceded by a 0x00 delimiter::

    0x00 | COBS(record + crc)          (back to back: 00 A 00 B 00 C ...)

0x00 only ever appears as a delimiter, so a reader that joins mid-stream drops bytes up to the
next 0x00 and is in step from the next record on. The end of a record follows from its COBS code
bytes and its length field, so it is decoded as soon as its last byte arrives. A damaged record
costs that record only. Runs of delimiters (idle fill) are allowed. Overhead per record:
1 delimiter + 1 COBS code byte (+1 per 254 bytes) + 10 header/CRC bytes.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from construct import Bytes, Int8ul, Int16ul, Int32ul, Struct, this

from ._fastinit import fast_frozen_init
from .codec import StructCodec, subspec
from .crc import crc16_ccitt
from .stream import BAD_LENGTH, NEED_MORE

__all__ = [
    "DIR_FROM_DSP",
    "DIR_TO_DSP",
    "MONITOR_CHANNELS",
    "MONITOR_MAX_DATA",
    "MONITOR_RECORD_SPEC",
    "MonitorFormat",
    "MonitorRecord",
    "cobs_decode",
    "cobs_encode",
    "encode_monitor",
    "monitor_frame_len",
]

MONITOR_CHANNELS = {"gyro": 0, "gnss": 1, "psns": 2, "host": 3, "uart0": 4, "uart1": 5, "uart2": 6, "uart3": 7,
                    "mag": 8}
DIR_TO_DSP = 0
DIR_FROM_DSP = 1
#: Largest data chunk in one record; longer chunks are split by the sender.
MONITOR_MAX_DATA = 1024

# Field docs are "scale | unit | meaning" (read by protocols.icd for docs/icd.md).
MONITOR_RECORD_SPEC = Struct(
    "channel" / Int8ul * " |  | MONITOR_CHANNELS id",
    "direction" / Int8ul * " |  | 0 towards the DSP, 1 away from the DSP",
    "t_us" / Int32ul * "1 | us | FPGA counter when the chunk's last byte passed (wraps)",
    "length" / Int16ul * "1 | bytes | N, bytes of data (<= 1024)",
    "data" / Bytes(this.length) * " |  | the bytes as they crossed the port",
    "crc" / Int16ul * " |  | CRC-16/CCITT-FALSE over channel..data",
)
_HDR = StructCodec(subspec(MONITOR_RECORD_SPEC, "channel", "length"), "MONITOR_HEADER")
_CRC = StructCodec(subspec(MONITOR_RECORD_SPEC, "crc", "crc"), "MONITOR_CRC")
_REC_OVERHEAD = _HDR.size + _CRC.size  # header + CRC


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
    return 1 + n + n // 254 + 1


def encode_monitor(rec: MonitorRecord) -> bytes:
    """The framed record: ``00 | COBS(record + CRC)``. ``t_us`` wraps at 2^32 like the FPGA counter.

    Back-to-back records are ``00 A 00 B 00 C``: each record's opening 0x00 closes the one before.
    A sender going idle may send one more 0x00; a reader does not need it.
    """
    if len(rec.data) > MONITOR_MAX_DATA:
        raise ValueError(f"monitor record of {len(rec.data)} bytes exceeds {MONITOR_MAX_DATA}; split it")
    body = _HDR.packer(channel=rec.channel & 0xFF, direction=rec.direction & 0xFF, t_us=rec.t_us & 0xFFFFFFFF,
                       length=len(rec.data)) + bytes(rec.data)
    body += _CRC.packer(crc=crc16_ccitt(body))
    return b"\x00" + cobs_encode(body)


#: MonitorRecord from the header by field name; ``length`` is implied by ``data`` and the CRC checked before.
_decode_header = _HDR.decoder(MonitorRecord, ignore=("length",))


#: zeros after a candidate's opening 0x00 beyond which the candidate is refused (docs/hostile-input.md)
_ZERO_RUN_MAX = 64
_ZEROS = bytes(_ZERO_RUN_MAX + 1)


class MonitorFormat:
    """:class:`~protocols.stream.FrameFormat` of the MONITOR port (yields :class:`MonitorRecord`).

    A candidate starts at a 0x00 (with any further 0x00 of the same run) and its end follows from
    the COBS code bytes and the record's own length field, so a record is complete as soon as its
    last byte arrives and the 0x00 after it stays in the stream as the next record's opening
    delimiter. A 0x00 met before that end, or a length beyond :data:`MONITOR_MAX_DATA`, refuses the
    candidate at once; the check verifies the CRC.
    """

    name = "monitor"
    sync = b"\x00"

    @staticmethod
    def encode(obj: Any) -> bytes:
        """Encode a :class:`MonitorRecord` (:func:`encode_monitor`)."""
        return encode_monitor(obj)

    def __init__(self) -> None:
        # frame_length decodes the record while it walks the COBS blocks; check and parse reuse
        # that body when they are handed the same encoded bytes (the decoder's call order).
        self._enc = b""
        self._body = b""

    def frame_length(self, buf: bytes | bytearray, start: int) -> int:
        n = len(buf)
        i = start + 1
        if buf[i : i + _ZERO_RUN_MAX + 1] == _ZEROS:
            # a long run of 0x00 (a line held low, BREAK): the candidates inside it are refused at once, so the
            # scan stays linear; the last _ZERO_RUN_MAX zeros of the run still open the next record as idle fill
            return BAD_LENGTH
        while i < n and buf[i] == 0:
            i += 1
        first = i
        z = buf.find(b"\x00", i)  # COBS data holds no 0x00: the record ends before z
        if z < 0:
            z = n
        parts: list[bytes | bytearray] = []
        want = -1  # decoded record length (header + data + CRC) once the header is known
        decoded = 0
        while True:
            if i >= z:
                return NEED_MORE if z == n else BAD_LENGTH
            code = buf[i]
            j = i + code
            if j > z:
                return NEED_MORE if z == n else BAD_LENGTH
            parts.append(buf[i + 1 : j])
            decoded += code - 1
            i = j
            if code != 0xFF:
                if decoded == want:
                    self._enc = bytes(buf[first:i])
                    self._body = b"".join(parts)
                    return i - start
                parts.append(b"\x00")
                decoded += 1  # the zero this block stands for
            if want < 0 and decoded >= 8:
                head = b"".join(parts)
                want = _REC_OVERHEAD + (head[6] | (head[7] << 8))
                if want > _REC_OVERHEAD + MONITOR_MAX_DATA:
                    return BAD_LENGTH
                if decoded == want + 1 and code != 0xFF:  # the record ended with this block
                    parts.pop()
                    self._enc = bytes(buf[first:i])
                    self._body = b"".join(parts)
                    return i - start
            if want >= 0 and decoded > want:
                return BAD_LENGTH

    def _decoded(self, frame: bytes) -> bytes:
        enc = frame.lstrip(b"\x00")
        return self._body if enc == self._enc else cobs_decode(enc)

    def check(self, frame: bytes) -> bool:
        try:
            body = self._decoded(frame)
        except ValueError:
            return False
        if len(body) < _REC_OVERHEAD or len(body) != _REC_OVERHEAD + (body[6] | (body[7] << 8)):
            return False
        return crc16_ccitt(body[:-2]) == (body[-2] | (body[-1] << 8))

    def parse(self, frame: bytes) -> MonitorRecord:
        body = self._decoded(frame)
        rec: MonitorRecord = _decode_header(body, 0, bytes(body[_HDR.size : -2]))
        return rec
