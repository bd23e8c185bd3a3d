"""FPGA IMU frame and host NAV_SOLUTION: fast codecs agree with the declarative specs."""

import math

import pytest

from protocols.host import NAV_SOLUTION_SPEC, HostFormat, NavSolution, encode_nav_solution
from protocols.imu_frame import IMU_FRAME_LEN, IMU_FRAME_SPEC, ImuFrame, ImuFrameFormat
from protocols.stream import StreamDecoder, parse_one


def sample_imu() -> ImuFrame:
    return ImuFrame(seq=65535, t_trigger_us=4294967295, t_pps_us=123456, pps_count=7, gyro=(-8388608, 0, 8388607),
                    gyro_status=0x80, gyro_counter=250, gyro_latency_us=516, accel=(-1, 2, -3), fpga_status=0x11)


def test_imu_frame_round_trip_and_spec():
    fmt = ImuFrameFormat()
    raw = fmt.build(sample_imu())
    assert len(raw) == IMU_FRAME_LEN == IMU_FRAME_SPEC.sizeof()
    assert parse_one(fmt, raw) == sample_imu()
    c = IMU_FRAME_SPEC.parse(raw)
    assert list(c.gyro) == [-8388608, 0, 8388607] and c.t_trigger_us == 4294967295 and c.seq == 65535


def test_imu_frame_golden_bytes():
    # sync, type 1, len 34, then little-endian fields, CRC-16/CCITT-FALSE over bytes 2..37
    raw = ImuFrameFormat().build(ImuFrame(1, 5000, 0, 0, (1, -1, 0), 0, 10, 0, (0, 0, 1), 0))
    assert raw[:15].hex() == "55aa01220100881300000000000000"
    assert raw[15:24].hex() == "010000ffffff000000"
    assert raw[28:37].hex() == "000000000000010000"


def test_nav_solution_round_trip():
    n = NavSolution(seq=3, time_s=12.345, lat_deg=39.979, lon_deg=116.339, height_m=50.25,
                    vel_enu_mps=(0.5, -0.25, 0.125), roll_deg=1.5, pitch_deg=-2.5, heading_deg=359.5,
                    sigma=tuple(float(i) for i in range(9)), mode=6, gnss_status=1, psns_status=0,
                    cpu_load_pct=12.34, deadline_misses=2)
    raw = encode_nav_solution(n)
    back = parse_one(HostFormat(), raw)
    assert back == n
    assert NAV_SOLUTION_SPEC.parse(raw[5:-2]).lat_deg == 39.979


def test_host_decoder_survives_noise():
    n = NavSolution(1, 1.0, 1.0, 2.0, 3.0, (0.0, 0.0, 0.0), 0.0, 0.0, 0.0, (0.0,) * 9, 0, 0, 0, 0.0, 0)
    raw = encode_nav_solution(n)
    dec = StreamDecoder([HostFormat()])
    out = dec.feed(b"\xa5\x5a\xff\xff" + raw[:10]) + dec.feed(raw[10:] + b"\x00\xa5" + raw)
    assert len(out) == 2 and all(o == n for o in out)
    assert dec.stats.length_errors >= 1
    assert not math.isnan(out[0].time_s)


@pytest.mark.parametrize("cut", [1, 5, 17, 39])
def test_imu_frame_any_chunking(cut):
    fmt = ImuFrameFormat()
    raw = fmt.build(sample_imu()) * 3
    dec = StreamDecoder([fmt])
    out = dec.feed(raw[:cut]) + dec.feed(raw[cut:])
    assert out == [sample_imu()] * 3
