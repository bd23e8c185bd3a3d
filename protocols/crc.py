"""Checksums used on the wire.

====================== ==================================================================  ==========
function               algorithm                                                           check(*)
====================== ==================================================================  ==========
``crc8_stim[_fast]``   CRC-8, poly 0x07, init 0xFF, no reflection, no xor (STIM210/300)     0xFB
``crc16_ccitt``        CRC-16/CCITT-FALSE, poly 0x1021, init 0xFFFF, no refl., no xor       0x29B1
``crc32_mpeg2[_fast]`` CRC-32/MPEG-2, poly 0x04C11DB7, init 0xFFFFFFFF, no refl., no xor    0x0376E6E7
``nmea_checksum``      XOR of every byte between ``$`` and ``*``                            --
``ubx_fletcher``       8-bit Fletcher over class, id, length, payload (u-blox)              --
====================== ==================================================================  ==========

(*) ``check`` is the CRC of the ASCII bytes ``b"123456789"`` (the catalogue convention).
Sources: ``docs/reference/wire-formats.md`` section 1.7 (STIM CRCs, from TS1524 r31 and the
c2a-aobc STIM210 driver); CRC-16/CCITT is ``binascii.crc_hqx`` seeded with 0xFFFF.

Speed: the CRC-16 runs in C. :func:`crc32_mpeg2` is the table-driven reference; :func:`crc32_mpeg2_fast`
runs in C: CRC-32/MPEG-2 is the bit-reversed twin of the zlib CRC-32 (same polynomial, reflected, final
XOR), so reversing the bits of every input byte, running ``zlib.crc32`` and reversing the 32-bit result
gives the MPEG-2 value (``tests/protocols/fast_path_cases.py`` checks the two against each other, and
``tests/protocols/test_crc.py`` against ``crccheck``).
:func:`crc8_stim_fast` is :func:`crc8_stim` remembered for the last few hundred byte strings: a STIM datagram's
CRC-8 (a Python loop, ~0.6 us for 16 bytes) is computed by the gyro that sends it, then checked by the FPGA and by the
recorder's frame count on the same bytes; the second and third are a dictionary look-up
(``tests/protocols/fast_path_cases.py`` compares the two on fresh, repeated and non-``bytes`` inputs).
The Fletcher sums use ``sum`` and ``itertools.accumulate`` (CK_B is the sum of the running CK_A).
"""

from __future__ import annotations

import binascii
import itertools
import zlib

__all__ = ["CRC8_MEMO_GENERATION", "crc8_stim", "crc8_stim_fast", "crc8_stim_rows", "crc16_ccitt", "crc32_mpeg2",
           "crc32_mpeg2_fast", "nmea_checksum", "ubx_fletcher"]


def _crc8_table(poly: int) -> bytes:
    table = bytearray(256)
    for i in range(256):
        c = i
        for _ in range(8):
            c = ((c << 1) ^ poly) & 0xFF if c & 0x80 else (c << 1) & 0xFF
        table[i] = c
    return bytes(table)


def _crc32_table(poly: int) -> tuple[int, ...]:
    table = []
    for i in range(256):
        c = i << 24
        for _ in range(8):
            c = ((c << 1) ^ poly) & 0xFFFFFFFF if c & 0x80000000 else (c << 1) & 0xFFFFFFFF
        table.append(c)
    return tuple(table)


_CRC8_07 = _crc8_table(0x07)
_CRC32_04C11DB7 = _crc32_table(0x04C11DB7)


def crc8_stim(data: bytes | bytearray | memoryview, init: int = 0xFF) -> int:
    """CRC-8 (poly 0x07, init 0xFF) as used by the STIM210 normal datagram and STIM utility mode."""
    c = init
    table = _CRC8_07
    for b in data:
        c = table[c ^ b]
    return c


#: :func:`crc8_stim_fast`'s memory: CRC-8 (init 0xFF) by the bytes, the newer and the older generation
_CRC8_NEW: dict[bytes, int] = {}
_CRC8_OLD: dict[bytes, int] = {}
#: byte strings per generation: an entry lives 256-512 insertions (1.3-2.6 s of 200 Hz datagrams; the recorder
#: counts the gyro's datagrams at its 1 s flush)
CRC8_MEMO_GENERATION = 256


