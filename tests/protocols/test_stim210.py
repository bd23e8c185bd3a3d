"""STIM210 datagrams: a hand-derived vector, round trips and the streaming decoder."""

import random

import pytest

from protocols.crc import crc8_stim
from protocols.errors import ChecksumError
from protocols.stim import (
    GYRO_RATE_LSB_DPS,
    STIM210_FORMATS,
    Stim210Format,
    StimDatagram,
    StimStatus,
    overload_status,
)
from protocols.stream import StreamDecoder, parse_one


def hand_built_0xa5() -> bytes:
    """Format 'm' (0xA5) built by hand from the layout table, not by our encoder.

    gyro X = +1.0 deg/s = 16384 LSB = 0x004000, Y = -1 LSB = 0xFFFFFF,
    Z = -400 deg/s = -6553600 LSB = 0x9C0000; status 0; counter 0x0A; latency 516 us = 0x0204.
    """
    body = bytes([0xA5, 0x00, 0x40, 0x00, 0xFF, 0xFF, 0xFF, 0x9C, 0x00, 0x00, 0x00, 0x0A, 0x02, 0x04])
    return body + bytes([crc8_stim(body)])


def test_hand_built_datagram_decodes():
    fmt = Stim210Format("m")
    d = parse_one(fmt, hand_built_0xa5())
    assert d.gyro == (16384, -1, -6553600)
    assert d.gyro[0] * GYRO_RATE_LSB_DPS == 1.0
    assert d.gyro[2] * GYRO_RATE_LSB_DPS == -400.0
    assert (d.status, d.counter, d.latency_us) == (0, 10, 516)


def test_encoder_matches_hand_built():
    fmt = Stim210Format("m")
    d = StimDatagram(0xA5, (16384, -1, -6553600), 0, counter=10, latency_us=516)
    assert fmt.build(d) == hand_built_0xa5()


@pytest.mark.parametrize("letter", sorted(STIM210_FORMATS))
@pytest.mark.parametrize("crlf", [False, True])
def test_every_format_round_trips_and_matches_construct(letter, crlf):
    fmt = Stim210Format(letter, crlf=crlf)
    d = StimDatagram(fmt.ident, (123456, -654321, 7), 0x10, counter=200, latency_us=999,
                     temperature=(25 * 256, -3 * 256, 1), reserved=b"\x01\x02\x03")
    raw = fmt.build(d)
    expected_len = {"s": 12, "e": 15, "j": 18, "k": 13, "l": 14, "m": 15, "n": 19, "o": 20, "p": 21}[letter]
    assert len(raw) == expected_len + (2 if crlf else 0)
    back = parse_one(fmt, raw)
    assert back.gyro == d.gyro and back.status == d.status
    # the declarative construct layout agrees with the fast parser
    c = fmt.spec.parse(raw)
    assert list(c.gyro) == list(d.gyro)
    assert c.crc == raw[fmt.body_len]
    assert fmt.build(back) == raw


def test_bad_crc_is_rejected_strictly():
    raw = bytearray(hand_built_0xa5())
    raw[3] ^= 0x01
    with pytest.raises(ChecksumError):
        parse_one(Stim210Format("m"), bytes(raw))


def test_stream_decoder_resyncs_after_corruption():
    fmt = Stim210Format("m")
    frames = [fmt.build(StimDatagram(0xA5, (i, -i, 2 * i), 0, counter=(10 * i) & 0xFF, latency_us=0))
              for i in range(50)]
    stream = bytearray(b"".join(frames))
    stream[15 * 10 + 5] ^= 0x40  # corrupt frame 10
    dec = StreamDecoder([fmt])
    out = []
    for i in range(0, len(stream), 7):  # odd chunking
        out += dec.feed(bytes(stream[i : i + 7]))
    got = [d.gyro[0] for d in out]
    assert got == [i for i in range(50) if i != 10]
    assert dec.stats.crc_errors >= 1
    assert dec.stats.frames == 49


