"""The IMU's warm-up: T(t) = start + rise (1 - exp(-t/tau)) + rate t, its slope, and the biases that follow it."""

from __future__ import annotations

import math
import types
from pathlib import Path

import numpy as np
import pytest

from emulator.devices.imu import AccelErrors, AnalogAccelerometers, GyroErrors, ImuTemperature, ImuTruthTap, Stim210Gyro
from emulator.devices.sensors import imu_temperature
from emulator.scenario import load_scenario
from protocols.constants import DPH
from tests.emulator.still_truth import still_truth

SCENARIOS = Path(__file__).resolve().parents[3] / "scenarios"


def _closed(t: float, start: float, rise: float, tau: float, rate_min: float) -> tuple[float, float]:
    return (start + rise * (1.0 - math.exp(-t / tau)) + rate_min * t / 60.0,
            rate_min + 60.0 * rise / tau * math.exp(-t / tau))


@pytest.mark.parametrize("t", [0.0, 1.0, 60.0, 600.0, 1234.5, 3600.0, 36000.0])
def test_warm_up_profile_and_rate_follow_the_closed_form(t):
    temp = ImuTemperature(start_c=18.0, rate_c_per_min=-0.05, cal_c=25.0, warmup_c=12.0, warmup_tau_s=600.0)
    want_t, want_rate = _closed(t, 18.0, 12.0, 600.0, -0.05)
    assert temp.at(t) == pytest.approx(want_t, rel=1e-14, abs=1e-12)
    assert temp.rate_at(t) == pytest.approx(want_rate, rel=1e-14, abs=1e-15)
    # the rate is the derivative of the profile (central difference, degC/min)
    h = 1e-3
    assert temp.rate_at(t) == pytest.approx((temp.at(t + h) - temp.at(max(t - h, 0.0))) / (t + h - max(t - h, 0.0))
                                            * 60.0, rel=1e-6, abs=1e-9)


def test_without_warm_up_the_profile_is_the_linear_ramp():
    temp = ImuTemperature(20.0, 2.0)
    assert not temp.warms_up
    assert temp.at(60.0) == 22.0 and temp.rate_at(60.0) == 2.0 and temp.rate_at(0.0) == 2.0


class _Link:
    def __init__(self) -> None:
        self.loop = types.SimpleNamespace(time=lambda: 0.0)

    def send_at(self, t: float, data: bytes, atomic: bool = False) -> int:
        return len(data)


def test_gyro_gradient_bias_and_accel_temperature_bias_follow_the_warm_up():
    """A still IMU with only temperature errors: the gyro reads ``k_grad dT/dt`` and the accelerometers
    ``k_T (T - T_cal)``, the closed forms at every trigger of a 30 min warm-up."""
    temp = ImuTemperature(start_c=25.0, rate_c_per_min=0.0, cal_c=25.0, warmup_c=12.0, warmup_tau_s=600.0)
    tap = ImuTruthTap(still_truth())  # type: ignore[arg-type]
    ge = GyroErrors(arw_deg_rt_h=0, bias_repeatability_deg_h=0, bias_instability_deg_h=0, scale_factor_ppm=0,
                    scale_asymmetry_ppm=0, misalignment_mrad=0, nonlinearity_ppm_fs=0, g_sensitivity_deg_h_per_g=0,
                    bias_temp_gradient_deg_h=10.0)
    ae = AccelErrors(bias_repeatability_mg=(0, 0, 0), bias_instability_mg=(0, 0, 0), noise_ug_rt_hz=0,
                     scale_factor_ppm=(0, 0, 0), scale_error_ppm=(0, 0, 0), misalignment_mrad=0,
                     bias_temp_coeff_mg_per_c=0.1)
    rate = 10.0
    gyro = Stim210Gyro(_Link(), tap, np.random.default_rng(2), ge, trigger_rate_hz=rate,  # type: ignore[arg-type]
                       temperature=temp)
    acc = AnalogAccelerometers(tap, np.random.default_rng(3), ae, temperature=temp, trigger_rate_hz=rate)
    kg = gyro.model.temp_gradient
    ka = acc.model.temp_coeff
    assert np.all(np.abs(kg) > 0.5 * DPH) and np.all(np.abs(ka) > 0)
    first = None
    for k in range(1, int(1800 * rate) + 1):
        t = k / rate
        gyro.trigger(t, t - 1 / rate)
        acc.sample(t, t - 1 / rate)
        if k % 997 == 1 or k == int(1800 * rate):
            t_c, r = _closed(t, 25.0, 12.0, 600.0, 0.0)
            np.testing.assert_allclose(gyro.last_measured, kg * r, rtol=1e-12, atol=1e-18)
            np.testing.assert_allclose(acc.last_measured, ka * (t_c - 25.0), rtol=1e-9, atol=1e-15)
            if first is None:
                first = gyro.last_measured.copy()
    # the gradient bias decays with the warm-up: after 30 min (3 tau) it is exp(-3) of its start
    assert np.allclose(gyro.last_measured, first * math.exp(-(1800.0 - 0.1) / 600.0), rtol=1e-9)


def test_field_preset_warms_up_and_the_scenario_overrides_it():
    scn = load_scenario(SCENARIOS / "vehicle_loop_gnss_outage.yaml")
    temp = imu_temperature(scn)
    assert scn.sensors.preset == "field" and temp.warms_up
    assert (temp.warmup_c, temp.warmup_tau_s) == (12.0, 600.0)
    t2 = scn.sensors.imu.temperature.model_copy(update={"warmup_c": 0.0})
    imu = scn.sensors.imu.model_copy(update={"temperature": t2})
    scn2 = scn.model_copy(update={"sensors": scn.sensors.model_copy(update={"imu": imu})})
    assert not imu_temperature(scn2).warms_up
    paper = scn.model_copy(update={"sensors": scn.sensors.model_copy(update={"preset": "paper"})})
    assert not imu_temperature(paper).warms_up
