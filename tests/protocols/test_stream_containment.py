"""No exception from input escapes :class:`StreamDecoder` (issue 41 item 1, docs/hostile-input.md section 1).

A format whose ``frame_length``, ``check`` or ``parse`` raises anything (here: the ``OverflowError`` NMEA times once
raised, a ``RecursionError``, a ``ZeroDivisionError``) is contained by every scanner (the reference scanner with
several formats, the one-format scanner and the whole-frame fast path): the candidate is counted as the failure of
its step and in ``format_faults``, the scan advances past it, the next good frame comes out and nothing stays
buffered, whatever the chunking."""

from __future__ import annotations

import pytest

from protocols.crc import crc16_ccitt
from protocols.nmea import NmeaFormat
from protocols.stream import NEED_MORE, StreamDecoder


class _Raising:
    """A TLV format (0xC3 0x3C, length, payload, CRC-16) whose steps raise on chosen payloads."""

    name = "tlv"
    sync = b"\xc3\x3c"

    def __init__(self, exc: type[BaseException]) -> None:
        self.exc = exc

    def frame_length(self, buf, start):
        if len(buf) - start < 4:
            return NEED_MORE
        if buf[start + 3] == ord("L"):  # the length step raises
            raise self.exc("frame_length")
        return 5 + buf[start + 2]

    def check(self, frame):
        if frame[3:4] == b"C":
            raise self.exc("check")
        return crc16_ccitt(frame[:-2]) == int.from_bytes(frame[-2:], "little")

    def parse(self, frame):
        p = bytes(frame[3:-2])
        if p.startswith(b"P"):
            raise self.exc("parse")
        return p


def _tlv(payload: bytes) -> bytes:
    body = b"\xc3\x3c" + bytes((len(payload),)) + payload
    return body + crc16_ccitt(body).to_bytes(2, "little")


class _Other:
    name = "other"
    sync = b"\x7e\x7e"

    def frame_length(self, buf, start):
        return NEED_MORE

    def check(self, frame):
        return False

    def parse(self, frame):
        return None


@pytest.mark.parametrize("exc", [OverflowError, RecursionError, ZeroDivisionError, ValueError])
@pytest.mark.parametrize("how", ["fast", "one-format scan", "reference scan"])
@pytest.mark.parametrize("chunk", [0, 1, 3])
def test_every_step_of_a_format_is_contained(exc: type[Exception], how: str, chunk: int) -> None:
    fmt = _Raising(exc)
    formats = [fmt, _Other()] if how == "reference scan" else [fmt]
    dec = StreamDecoder(formats, fast_paths=how != "reference scan")  # type: ignore[list-item]
    good = _tlv(b"good")
    hostile = [_tlv(b"Lx"), _tlv(b"Cx"), _tlv(b"Px")]
    out: list[object] = []
    for _round in range(3):  # the same hostile frames again: the decoder must not be stuck on them
        for h in hostile:
            data = h + good
            if how == "fast":
                out += dec.feed(h)  # a whole frame per chunk: the fast path of feed()
                out += dec.feed(good)
            elif chunk:
                for i in range(0, len(data), chunk):
                    out += dec.feed(memoryview(data)[i : i + chunk])
            else:
                out += dec.feed(bytearray(data))
    assert out == [b"good"] * 9
    assert dec.pending() == 0
    st = dec.stats
    assert st.frames == 9
    assert st.parse_errors == 3  # the parse step: 'P'
    assert st.crc_errors == 3  # the check step: 'C'
    assert st.length_errors >= 3  # the length step: 'L' (and resyncs inside the refused candidates)
    # an exception of frame_length or check is always a fault; of parse, a fault unless it is a refusal (ValueError)
    assert st.format_faults == (6 if exc is ValueError else 9), st


def test_a_time_field_that_overflowed_is_a_parse_error() -> None:
    """The case of issue 41: ``hhmminf`` raised OverflowError out of feed() and the decoder stayed on it."""
    from protocols.crc import nmea_checksum

    def s(body: str) -> bytes:
        return f"${body}*{nmea_checksum(body.encode()):02X}\r\n".encode()

    bad = s("GPGGA,1235inf,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,")
    good = s("GPGGA,123519.00,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,")
    dec = StreamDecoder([NmeaFormat()])
    for _ in range(1000):
        assert len(dec.feed(bad + good)) == 1
    assert dec.pending() == 0
    assert dec.stats.parse_errors == 1000 and dec.stats.frames == 1000 and dec.stats.format_faults == 0
