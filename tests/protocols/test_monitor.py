"""FPGA monitor multiplex: COBS framing with CRC, joinable mid-stream."""

import random

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from protocols.monitor import (
    MONITOR_CHANNELS,
    MONITOR_MAX_DATA,
    MONITOR_RECORD_SPEC,
    MonitorFormat,
    MonitorRecord,
    cobs_decode,
    cobs_encode,
    encode_monitor,
    monitor_frame_len,
)
from protocols.stream import StreamDecoder, parse_one


@settings(max_examples=200, deadline=None, derandomize=True)
@given(st.binary(max_size=1200))
def test_cobs_round_trip_and_no_zero(data):
    enc = cobs_encode(data)
    assert 0 not in enc and cobs_decode(enc) == data
    assert len(enc) <= len(data) + len(data) // 254 + 1


def test_cobs_known_examples():
    # Cheshire & Baker examples (and the Wikipedia table): 00 -> 01 01; 11 22 00 33 -> 03 11 22 02 33
    assert cobs_encode(b"\x00") == b"\x01\x01"
    assert cobs_encode(b"\x11\x22\x00\x33") == b"\x03\x11\x22\x02\x33"
    assert cobs_encode(b"\x11\x00\x00\x00") == b"\x02\x11\x01\x01\x01"
    assert cobs_encode(bytes(range(1, 255)))[:1] == b"\xff"
    with pytest.raises(ValueError):
        cobs_decode(b"\x05\x11")


def test_record_layout_matches_spec():
    r = MonitorRecord(MONITOR_CHANNELS["psns"], 1, 123456789, b"\x00\x01\x02")
    raw = encode_monitor(r)
    assert raw[0] == 0 and 0 not in raw[1:]
    body = cobs_decode(raw[1:])
    c = MONITOR_RECORD_SPEC.parse(body)
    assert (c.channel, c.direction, c.t_us, c.length, c.data) == (2, 1, 123456789, 3, b"\x00\x01\x02")
    assert parse_one(MonitorFormat(), raw) == r
    assert len(raw) <= monitor_frame_len(3)


def test_join_mid_stream_at_every_offset():
    rng = random.Random(5)
    recs = [MonitorRecord(rng.choice(list(MONITOR_CHANNELS.values())), rng.randrange(2), rng.randrange(2**32),
                          bytes(rng.randrange(256) for _ in range(rng.randrange(0, 60)))) for _ in range(6)]
    frames = [encode_monitor(r) for r in recs]
    stream = b"".join(frames)
    starts = [sum(len(f) for f in frames[:i]) for i in range(len(frames))]
    for off in range(len(stream)):
        dec = StreamDecoder([MonitorFormat()])
        out = dec.feed(stream[off:])
        # the record we landed in is lost (no 0x00 inside COBS data, so nothing of it can pass
        # for a record); every record that starts at or after the join comes out, nothing is miscounted
        first_whole = next((i for i, s in enumerate(starts) if s >= off), len(recs))
        assert out == recs[first_whole:], off
        assert dec.stats.crc_errors == 0 and dec.stats.length_errors == 0


def test_large_record_and_limit():
    r = MonitorRecord(0, 0, 0, bytes(range(256)) * 4)
    assert len(r.data) == MONITOR_MAX_DATA
    assert parse_one(MonitorFormat(), encode_monitor(r)) == r
    with pytest.raises(ValueError, match="split"):
        encode_monitor(MonitorRecord(0, 0, 0, bytes(MONITOR_MAX_DATA + 1)))


def test_record_is_complete_without_the_next_delimiter():
    rec = MonitorRecord(4, 1, 99, b"\x00" * 300 + b"\x01" * 300)
    dec = StreamDecoder([MonitorFormat()])
    assert dec.feed(encode_monitor(rec)) == [rec] and dec.pending() == 0
    assert dec.feed(b"\x00\x00\x00") == [] and dec.stats.garbage_bytes == 0  # idle delimiters


def test_lost_closing_delimiter_costs_only_the_cut_record():
    a, b = (encode_monitor(MonitorRecord(1, 0, t, bytes(range(1, 40)))) for t in (1, 2))
    dec = StreamDecoder([MonitorFormat()])
    out = dec.feed(a[:-5] + b + b)
    assert out == [MonitorRecord(1, 0, 2, bytes(range(1, 40)))] * 2
    assert dec.stats.length_errors == 1 and dec.stats.garbage_bytes == len(a) - 5


def test_time_stamp_wraps_like_the_fpga_counter():
    r = parse_one(MonitorFormat(), encode_monitor(MonitorRecord(1, 0, 2**32 + 5, b"x")))
    assert r.t_us == 5
