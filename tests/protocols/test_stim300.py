"""STIM300 datagrams: the ID table against TS1524 r31, every ID both ways, device/format configuration."""

import itertools

import pytest
from crccheck.crc import Crc32Mpeg2

from protocols.errors import ChecksumError
from protocols.stim import (
    STIM300_ACCEL_DV_LSB_MPS,
    STIM300_ACCEL_LSB_G,
    STIM300_DATAGRAMS,
    Stim210Format,
    Stim300Datagram,
    Stim300Format,
    StimDatagram,
    StimStatus,
    counter_step,
)
from protocols.stream import StreamDecoder, parse_one

# TS1524 r31 Table 5-22 (length without CR LF, dummy bytes), as listed in docs/reference/wire-formats.md section 1.4.
DATASHEET = {0x90: (18, 2), 0x91: (28, 0), 0x92: (28, 0), 0x93: (38, 2), 0x94: (25, 3), 0xA5: (42, 2), 0xA6: (42, 2),
             0xA7: (59, 1), 0xF0: (22, 2), 0xF1: (32, 0), 0xF2: (32, 0), 0xF3: (42, 2), 0xF4: (29, 3), 0xF5: (46, 2),
             0xF6: (46, 2), 0xF7: (63, 1)}
LEGACY = {0x97: 0xA7, 0x98: 0xF0, 0x99: 0xF1, 0x9A: 0xF2, 0x9B: 0xF3, 0x9C: 0xF4, 0xAD: 0xF5, 0xAE: 0xF6, 0xAF: 0xF7}


def full(ident: int, k: int = 1) -> Stim300Datagram:
    groups = STIM300_DATAGRAMS[ident][0]
    acc, incl, temp, aux = ("acc" in groups), ("incl" in groups), ("temp" in groups), ("aux" in groups)
    return Stim300Datagram(
        ident, (123456 * k, -654321, -8388608), 0x80, (10 * k) & 0xFF, 999,
        accel=(1, -2, 8388607) if acc else None, accel_status=0x11 if acc else None,
        incl=(-3, 4, 4194304) if incl else None, incl_status=0x22 if incl else None,
        gyro_temp=(6400, -1, 32767) if temp else None, gyro_temp_status=0x40 if temp else None,
        accel_temp=(6401, 2, -32768) if temp and acc else None, accel_temp_status=0x08 if temp and acc else None,
        incl_temp=(6402, 3, 0) if temp and incl else None, incl_temp_status=0x04 if temp and incl else None,
        aux=-4350 if aux else None, aux_status=0x01 if aux else None)


def test_id_table_matches_the_datasheet():
    for ident, (length, dummy) in DATASHEET.items():
        _groups, n, d, _ = STIM300_DATAGRAMS[ident]
        assert (n, d) == (length, dummy), hex(ident)
        fmt = Stim300Format(ident)
        assert fmt.spec.sizeof() == length and (fmt.body_len + dummy) % 4 == 0
    for legacy, r31 in LEGACY.items():
        assert STIM300_DATAGRAMS[legacy][:3] == STIM300_DATAGRAMS[r31][:3]


@pytest.mark.parametrize("ident", sorted(STIM300_DATAGRAMS))
@pytest.mark.parametrize("crlf", [False, True])
def test_every_id_round_trips_and_agrees_with_construct_and_crccheck(ident, crlf):
    fmt = Stim300Format(ident, crlf=crlf)
    d = full(ident)
    raw = fmt.build(d)
    assert len(raw) == STIM300_DATAGRAMS[ident][1] + (2 if crlf else 0)
    assert raw[0] == ident and (raw.endswith(b"\r\n") if crlf else True)
    assert parse_one(fmt, raw) == d
    assert fmt.build(parse_one(fmt, raw)) == raw
    c = fmt.spec.parse(raw)
    assert list(c.gyro) == list(d.gyro) and c.counter == d.counter and c.latency_us == d.latency_us
    body = raw[: fmt.body_len]
    assert c.crc == Crc32Mpeg2.calc(body + bytes(STIM300_DATAGRAMS[ident][2]))  # independent CRC library


def test_missing_cluster_refused_by_encoder():
    with pytest.raises(ValueError, match="accel"):
        Stim300Format(0x93).build(Stim300Datagram(0x93, (0, 0, 0), 0, 0, 0))


def test_crc_covers_dummy_bytes_and_not_crlf():
    fmt = Stim300Format(0x94, crlf=True)  # 3 dummy bytes
    raw = bytearray(fmt.build(full(0x94)))
    with_zero_dummy = Crc32Mpeg2.calc(bytes(raw[:21]) + b"\x00\x00\x00")
    assert int.from_bytes(raw[21:25], "big") == with_zero_dummy
    raw[-1] = 0x00  # a broken LF is a broken datagram
    with pytest.raises(ChecksumError):
        parse_one(fmt, bytes(raw))


def test_id_0x90_means_different_frames_on_stim210_and_stim300():
    s210 = Stim210Format("s").build(StimDatagram(0x90, (1, 2, 3), 0))
    s300 = Stim300Format(0x90).build(Stim300Datagram(0x90, (1, 2, 3), 0, 10, 500))
    assert len(s210) == 12 and len(s300) == 18
    d210 = StreamDecoder([Stim210Format("s")])
    d300 = StreamDecoder([Stim300Format(0x90)])
    assert d210.feed(s300) == [] and d300.feed(s210) == []
    assert d210.stats.crc_errors >= 1
    assert d210.feed(s210 * 2) and d300.feed(s300 * 2)


def test_counter_step_of_external_trigger():
    assert counter_step(200) == 10 and counter_step(2000) == 1 and counter_step(125) == 16
    with pytest.raises(ValueError):
        counter_step(300)
    fmt = Stim300Format(0x90)
    stream = b"".join(fmt.build(Stim300Datagram(0x90, (0, 0, 0), 0, (250 + 10 * k) & 0xFF, 500)) for k in range(5))
    counters = [d.counter for d in StreamDecoder([fmt]).feed(stream)]
    assert [(b - a) % 256 for a, b in itertools.pairwise(counters)] == [10] * 4


def test_scale_tables_and_status_bits():
    assert STIM300_ACCEL_LSB_G[10] == 2.0**-19 and STIM300_ACCEL_DV_LSB_MPS[80] == 2.0**-19
    assert StimStatus(0x91) == StimStatus.SYSTEM_INTEGRITY_ERROR | StimStatus.OVERLOAD | StimStatus.X_CHANNEL


def test_unknown_id_refused():
    with pytest.raises(ValueError, match="0xA0"):
        Stim300Format(0xA0)
