"""Checksums against catalogue check values and the STIM300 datasheet's own examples."""

from protocols.crc import (
    crc8_stim,
    crc8_stim_rows,
    crc16_ccitt,
    crc32_mpeg2,
    crc32_mpeg2_fast,
    nmea_checksum,
    ubx_fletcher,
)

CHECK = b"123456789"


def test_crc8_check_value():
    # CRC-8 poly 0x07 init 0xFF: check("123456789") = 0xFB (docs/reference/wire-formats.md section 1.7)
    assert crc8_stim(CHECK) == 0xFB


def test_crc8_stim_utility_mode_datasheet_examples():
    # TS1524 r31 Figure 10-2: "$isn," -> 28 and "#isn,0,N2558184602002," -> 32 (decimal ASCII)
    assert crc8_stim(b"$isn,") == 28
    assert crc8_stim(b"#isn,0,N2558184602002,") == 32


def test_crc16_ccitt_false_check_value():
    assert crc16_ccitt(CHECK) == 0x29B1


def test_crc32_mpeg2_check_value_and_residue():
    for crc32 in (crc32_mpeg2, crc32_mpeg2_fast):
        assert crc32(CHECK) == 0x0376E6E7
        data = bytes(range(1, 17))
        crc = crc32(data)
        # running data + the big-endian CRC through the CRC leaves residue 0 (fprime's check)
        assert crc32(data + crc.to_bytes(4, "big")) == 0


def test_nmea_checksum_known_sentence():
    # $GPGGA,...*5B from docs/reference/wire-formats.md section 2.4 (built and parsed by pynmea2 there)
    body = "GPGGA,120000.00,3952.95000,N,11623.91600,E,1,12,0.80,44.0,M,6.1,M,,"
    assert nmea_checksum(body) == 0x5B


def test_ubx_fletcher_known_polls():
    # Well-known poll frames: CFG-PRT "B5 62 06 00 00 00 06 18", NAV-PVT "B5 62 01 07 00 00 08 19"
    assert ubx_fletcher(bytes([0x06, 0x00, 0x00, 0x00])) == (0x06, 0x18)
    assert ubx_fletcher(bytes([0x01, 0x07, 0x00, 0x00])) == (0x08, 0x19)


def test_crcs_agree_with_crccheck_on_random_data():
    import random

    from crccheck.crc import Crc8Base, Crc16CcittFalse, Crc32Mpeg2

    class Crc8Stim(Crc8Base):
        _poly, _initvalue, _reflect_input, _reflect_output, _xor_output = 0x07, 0xFF, False, False, 0x00

    rng = random.Random(3)
    for n in [*range(70), 255, 1000]:
        data = bytes(rng.randrange(256) for _ in range(n))
        assert crc32_mpeg2_fast(data) == crc32_mpeg2(data) == Crc32Mpeg2.calc(data)
        assert crc32_mpeg2_fast(data, 0x12345678) == crc32_mpeg2(data, 0x12345678)
        assert crc16_ccitt(data) == Crc16CcittFalse.calc(data)
        assert crc8_stim(data) == Crc8Stim.calc(data)
        a = b = 0
        for x in data:  # the Fletcher definition, byte by byte
            a = (a + x) & 0xFF
            b = (b + a) & 0xFF
        assert ubx_fletcher(data) == (a, b)
        assert nmea_checksum(data) == __import__("functools").reduce(lambda c, x: c ^ x, data, 0)


def test_crc8_stim_rows_is_each_row_s_crc8_against_crccheck():
    """The column-at-a-time CRC-8 of a window (D-10.E21) is, row by row, the CRC-8 of each row's body, checked
    against crccheck's catalogue CRC-8 (poly 0x07, init 0xFF) and the table-driven :func:`crc8_stim`; rows past
    the body are not read; another init is honoured."""
    import random

    import pytest
    from crccheck.crc import Crc8Base

    class Crc8Stim(Crc8Base):
        _poly, _initvalue, _reflect_input, _reflect_output, _xor_output = 0x07, 0xFF, False, False, 0x00

    rng = random.Random(43)
    for n, row_len, body_len in [(1, 15, 14), (2, 15, 14), (3, 21, 18), (2000, 15, 14), (50, 9, 9), (7, 4, 0)]:
        buf = bytes(rng.randrange(256) for _ in range(n * row_len))
        rows = [buf[i * row_len:i * row_len + body_len] for i in range(n)]
        assert crc8_stim_rows(buf, row_len, body_len) == bytes(Crc8Stim.calc(r) for r in rows)
        assert crc8_stim_rows(bytearray(buf), row_len, body_len, init=0x5A) == bytes(crc8_stim(r, 0x5A) for r in rows)
    assert crc8_stim_rows(b"", 15, 14) == b""
    with pytest.raises(ValueError):
        crc8_stim_rows(bytes(16), 15, 14)
    with pytest.raises(ValueError):
        crc8_stim_rows(bytes(15), 15, 16)
