"""The IMU frame as the firmware screens it (issue 41, items 6 and 8; docs/hostile-input.md section 1): the STIM
STATUS byte, words beyond the fitted units' ranges, the time-base resync against replays, and the host's
SET_OUTPUT_RATE range. Frames are built here field by field (protocols.imu_frame), so each rule is seen alone."""

from __future__ import annotations

import math

import pytest

from firmware_model import Firmware, FirmwareConfig
from firmware_model.input_guard import check_gyro_status, check_imu_range
from protocols.host import (
    OUTPUT_RATE_MIN_HZ,
    Ack,
    AckResult,
    HostFormat,
    SetOutputRate,
    encode_command,
)
from protocols.imu_frame import ACCEL_VOLTS_PER_G, ADC_VOLTS_PER_LSB, build_imu_frame
from protocols.stim import GYRO_RATE_LSB_DPS, STATUS_SAMPLE_INVALID, StimStatus, overload_status
from protocols.stream import StreamDecoder

UART_HOST, UART_IMU = 0, 1
PERIOD_US = 5000
#: 1 g on z, as the ADC codes it (the static vehicle)
ACCEL_1G = (0, 0, round(ACCEL_VOLTS_PER_G[2] / ADC_VOLTS_PER_LSB))
#: the STIM210's +-400 deg/s in rate words (2^-14 deg/s): 6 553 600, well inside the 24-bit rail (8 388 607)
GYRO_400 = round(400.0 / GYRO_RATE_LSB_DPS)


def frame(k: int, gyro: tuple[int, int, int] = (0, 0, 0), status: int = 0, accel: tuple[int, int, int] = ACCEL_1G,
          t_us: int | None = None, seq: int | None = None, counter: int | None = None) -> bytes:
    """IMU frame number ``k`` of a 200 Hz stream (time, sequence and STIM counter from ``k`` unless given)."""
    return build_imu_frame(k & 0xFFFF if seq is None else seq, k * PERIOD_US if t_us is None else t_us, 0, 0, gyro,
                           status, (10 * k) & 0xFF if counter is None else counter, 500, accel, 0)


def feed(fw: Firmware, frames: list[bytes]) -> None:
    for f in frames:
        fw.receive(UART_IMU, f)
        fw.service()


def test_status_bits_that_invalidate_a_sample_follow_table_5_23() -> None:
    """Overload, channel error, start-up and system integrity error make the sample invalid; outside operating
    conditions and the channel bits alone do not (TS1524 r31 Table 5-23, docs/reference/wire-formats.md 1.6)."""
    for bit in (StimStatus.OVERLOAD, StimStatus.CHANNEL_ERROR, StimStatus.STARTUP, StimStatus.SYSTEM_INTEGRITY_ERROR):
        assert check_gyro_status(int(bit | StimStatus.X_CHANNEL)) == "gyro_status"
    for ok in (0, StimStatus.OUTSIDE_OPERATING_CONDITIONS, StimStatus.X_CHANNEL | StimStatus.Z_CHANNEL):
        assert check_gyro_status(int(ok)) is None
    assert STATUS_SAMPLE_INVALID == 0xD8
    assert overload_status(False, False, False) == 0
    assert overload_status(True, False, True) == 0x10 | 0x01 | 0x04


def test_words_beyond_the_range_are_refused_below_the_rail() -> None:
    """400 deg/s (the range) passes; one LSB of rounding more passes; two more, and the near-rail word that passed
    before issue 41, are ``gyro_range``; an accelerometer code beyond its +-30 g / +-25 g is ``accel_range``."""
    fw = Firmware(FirmwareConfig())
    gmax, amax = fw._gyro_word_max, fw._accel_code_max
    assert gmax == GYRO_400 + 1
    ok_a = ACCEL_1G
    assert check_imu_range((GYRO_400, -GYRO_400, 0), ok_a, gmax, amax) == (None, None)
    assert check_imu_range((0, GYRO_400 + 2, 0), ok_a, gmax, amax) == ("gyro_range", None)
    assert check_imu_range((2**23 - 2, 0, 0), ok_a, gmax, amax) == ("gyro_range", None)
    x30 = round(30.0 * ACCEL_VOLTS_PER_G[0] / ADC_VOLTS_PER_LSB)
    assert check_imu_range((0, 0, 0), (x30, 0, 0), gmax, amax) == (None, None)
    assert check_imu_range((0, 0, 0), (x30 + 2, 0, 0), gmax, amax) == (None, "accel_range")
    z26 = round(26.0 * ACCEL_VOLTS_PER_G[2] / ADC_VOLTS_PER_LSB)
    assert check_imu_range((0, 0, 0), (0, 0, -z26), gmax, amax) == (None, "accel_range")


