"""The IMU models' look-ahead (a speed-up of the fast path) gives bit for bit the per-interval path's output.

:func:`emulator.devices.imu.lookahead.measure_ahead` computes the measured means of the coming trigger
intervals in one vectorised pass. The reference is the same device with the look-ahead switched
off: on a moving trajectory (turns, acceleration: the truth changes every interval), with every
error term of the ``paper`` preset, injected faults switched on and off mid-block, and a break
in the trigger grid, the gyro's datagrams and the accelerometers' ADC codes must be identical.
"""

from __future__ import annotations

import dataclasses
import types
from pathlib import Path

import numpy as np
import pytest

from emulator.devices.imu import AnalogAccelerometers, ImuTemperature, ImuTruthTap, Stim210Gyro
from emulator.devices.sensors import accel_errors, gyro_errors
from emulator.scenario import load_scenario
from emulator.scenario.presets import preset
from emulator.world.build import build_trajectory
from emulator.world.vibration import VibrationModel
from protocols.stim import STATUS_SAMPLE_INVALID, StimStatus

SCENARIOS = Path(__file__).resolve().parents[3] / "scenarios"


class _Link:
    def __init__(self) -> None:
        self.loop = types.SimpleNamespace(time=lambda: 0.0)
        self.out: list[tuple[float, bytes]] = []

    def send_at(self, t: float, data: bytes, atomic: bool = False) -> int:
        self.out.append((t, data))
        return len(data)


def _run(look_ahead: bool, temp: ImuTemperature, vibration: bool = False, lp_filter_hz: float = 0.0,
         fmt: str = "m", output: str = "rate",
         range_dps: float | None = None) -> tuple[list[tuple[float, bytes]], list[tuple[int, int, int]], bool]:
    scn = load_scenario(SCENARIOS / "vehicle_loop_gnss_outage.yaml")
    traj = build_trajectory(scn)
    vib = None
    if vibration:  # the field preset's profile at 4x its level, and the accelerometers' rectification
        prof = preset("imu", "field")["vibration"]
        vib = VibrationModel(prof["psd"], [4 * a for a in prof["axes"]], 200.0, np.random.default_rng(7))
    tap = ImuTruthTap(traj, vib)
    link = _Link()
    errors = gyro_errors(scn)
    if range_dps is not None:  # a narrow range: the vehicle's turns saturate it inside look-ahead windows
        errors = dataclasses.replace(errors, range_dps=range_dps)
    gyro = Stim210Gyro(link, tap, np.random.default_rng(5), errors, temperature=temp,  # type: ignore[arg-type]
                       lp_filter_hz=lp_filter_hz, fmt=fmt, output=output)
    accel = AnalogAccelerometers(tap, np.random.default_rng(6), accel_errors(scn), temperature=temp)
    gyro._look_ahead = accel._look_ahead = look_ahead
    period = 1.0 / 200.0
    codes = []
    for k in range(0, 1300):
        if 900 <= k < 905:  # a break in the trigger grid (the look-ahead must notice)
            continue
        t = k * period
        t_prev = t - period
        if k == 950:
            t_prev = (k - 1) * period  # an interval off the FPGA's grid
        if k == 130:
            gyro.set_bias_step("a", np.array([1e-3, 0.0, -2e-3]))
            accel.set_stuck_axis(1, True)
        if k == 170:
            gyro.set_bias_step("a", None)
            accel.set_stuck_axis(1, False)
        if k == 420:
            gyro.set_range_limit(0.1)
        if k == 460:
            gyro.set_range_limit(None)
        codes.append(accel.sample(t, t_prev))
        gyro.trigger(t, t_prev)
    return link.out, codes, gyro._ahead is not None


