"""Host port: STATUS, commands and ACKs, and the $PSNS text sentences (pynmea2 as the text peer)."""

import dataclasses

import pynmea2
import pytest

from protocols.host import (
    ACK_SPEC,
    CMD_REQUEST_STATUS,
    CMD_SELECT_VARIANT,
    COMMAND_SPECS,
    FILTER_VARIANT_NAMES,
    STATUS_SPEC,
    Ack,
    AckResult,
    FilterVariant,
    HostFormat,
    HostFrame,
    HostStatus,
    HostTextFormat,
    NavSolution,
    NavText,
    RequestStatus,
    ResetFilter,
    SelectVariant,
    SetOutputRate,
    build_host_frame,
    encode_host,
    encode_nav_solution,
    nav_text_sentences,
)
from protocols.nmea import NmeaFormat, build_gga
from protocols.stream import StreamDecoder, parse_one

NAV = NavSolution(seq=7, time_s=123456.785, lat_deg=-39.97912345, lon_deg=-116.33998765, height_m=-12.5,
                  vel_enu_mps=(-0.5, 12.25, -0.125), roll_deg=-1.5, pitch_deg=2.5, heading_deg=359.75,
                  sigma=(0.125,) * 9, mode=6 | (2 << 8), gnss_status=4, psns_status=1, cpu_load_pct=99.99,
                  deadline_misses=123456)
STATUS = HostStatus(seq=1, time_s=2.5, filter_variant=5, mode=6, output_rate_hz=40.0, gnss_status=1, psns_status=2,
                    cpu_load_pct=12.5, cpu_load_max_pct=88.75, fw_version=0x0102, deadline_misses=3, uart1_frames=10,
                    uart1_errors=1, uart2_frames=2, uart2_errors=0, uart3_frames=5, uart3_errors=4,
                    commands_accepted=6, commands_rejected=7)
COMMANDS = [ResetFilter(1, 0), ResetFilter(255, 1), SelectVariant(2, int(FilterVariant.SUN_ELEVATION)),
            SetOutputRate(3, 66.66666412353516), SetOutputRate(4, 0.0), RequestStatus(5)]


@pytest.mark.parametrize("obj", [STATUS, Ack(0x84, 5, int(AckResult.ACCEPTED)), *COMMANDS])
def test_round_trip_both_ways(obj):
    raw = encode_host(obj)
    assert parse_one(HostFormat(), raw) == obj
    assert encode_host(parse_one(HostFormat(), raw)) == raw


def test_specs_agree_with_struct_codecs():
    raw = encode_host(STATUS)
    assert STATUS_SPEC.sizeof() == 64 == len(raw) - 7
    c = STATUS_SPEC.parse(raw[5:-2])
    assert (c.cpu_load_max, c.uart3_errors, c.output_rate_hz) == (8875, 4, 40.0)
    assert ACK_SPEC.parse(encode_host(Ack(0x82, 9, 2))[5:-2]).token == 9
    raw = encode_host(SelectVariant(2, 4))
    assert COMMAND_SPECS[CMD_SELECT_VARIANT].parse(raw[5:-2]).variant == 4
    assert COMMAND_SPECS[CMD_REQUEST_STATUS].sizeof() == 1


def test_command_with_wrong_length_is_refused_at_the_header():
    dec = StreamDecoder([HostFormat()])
    out = dec.feed(build_host_frame(CMD_SELECT_VARIANT, b"\x01") + encode_host(RequestStatus(1)))
    assert out == [RequestStatus(1)] and dec.stats.length_errors == 1


def test_unknown_ids_and_longer_future_payloads():
    assert parse_one(HostFormat(), build_host_frame(0x40, b"abc")) == HostFrame(0x40, b"abc")
    longer = build_host_frame(0x01, encode_nav_solution(NAV)[5:-2] + b"\x01\x02\x03\x04")  # a future appended field
    assert parse_one(HostFormat(), longer) == NAV


def test_a_full_exchange_on_one_stream():
    up = b"".join(encode_host(c) for c in COMMANDS)
    down = encode_nav_solution(NAV) + b"".join(encode_host(Ack(c_id, tok, 0)) for c_id, tok in
                                                ((0x81, 1), (0x82, 2), (0x84, 5))) + encode_host(STATUS)
    dec = StreamDecoder([HostFormat()])
    assert dec.feed(up) == COMMANDS
    got = StreamDecoder([HostFormat()]).feed(down)
    assert got[0] == NAV and [type(g) for g in got[1:]] == [Ack, Ack, Ack, HostStatus]


def test_variant_names_and_enum():
    assert FILTER_VARIANT_NAMES["base"] is FilterVariant.BASE and len(FilterVariant) == 5


def test_text_sentences_parse_in_pynmea2_with_valid_checksums():
    text = nav_text_sentences(NAV, FilterVariant.DUAL_VECTOR)
    lines = text.decode().split("\r\n")[:-1]
    assert [ln[:8] for ln in lines] == ["$PSNSPOS", "$PSNSVEL", "$PSNSATT", "$PSNSSTA"]
    for ln in lines:
        assert len(ln) + 2 <= 82
        msg = pynmea2.parse(ln, check=True)  # raises on a bad checksum
        assert msg.manufacturer == "SNS"
    pos = pynmea2.parse(lines[0], check=True)
    assert pos.data == ["POS", "123456.785", "-39.9791235", "-116.3399876", "-12.50", "0206", "4", "1"]


def test_text_sentences_decode_in_ours_to_the_solution_rounded():
    out = StreamDecoder([HostTextFormat()]).feed(nav_text_sentences(NAV, FilterVariant.DUAL_VECTOR))
    assert [o.kind for o in out] == ["POS", "VEL", "ATT", "STA"]
    pos, vel, att, sta = out
    assert pos == NavText("POS", 123456.785, (-39.9791235, -116.3399876, -12.5, 0x0206, 4, 1))
    assert vel.values == (-0.5, 12.25, -0.125) and att.values == (-1.5, 2.5, 359.75)
    assert sta.values == (2, 99.99, 123456)
    assert all(HostTextFormat.encode(o) + b"" in nav_text_sentences(NAV, 2) for o in out)


def test_text_and_binary_share_the_port():
    stream = encode_nav_solution(NAV) + nav_text_sentences(NAV) + build_gga(__import__("datetime").time(1), 1, 2, 3, 4)
    out = StreamDecoder([HostFormat(), HostTextFormat()]).feed(stream)
    assert out[0] == NAV and [getattr(o, "kind", None) for o in out[1:5]] == ["POS", "VEL", "ATT", "STA"]
    assert type(out[5]).__name__ == "Gga"
    assert NmeaFormat().check(nav_text_sentences(NAV)[:60]) is False


def test_status_percentages_saturate():
    raw = encode_host(dataclasses.replace(STATUS, cpu_load_pct=1000.0, cpu_load_max_pct=-1.0))
    back = parse_one(HostFormat(), raw)
    assert (back.cpu_load_pct, back.cpu_load_max_pct) == (655.35, 0.0)