def test_angle_output_range_is_the_range_times_the_period() -> None:
    fw = Firmware(FirmwareConfig(gyro_output="angle"))
    assert fw._gyro_word_max == math.floor(400.0 * 0.005 * 2**21) + 1


def test_flagged_and_out_of_range_samples_are_held_and_counted() -> None:
    """A flagged gyro sample and a near-rail one are replaced by the last good gyro sample (D-5.46); the
    accelerometer of the same frame is still used; each refusal is counted by reason."""
    fw = Firmware(FirmwareConfig())
    good = (12, -7, 3)
    feed(fw, [frame(k, good) for k in range(10)])
    held: list[tuple[int, int, int]] = []
    orig = fw._imu_tick

    def spy(fr):  # what reaches the strapdown
        held.append((fr.gyro, fr.accel))
        return orig(fr)

    fw._imu_tick = spy  # type: ignore[method-assign]
    accel2 = (5, 6, ACCEL_1G[2] + 7)
    feed(fw, [frame(10, (GYRO_400 - 1, 0, 0), status=overload_status(True, False, False), accel=accel2),
              frame(11, (2**23 - 2, 0, 0), accel=accel2),
              frame(12, (0, 0, 0), status=int(StimStatus.STARTUP), accel=accel2),
              frame(13, (1, 2, 3), status=int(StimStatus.OUTSIDE_OPERATING_CONDITIONS), accel=accel2)])
    assert held == [(good, accel2)] * 3 + [((1, 2, 3), accel2)]
    c = fw.counters
    assert c["input_rejected_gyro_status"] == 2 and c["input_rejected_gyro_range"] == 1
    assert c["input_rejected"] == 3 and c["imu_frames"] == 14


def test_without_a_good_sample_yet_a_flagged_frame_is_dropped() -> None:
    fw = Firmware(FirmwareConfig())
    feed(fw, [frame(k, status=int(StimStatus.STARTUP)) for k in range(5)])
    assert fw.counters["imu_frames"] == 0 and fw.counters["input_rejected_gyro_status"] == 5


# -- the time-base resync ----------------------------------------------------------------------------------------

def test_a_new_time_base_is_taken_after_five_consistent_frames() -> None:
    """A forward jump of the FPGA counter held for five consistent frames is a new time base (``imu_time_resync``)."""
    fw = Firmware(FirmwareConfig())
    feed(fw, [frame(k) for k in range(400)])
    jump = 1_000_000_000
    feed(fw, [frame(k, t_us=k * PERIOD_US + jump) for k in range(400, 406)])
    assert fw.counters["imu_time_resync"] == 1
    assert fw.clock.now_s() == pytest.approx((405 * PERIOD_US + jump) / 1e6)
    assert fw.counters["imu_resync_refused"] == 0


def test_a_replayed_time_base_never_resyncs_the_clock() -> None:
    """Two seconds of frames from earlier in the run (a looped capture) are refused as ``imu_time_replay``, counted
    in ``imu_resync_refused``, and the clock stays; the live stream goes on afterwards."""
    fw = Firmware(FirmwareConfig())
    feed(fw, [frame(k) for k in range(2000)])  # 10 s
    t_before = fw.clock.now_s()
    feed(fw, [frame(k) for k in range(600, 1000)])  # 2 s replayed from t = 3 s
    assert fw.counters["imu_time_resync"] == 0
    assert fw.clock.now_s() == t_before
    assert fw.counters["imu_resync_refused"] == 400
    assert fw.counters["input_rejected_imu_time_replay"] == 400
    feed(fw, [frame(k) for k in range(2000, 2010)])
    assert fw.counters["imu_frames"] == 2010 and fw.clock.now_s() == pytest.approx(2009 * PERIOD_US / 1e6)