@pytest.mark.parametrize(("temp", "vibration", "lp_filter_hz"), [
    (ImuTemperature(), False, 0.0),
    (ImuTemperature(start_c=20.0, rate_c_per_min=1.5, cal_c=25.0), False, 0.0),
    (ImuTemperature(start_c=20.0, rate_c_per_min=0.5, cal_c=25.0, warmup_c=12.0, warmup_tau_s=3.0), True, 0.0),
    # the gyro's low-pass group delay (14 ms at 16 Hz): the measured intervals are off the trigger grid
    (ImuTemperature(start_c=20.0, rate_c_per_min=0.5, cal_c=25.0, warmup_c=12.0, warmup_tau_s=3.0), True, 16.0),
    (ImuTemperature(), False, 262.0),
])
def test_look_ahead_is_bit_identical_to_per_interval(temp: ImuTemperature, vibration: bool,
                                                     lp_filter_hz: float) -> None:
    ref_out, ref_codes, _ = _run(False, temp, vibration, lp_filter_hz)
    out, codes, gyro_ahead = _run(True, temp, vibration, lp_filter_hz)
    assert gyro_ahead  # the gyro took the look-ahead path (with or without the group delay)
    assert len(ref_out) == 1295
    assert codes == ref_codes
    assert out == ref_out
    # the run is not trivially constant: the vehicle turns, so the words change from tick to tick
    assert len({d for _t, d in ref_out}) > 1000


@pytest.mark.parametrize(("fmt", "output", "range_dps"), [
    ("p", "rate", None),  # temperature words (warming up: they change), counter and latency
    ("n", "angle", None),  # incremental angle over each (measured) interval
    ("m", "rate", 0.05),  # STATUS overload bits set inside the look-ahead windows, not only under faults
    ("j", "angle", 0.05),
])
def test_look_ahead_window_datagrams_are_the_per_trigger_bytes(fmt: str, output: str, range_dps: float | None,
                                                               monkeypatch: pytest.MonkeyPatch) -> None:
    """The gyro's window of datagrams (one :meth:`~protocols.stim.Stim210Format.build_window` per look-ahead
    block, D-10.E21) is byte for byte what the per-trigger path (a window of one) sends, in formats with
    temperature words, counters and latency, in both output modes and with axes saturating inside a window
    (STATUS overload with its channel bits, protocols.stim.overload_status), across faults switched on and off
    mid-block, a break in the trigger grid and an interval off the grid."""
    temp = ImuTemperature(start_c=20.0, rate_c_per_min=0.5, cal_c=25.0, warmup_c=12.0, warmup_tau_s=3.0)
    ref_out, _, _ = _run(False, temp, fmt=fmt, output=output, range_dps=range_dps)
    encode = Stim210Gyro._datagrams
    windows: list[int] = []

    def counted(self: Stim210Gyro, rate: np.ndarray, *args: object) -> tuple[bytes, np.ndarray]:
        windows.append(len(rate))
        return encode(self, rate, *args)  # type: ignore[arg-type]

    monkeypatch.setattr(Stim210Gyro, "_datagrams", counted)
    out, _, gyro_ahead = _run(True, temp, fmt=fmt, output=output, range_dps=range_dps)
    assert gyro_ahead
    # the windows served most triggers: per-trigger encodes only at a block's first row, under the faults
    # (k 130-170, 420-460) and around the grid's break and off-grid interval
    assert windows.count(1) < 120 and max(windows) > 100, windows
    assert out == ref_out
    assert len(ref_out) == 1295
    status = [d[10] for _t, d in ref_out]
    if range_dps is not None:  # the saturation is exercised, outside the fault window (k 420-460) as well
        over = [k for k, st in enumerate(status) if st & StimStatus.OVERLOAD]
        assert len(over) > 50 and any(k > 500 for k in over)
        assert all(st & STATUS_SAMPLE_INVALID for st in status if st)
    else:
        assert not any(s & StimStatus.OVERLOAD for s in status[:400])
    if fmt in ("p", "j"):  # the temperature words change along the run (warm-up)
        assert len({d[11:13] for _t, d in ref_out}) > 100
