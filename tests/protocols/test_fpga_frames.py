"""FPGA UART1 frames: the MAG frame, FpgaFrameFormat carrying both types, accelerometer ADC scale."""

import pytest

from protocols.crc import crc16_ccitt
from protocols.imu_frame import (
    ACCEL_VOLTS_PER_G,
    ADC_VOLTS_PER_LSB,
    MAG_FRAME_LEN,
    MAG_FRAME_SPEC,
    MAG_LSB_T,
    FpgaFrameFormat,
    ImuFrame,
    ImuFrameFormat,
    MagFrame,
    accel_code_to_g,
    adc_code_to_volts,
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
