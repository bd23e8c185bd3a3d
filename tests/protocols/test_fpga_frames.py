"""FPGA UART1 frames: the MAG frame, FpgaFrameFormat carrying both types, accelerometer ADC scale."""

import random

import pytest

from protocols.crc import crc16_ccitt
from protocols.imu_frame import (
    ACCEL_VOLTS_PER_G,
    ADC_VOLTS_PER_LSB,
    IMU_FRAME_SPEC,
    MAG_FRAME_LEN,
    MAG_FRAME_SPEC,
    MAG_LSB_T,
    FpgaFrameFormat,
    ImuFrame,
    ImuFrameFormat,
    MagFrame,
    accel_code_to_g,
    adc_code_to_volts,
    build_imu_frame,
    encode_mag_frame,
)
from protocols.stream import StreamDecoder, parse_one

MAG = MagFrame(seq=65535, t_sample_us=4294967295, field=(213_450, -41_200, -2**31), status=0x02)
IMU = ImuFrame(1, 5000, 0, 0, (1, -1, 0), 0, 10, 516, (0, 0, 1), 0)


def test_mag_frame_layout_by_hand():
    raw = encode_mag_frame(MagFrame(1, 5000, (1, -1, 10), 0x04))
    assert len(raw) == MAG_FRAME_LEN == MAG_FRAME_SPEC.sizeof() == 25
    # sync, type 2, len 19, seq 1, t 5000 (0x1388), field LE i32 1, -1, 10, status 4, CRC over bytes 2..22
    assert raw[:23].hex() == "55aa021301008813000001000000ffffffff0a00000004"
    assert int.from_bytes(raw[23:], "little") == crc16_ccitt(raw[2:23])


def test_mag_round_trip_and_spec():
    raw = encode_mag_frame(MAG)
    assert parse_one(FpgaFrameFormat(), raw) == MAG
    c = MAG_FRAME_SPEC.parse(raw)
    assert list(c.field) == list(MAG.field) and c.status == 2
    assert MAG.field[0] * MAG_LSB_T == pytest.approx(21.345e-6)


def test_fpga_format_carries_both_and_imu_format_keeps_to_imu():
    stream = ImuFrameFormat().build(IMU) + encode_mag_frame(MAG) + ImuFrameFormat().build(IMU)
    assert StreamDecoder([FpgaFrameFormat()]).feed(stream) == [IMU, MAG, IMU]
    dec = StreamDecoder([ImuFrameFormat()])
    assert dec.feed(stream) == [IMU, IMU]
    assert dec.stats.length_errors == 1 and dec.stats.garbage_bytes == MAG_FRAME_LEN
    assert FpgaFrameFormat().encode(MAG) == encode_mag_frame(MAG)


def test_field_range_enforced():
    with pytest.raises(ValueError):
        encode_mag_frame(MagFrame(0, 0, (2**31, 0, 0), 0))


def test_adc_scale():
    # 24-bit ADC, +-4.096 V: 488.28125 nV/LSB; x accelerometer 90 mV/g -> 5.425 ug/LSB
    assert pytest.approx(488.28125e-9) == ADC_VOLTS_PER_LSB
    assert adc_code_to_volts(2**23) == pytest.approx(4.096)
    assert accel_code_to_g(184320, 0) == pytest.approx(1.0)  # 90 mV = 184320 LSB
    assert accel_code_to_g(1, 1) == pytest.approx(ADC_VOLTS_PER_LSB / ACCEL_VOLTS_PER_G[1])


def test_build_imu_frame_is_construct_s_bytes_of_the_frame():
    """``build_imu_frame`` (the FPGA's sender: no frame object) gives ``construct``'s bytes of the frame with those
    fields (counters wrapped to their width, CRC-16 over bytes 2..37), and ``ImuFrameFormat.build`` of the object
    the same bytes (performance.md 5.7, D-10.E8)."""
    rng = random.Random(7)
    for _ in range(300):
        seq, t_trig, t_pps = rng.randint(0, 2**20), rng.randint(0, 2**34), rng.randint(0, 2**34)
        pps, gst, gcnt, st = (rng.randint(0, 0x3FF) for _ in range(4))
        lat = rng.randint(0, 2**17)
        gyro = tuple(rng.randint(-2**23, 2**23 - 1) for _ in range(3))
        accel = tuple(rng.randint(-2**23, 2**23 - 1) for _ in range(3))
        raw = build_imu_frame(seq, t_trig, t_pps, pps, gyro, gst, gcnt, lat, accel, st)
        values = {"seq": seq & 0xFFFF, "t_trigger_us": t_trig & 0xFFFFFFFF, "t_pps_us": t_pps & 0xFFFFFFFF,
                  "pps_count": pps & 0xFF, "gyro": list(gyro), "gyro_status": gst & 0xFF,
                  "gyro_counter": gcnt & 0xFF, "gyro_latency_us": lat & 0xFFFF, "accel": list(accel),
                  "fpga_status": st & 0xFF}
        body = IMU_FRAME_SPEC.build({**values, "crc": 0})[:38]
        assert raw == body + crc16_ccitt(body[2:]).to_bytes(2, "little")
        assert ImuFrameFormat().build(ImuFrame(seq, t_trig, t_pps, pps, gyro, gst, gcnt, lat, accel, st)) == raw
    with pytest.raises(ValueError):
        build_imu_frame(0, 0, 0, 0, (2**23, 0, 0), 0, 0, 0, (0, 0, 0), 0)
