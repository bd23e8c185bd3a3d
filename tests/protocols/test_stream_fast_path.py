"""The StreamDecoder's one-whole-frame fast path counts and returns exactly what the scanner does.

A chunk that is exactly one frame (bytes, nothing buffered) is decoded without the buffer; everything else goes
through the scanner. Feeding the same chunks as memoryviews forces the scanner, so the two runs must agree on
every frame and every counter, including a CRC error, a parse error, garbage, split frames and back-to-back
frames in one chunk."""

from __future__ import annotations

import numpy as np

from protocols.crc import crc16_ccitt
from protocols.imu_frame import FpgaFrameFormat, ImuFrame, ImuFrameFormat
from protocols.stream import BAD_LENGTH, NEED_MORE, StreamDecoder


class _Tlv:
    """A tiny format for the test: 0xC3 0x3C, length byte, payload, CRC-16; payload 'bad' fails to parse."""

    name = "tlv"
    sync = b"\xc3\x3c"

    def frame_length(self, buf, start):
        if len(buf) - start < 3:
            return NEED_MORE
        n = buf[start + 2]
        return 5 + n if n <= 32 else BAD_LENGTH

    def check(self, frame):
        return crc16_ccitt(frame[:-2]) == int.from_bytes(frame[-2:], "little")

    def parse(self, frame):
        p = bytes(frame[3:-2])
        if p == b"bad":
            raise ValueError("bad payload")
        return p


def _tlv(payload: bytes) -> bytes:
    body = b"\xc3\x3c" + bytes((len(payload),)) + payload
    return body + crc16_ccitt(body).to_bytes(2, "little")


def _run(fmt, chunks, as_view: bool):
    d = StreamDecoder([fmt])
    out = []
    for c in chunks:
        out += d.feed(memoryview(c) if as_view else c)
    return out, d.stats.as_dict()


def test_fast_path_counts_like_the_scanner():
    good = _tlv(b"hello")
    bad_crc = good[:-1] + bytes((good[-1] ^ 0xFF,))
    chunks = [good, good, bad_crc, good, _tlv(b"bad"), b"\x00\x01garbage", good, good[:4], good[4:], good + good,
              _tlv(b""), _tlv(b"x" * 32), good]
    fast, fast_stats = _run(_Tlv(), chunks, as_view=False)
    slow, slow_stats = _run(_Tlv(), chunks, as_view=True)
    assert fast == slow and fast_stats == slow_stats
    assert fast_stats["crc_errors"] == 1 and fast_stats["parse_errors"] == 1 and fast_stats["resyncs"] >= 2
    assert fast.count(b"hello") == 8


def test_fast_path_on_imu_frames_with_random_corruption():
    rng = np.random.default_rng(5)
    fmt = ImuFrameFormat()
    chunks = []
    for k in range(400):
        f = fmt.build(ImuFrame(k, 5000 * k, 0, 0, tuple(int(x) for x in rng.integers(-2**23, 2**23, 3)), 0, k & 255,
                               500, tuple(int(x) for x in rng.integers(-2**23, 2**23, 3)), 0x10))
        r = rng.random()
        if r < 0.05:  # a flipped bit
            i = int(rng.integers(0, len(f)))
            f = f[:i] + bytes((f[i] ^ (1 << int(rng.integers(0, 8))),)) + f[i + 1:]
        elif r < 0.1:  # split
            i = int(rng.integers(1, len(f)))
            chunks.append(f[:i])
            f = f[i:]
        chunks.append(f)
    fast, fast_stats = _run(FpgaFrameFormat(), chunks, as_view=False)
    slow, slow_stats = _run(FpgaFrameFormat(), chunks, as_view=True)
    assert fast == slow and fast_stats == slow_stats
    assert fast_stats["crc_errors"] + fast_stats["length_errors"] > 0 and len(fast) > 350
