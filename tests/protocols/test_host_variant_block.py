"""NAV_SOLUTION's optional VARIANT block and STATUS's variant_mode (the filter variants): both ways, and absent for
the base variant."""

from __future__ import annotations

from protocols.host import (
    NAV_SOLUTION_LEN,
    NAV_VARIANT_BLOCK_SPEC,
    STATUS_SPEC,
    HostFormat,
    HostStatus,
    NavSolution,
    build_host_frame,
    encode_host,
    encode_nav_solution,
)
from protocols.stream import parse_one

BASE = NavSolution(7, 12.5, 39.979, 116.339, 50.25, (0.5, -0.25, 0.125), 1.5, -2.75, 30.5, (0.0625,) * 9, 0x0102, 1,
                   1, 3.5, 0)


def test_base_frame_has_no_variant_block():
    raw = encode_nav_solution(BASE)
    assert len(raw) == 7 + NAV_SOLUTION_LEN and parse_one(HostFormat(), raw) == BASE


def test_variant_block_round_trip_and_spec():
    n = NavSolution(*[getattr(BASE, f) for f in BASE.__dataclass_fields__ if f not in
                      ("variant_mode", "psns_units", "psns_q_mask")], variant_mode=2, psns_units=3, psns_q_mask=0b101)
    raw = encode_host(n)
    assert len(raw) == 7 + NAV_SOLUTION_LEN + 6
    back = parse_one(HostFormat(), raw)
    assert back == n and encode_host(back) == raw
    blk = NAV_VARIANT_BLOCK_SPEC.parse(raw[5 + NAV_SOLUTION_LEN:-2])
    assert (blk.block_len, blk.variant_mode, blk.psns_units, blk.psns_q_mask) == (4, 2, 3, 0b101)


def test_unknown_appended_bytes_are_not_taken_for_a_variant_block():
    longer = build_host_frame(0x01, encode_nav_solution(BASE)[5:-2] + b"\x01\x04\x02\x03\x04\x05\x06")
    assert parse_one(HostFormat(), longer) == BASE


def test_status_carries_the_variant_mode_in_its_former_reserved_byte():
    st = HostStatus(1, 2.0, 4, 6, 100.0, 1, 1, 1.0, 2.0, 0x0105, 0, 1, 0, 2, 0, 3, 0, 0, 0, variant_mode=2)
    raw = encode_host(st)
    assert parse_one(HostFormat(), raw) == st and STATUS_SPEC.parse(raw[5:-2]).variant_mode == 2