def test_a_duplicated_frame_never_resyncs_the_clock() -> None:
    """The same frame again and again (time stamp, sequence and STIM counter repeated) is a replay of the last
    frame: it never counts toward a resync."""
    fw = Firmware(FirmwareConfig())
    feed(fw, [frame(k) for k in range(400)])
    feed(fw, [frame(399)] * 20)
    assert fw.counters["imu_time_resync"] == 0 and fw.counters["imu_resync_refused"] == 20


def test_a_jumped_base_with_a_repeated_gyro_counter_never_resyncs() -> None:
    """Frames of a new time base whose STIM datagram counter does not advance (a duplicated datagram, not a live
    gyro) never form a new time base."""
    fw = Firmware(FirmwareConfig())
    feed(fw, [frame(k) for k in range(400)])
    jump = 500_000_000
    feed(fw, [frame(k, t_us=k * PERIOD_US + jump, counter=77) for k in range(400, 420)])
    assert fw.counters["imu_time_resync"] == 0 and fw.counters["imu_resync_refused"] >= 15


def test_an_fpga_restart_from_sequence_zero_is_taken() -> None:
    """An FPGA that restarted (sequence and counter from 0 again) is a new time base, though its stamps lie in
    time already lived through."""
    fw = Firmware(FirmwareConfig())
    feed(fw, [frame(k) for k in range(2000)])
    feed(fw, [frame(k) for k in range(0, 6)])
    assert fw.counters["imu_time_resync"] == 1 and fw.counters["imu_resync_refused"] == 0
    assert fw.clock.now_s() == pytest.approx(5 * PERIOD_US / 1e6)


# -- SET_OUTPUT_RATE ---------------------------------------------------------------------------------------------

@pytest.mark.parametrize("rate, accepted", [(1e-30, False), (0.05, False), (OUTPUT_RATE_MIN_HZ, True), (0.0, True),
                                            (100.0, True), (400.0, False), (float("inf"), False), (-10.0, False),
                                            (float("nan"), False), (3.0, False)])
def test_set_output_rate_outside_its_range_is_refused_and_counted(rate: float, accepted: bool) -> None:
    fw = Firmware(FirmwareConfig())
    feed(fw, [frame(k) for k in range(3)])
    fw.receive(UART_HOST, encode_command(SetOutputRate(7, rate)))
    acks = []
    dec = StreamDecoder([HostFormat()])
    fw.receive(UART_IMU, frame(3))
    for r in fw.service():
        for uart, data, _c in r.outputs:
            if uart == UART_HOST:
                acks += [f for f in dec.feed(data) if isinstance(f, Ack)]
    assert len(acks) == 1 and acks[0].token == 7
    assert acks[0].result == (AckResult.ACCEPTED if accepted else AckResult.BAD_ARGUMENT)
    assert fw.counters["commands_rejected_output_rate"] == (0 if accepted else 1)


def test_a_replay_after_a_jumped_frame_never_resyncs_the_clock() -> None:
    """One frame of a forward jump opens a run of candidates; the replayed stretch after it still lies in lived
    time and is refused frame by frame (a run may hold lived time only when it began at sequence 0)."""
    fw = Firmware(FirmwareConfig())
    feed(fw, [frame(k) for k in range(2000)])
    t_before = fw.clock.now_s()
    feed(fw, [frame(2000, t_us=2000 * PERIOD_US + 10_000_000)] + [frame(k) for k in range(600, 700)])
    assert fw.counters["imu_time_resync"] == 0 and fw.clock.now_s() == t_before
    assert fw.counters["input_rejected_imu_time_replay"] == 100