@pytest.mark.parametrize("letter", sorted(STIM210_FORMATS))
@pytest.mark.parametrize("crlf", [False, True])
def test_build_values_is_construct_s_bytes_of_the_datagram(letter, crlf):
    """``build_values`` (the gyro model's sender: no datagram object) gives ``construct``'s bytes of the datagram
    with those fields, absent optional fields as zeros and STATUS/counter wrapped to their byte, for every
    format; and ``build`` of the object is the same bytes (performance.md 5.7, D-10.E8)."""
    fmt = Stim210Format(letter, crlf=crlf)
    rng = random.Random(f"{letter}{crlf}")
    for _ in range(200):
        gyro = tuple(rng.randint(-2**23, 2**23 - 1) for _ in range(3))
        status = rng.randint(0, 0x1FF)
        counter = rng.choice([None, rng.randint(0, 0x1FF)])
        latency = rng.choice([None, rng.randint(0, 0xFFFF)])
        temp = rng.choice([None, tuple(rng.randint(-2**15, 2**15 - 1) for _ in range(3))])
        reserved = rng.choice([None, bytes(rng.randrange(256) for _ in range(3))])
        raw = fmt.build_values(gyro, status, counter, latency, temp, reserved)
        values = {"gyro": list(gyro), "status": status & 0xFF, "counter": (counter or 0) & 0xFF,
                  "latency_us": latency or 0, "temperature": list(temp or (0, 0, 0)),
                  "reserved": b"\x00\x00\x00" if reserved is None else reserved}
        body = fmt.spec.build({**values, "crc": 0})[:fmt.body_len]
        assert raw == body + bytes((crc8_stim(body),)) + (b"\r\n" if crlf else b"")
        assert fmt.build(StimDatagram(fmt.ident, gyro, status, counter, latency, temp, reserved)) == raw


def _construct_datagram(fmt: Stim210Format, gyro, status, counter, latency, temp, reserved) -> bytes:
    """The reference: ``construct``'s bytes of the datagram's body, its CRC-8 byte by byte, CR LF if configured."""
    values = {"gyro": list(gyro), "status": status & 0xFF, "counter": (counter or 0) & 0xFF,
              "latency_us": latency or 0, "temperature": list(temp or (0, 0, 0)),
              "reserved": b"\x00\x00\x00" if reserved is None else reserved}
    body = fmt.spec.build({**values, "crc": 0})[:fmt.body_len]
    return body + bytes((crc8_stim(body),)) + (b"\r\n" if fmt.crlf else b"")


@pytest.mark.parametrize("letter", sorted(STIM210_FORMATS))
@pytest.mark.parametrize("crlf", [False, True])
@pytest.mark.parametrize("n", [1, 2, 7, 200, 2000])
def test_build_window_is_the_per_sample_datagrams_back_to_back(letter, crlf, n):
    """A window of ``n`` samples (seeded: words at and near the s24 rails, every STATUS overload combination and
    other STATUS bytes, counters past 255, absent groups) encodes to ``construct``'s datagrams of the same
    samples back to back, byte for byte (D-10.E21); ``build_values`` of each sample is its row."""
    fmt = Stim210Format(letter, crlf=crlf)
    rng = random.Random(f"window{letter}{crlf}{n}")
    rails = (-2**23, -2**23 + 1, -1, 0, 1, 2**23 - 2, 2**23 - 1)
    statuses = [overload_status(x, y, z) for x in (False, True) for y in (False, True) for z in (False, True)]
    statuses += [int(StimStatus.STARTUP), 0x1FF, 0x20]
    rows = []
    for _ in range(n):
        gyro = tuple(rng.choice(rails) if rng.random() < 0.2 else rng.randint(-2**23, 2**23 - 1) for _ in range(3))
        status = rng.choice(statuses)
        counter = rng.choice([None, rng.randint(0, 0x1FF)])
        latency = rng.choice([None, rng.randint(0, 0xFFFF)])
        temp = rng.choice([None, tuple(rng.randint(-2**15, 2**15 - 1) for _ in range(3))])
        reserved = rng.choice([None, bytes(rng.randrange(256) for _ in range(3))])
        rows.append((gyro, status, counter, latency, temp, reserved))
    window = fmt.build_window(*(list(col) for col in zip(*rows, strict=True)))
    assert len(window) == n * fmt.length
    assert window == b"".join(_construct_datagram(fmt, *r) for r in rows)
    assert window == b"".join(fmt.build_values(*r) for r in rows)
    # and the decoder reads the same samples back
    frames = StreamDecoder([fmt]).feed(window)
    assert [(f.gyro, f.status) for f in frames] == [(r[0], r[1] & 0xFF) for r in rows]


def test_build_window_refuses_a_word_outside_s24_and_ragged_columns():
    fmt = Stim210Format("m")
    with pytest.raises(ValueError):
        fmt.build_window([(0, 0, 0), (2**23, 0, 0)], [0, 0], [0, 0], [0, 0])
    with pytest.raises(ValueError):
        fmt.build_window([(0, 0, 0), (1, 0, 0)], [0], [0, 0], [0, 0])