def crc8_stim_fast(data: bytes | bytearray | memoryview, init: int = 0xFF) -> int:
    """:func:`crc8_stim`, looked up for ``bytes`` seen among the last 256-512 distinct ones (see the module
    docstring); other types and another ``init`` are computed."""
    global _CRC8_NEW, _CRC8_OLD
    if type(data) is not bytes or init != 0xFF:
        return crc8_stim(data, init)
    c = _CRC8_NEW.get(data)
    if c is None:
        c = _CRC8_OLD.get(data)
        if c is None:
            c = crc8_stim(data)
        if len(_CRC8_NEW) >= CRC8_MEMO_GENERATION:
            _CRC8_OLD = _CRC8_NEW
            _CRC8_NEW = {}
        _CRC8_NEW[data] = c
    return c


def crc8_stim_rows(buf: bytes | bytearray, row_len: int, body_len: int, init: int = 0xFF) -> bytes:
    """:func:`crc8_stim` of each row of ``buf`` (rows of ``row_len`` bytes back to back), over its first
    ``body_len`` bytes: one byte per row, in row order.

    The same table and the same recurrence ``c = T[c ^ b]``, taken a column at a time over every row at once:
    the column's bytes (an extended slice) XOR the running CRCs (as one big integer), then ``bytes.translate``
    looks the table up for the whole column. ``body_len`` C-level passes instead of ``rows * body_len`` Python
    steps (docs/decisions/performance.md D-10.E21). A single row goes through :func:`crc8_stim_fast`."""
    if row_len <= 0 or not 0 <= body_len <= row_len or len(buf) % row_len:
        raise ValueError(f"crc8_stim_rows: {len(buf)} bytes are not rows of {row_len} with a {body_len}-byte body")
    n = len(buf) // row_len
    if n == 1:
        return bytes((crc8_stim_fast(bytes(buf[:body_len]), init),))
    c = bytes((init,)) * n
    table = _CRC8_07
    for i in range(body_len):
        col = buf[i::row_len]
        c = (int.from_bytes(c, "big") ^ int.from_bytes(col, "big")).to_bytes(n, "big").translate(table)
    return c


def crc16_ccitt(data: bytes | bytearray | memoryview, init: int = 0xFFFF) -> int:
    """CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF); used by the FPGA, PSNS and host frames."""
    return binascii.crc_hqx(data, init)


#: ``bytes.translate`` table reversing the bit order of one byte.
_BITREV8 = bytes(int(f"{i:08b}"[::-1], 2) for i in range(256))


def _bitrev32(v: int) -> int:
    return int.from_bytes(v.to_bytes(4, "little").translate(_BITREV8), "big")


def crc32_mpeg2_fast(data: bytes | bytearray | memoryview, init: int = 0xFFFFFFFF) -> int:
    """:func:`crc32_mpeg2` through ``zlib.crc32`` on the bit-reversed bytes (see the module docstring)."""
    start = 0 if init == 0xFFFFFFFF else _bitrev32(init) ^ 0xFFFFFFFF
    return _bitrev32(zlib.crc32(bytes(data).translate(_BITREV8), start) ^ 0xFFFFFFFF)


def crc32_mpeg2(data: bytes | bytearray | memoryview, init: int = 0xFFFFFFFF) -> int:
    """CRC-32/MPEG-2 (poly 0x04C11DB7, init 0xFFFFFFFF, MSB first) of the STIM300 datagrams; table-driven
    reference of :func:`crc32_mpeg2_fast`.

    The STIM300 appends N dummy 0x00 bytes to the covered bytes (never sent) so that the
    CRC input is a multiple of four bytes; pass them in ``data``.
    """
    c = init
    table = _CRC32_04C11DB7
    for b in data:
        c = ((c << 8) & 0xFFFFFFFF) ^ table[((c >> 24) ^ b) & 0xFF]
    return c


def nmea_checksum(body: bytes | str) -> int:
    """XOR of the sentence body: every character strictly between ``$`` and ``*``."""
    if isinstance(body, str):
        body = body.encode("ascii")
    c = 0
    for b in body:
        c ^= b
    return c


def ubx_fletcher(data: bytes | bytearray | memoryview) -> tuple[int, int]:
    """u-blox 8-bit Fletcher checksum (CK_A, CK_B) over class, id, length and payload."""
    return sum(data) & 0xFF, sum(itertools.accumulate(data)) & 0xFF
