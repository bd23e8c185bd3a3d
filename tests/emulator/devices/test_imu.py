"""IMU error model: Allan deviation of a 2 h static record, deterministic terms, words, presets."""

from __future__ import annotations

import math

import numpy as np
import pytest

from emulator.devices.imu import (
    AccelErrors,
    FlickerBank,
    GyroErrors,
    ImuTemperature,
    InertialErrorModel,
    accel_error_model,
    allan_deviation,
    gyro_error_model,
)
from emulator.scenario.presets import preset, preset_names
from emulator.scenario.schema import Scenario
from protocols.constants import DEG, DPH

G = 9.80665


def fit_arw_and_b(y, dt, tau_c=600.0):
    """Least-squares fit of the measured Allan variance to ``N^2/tau + B^2 U(tau)`` per axis.

    ``U`` is the Allan variance of the flicker bank for B = 1 (the configured noise *shape*); the fit
    returns the white-noise density N and the bias instability B that the record actually contains.
    Relative weighting, tau from 0.01 s to 300 s (at least 24 clusters in 2 h).
    """
    taus = np.logspace(-2, math.log10(300), 36)
    T, ad = allan_deviation(y, dt, taus)
    u = FlickerBank(np.ones(1), tau_c).allan_variance(T)[:, 0]
    a = np.stack([1.0 / T, u], axis=1)
    n_est, b_est = [], []
    for k in range(ad.shape[1]):
        w = 1.0 / ad[:, k] ** 2
        coef, *_ = np.linalg.lstsq(a * w[:, None], ad[:, k] ** 2 * w, rcond=None)
        n_est.append(math.sqrt(max(coef[0], 0.0)))
        b_est.append(math.sqrt(max(coef[1], 0.0)))
    return np.array(n_est), np.array(b_est)


def test_gyro_allan_deviation_of_2h_static_record_matches_arw_and_bias_instability():
    e = GyroErrors()  # paper preset figures: ARW 0.15 deg/sqrt(h), B = 20/3 deg/h
    m = gyro_error_model(e, np.random.default_rng(3))
    dt = 0.005
    y = m.noise(int(2 * 3600 / dt), dt)  # the same block generator the device uses
    n_est, b_est = fit_arw_and_b(y, dt)
    arw = n_est / (DEG / 60.0)
    b = b_est / DPH
    assert np.all(np.abs(arw / e.arw_deg_rt_h - 1) < 0.2), arw
    assert np.all(np.abs(b / e.bias_instability_deg_h - 1) < 0.2), b


def test_accel_allan_deviation_matches_vrw_and_bias_instability():
    e = AccelErrors()
    m = accel_error_model(e, np.random.default_rng(4))
    dt = 0.005
    y = m.noise(int(2 * 3600 / dt), dt)
    n_est, b_est = fit_arw_and_b(y, dt)
    assert np.all(np.abs(n_est / (e.noise_ug_rt_hz * 1e-6 * G) - 1) < 0.2)
    assert np.all(np.abs(b_est / (np.array(e.bias_instability_mg) * 1e-3 * G) - 1) < 0.2)


def test_rate_random_walk_slope():
    e = GyroErrors(arw_deg_rt_h=0.0, bias_instability_deg_h=0.0, rate_random_walk_deg_h_rt_h=30.0)
    m = gyro_error_model(e, np.random.default_rng(5))
    dt = 0.05
    y = m.noise(int(4 * 3600 / dt), dt)
    T, ad = allan_deviation(y, dt, np.array([10.0, 30.0, 100.0, 300.0]))
    k_est = np.median(ad / np.sqrt(T[:, None] / 3.0), axis=0) / (DPH / 60.0)
    assert np.all(np.abs(k_est / 30.0 - 1) < 0.2)


def test_flicker_bank_is_calibrated_to_the_allan_floor():
    fb = FlickerBank(np.array([1.0]), 600.0)
    T = np.logspace(0, 2.6, 50)
    ad = np.sqrt(fb.allan_variance(T))[:, 0]
    assert ad.max() == pytest.approx(FlickerBank.FLOOR, rel=1e-3)
    assert ad.min() > 0.8 * FlickerBank.FLOOR  # flat within the band


def test_deterministic_terms():
    rng = np.random.default_rng(1)
    e = GyroErrors(arw_deg_rt_h=0, bias_instability_deg_h=0, bias_repeatability_deg_h=0, g_sensitivity_deg_h_per_g=0,
                   bias_temp_gradient_deg_h=0, scale_factor_ppm=1000, misalignment_mrad=1, scale_asymmetry_ppm=0,
                   nonlinearity_ppm_fs=0)
    m = gyro_error_model(e, rng)
    x = np.array([0.3, -0.2, 0.1])
    assert np.allclose(m.measure(x, 0.005), m.m @ x)
    assert np.allclose(np.diag(m.m) - 1, np.diag(m.m) - 1) and np.max(np.abs(np.diag(m.m) - 1)) < 5e-3
    # nonlinearity is zero at 0 and at full scale, and peaks at the configured fraction of FS
    e2 = GyroErrors(arw_deg_rt_h=0, bias_instability_deg_h=0, bias_repeatability_deg_h=0, g_sensitivity_deg_h_per_g=0,
                    bias_temp_gradient_deg_h=0, scale_factor_ppm=0, misalignment_mrad=0, scale_asymmetry_ppm=0,
                    nonlinearity_ppm_fs=200)
    m2 = gyro_error_model(e2, np.random.default_rng(2))
    fs = 400 * DEG
    for v in (0.0, fs, -fs):
        assert np.allclose(m2.measure(np.full(3, v), 0.005), v, atol=1e-15)
    peak = m2.measure(np.full(3, fs / math.sqrt(3)), 0.005) - fs / math.sqrt(3)
    assert np.allclose(np.abs(peak), np.abs(m2.nl), rtol=1e-12)
    # asymmetry: different scale for positive and negative rates
    e3 = GyroErrors(arw_deg_rt_h=0, bias_instability_deg_h=0, bias_repeatability_deg_h=0, g_sensitivity_deg_h_per_g=0,
                    bias_temp_gradient_deg_h=0, scale_factor_ppm=0, misalignment_mrad=0, scale_asymmetry_ppm=500,
                    nonlinearity_ppm_fs=0)
    m3 = gyro_error_model(e3, np.random.default_rng(3))
    pos, neg = m3.measure(np.full(3, 1.0), 0.005), m3.measure(np.full(3, -1.0), 0.005)
    assert np.allclose(pos + neg, 2 * m3.asym)


def test_temperature_gradient_and_g_sensitivity_biases():
    e = GyroErrors(arw_deg_rt_h=0, bias_instability_deg_h=0, bias_repeatability_deg_h=0, scale_factor_ppm=0,
                   misalignment_mrad=0, scale_asymmetry_ppm=0, nonlinearity_ppm_fs=0, bias_temp_gradient_deg_h=10,
                   g_sensitivity_deg_h_per_g=10)
    m = gyro_error_model(e, np.random.default_rng(8))
    f = np.array([0.0, 0.0, G])
    still = m.measure(np.zeros(3), 0.005, 25.0, 0.0, 25.0, None)
    assert np.allclose(still, 0.0)
    ramp = m.measure(np.zeros(3), 0.005, 30.0, 1.0, 25.0, None)
    assert np.allclose(ramp, m.temp_gradient)
    gs = m.measure(np.zeros(3), 0.005, 25.0, 0.0, 25.0, f)
    assert np.allclose(gs, m.g_sens @ f)
    assert ImuTemperature(20.0, 2.0).at(60.0) == 22.0


def test_perfect_preset_is_exact_and_paper_preset_uses_3_sigma():
    p = preset("imu", "perfect")
    assert all(v == 0 for k, v in p["gyro"].items() if k not in ("range_dps", "bias_corr_time_s"))
    paper = preset("imu", "paper")
    assert paper["gyro"]["bias_repeatability_deg_h"] == pytest.approx(40 / 3)
    assert paper["gyro"]["bias_instability_deg_h"] == pytest.approx(20 / 3)
    assert paper["gyro"]["nonlinearity_ppm_fs"] == pytest.approx(200 / 3)
    assert paper["accel"]["bias_instability_mg"] == pytest.approx([1.0, 4 / 3, 4 / 3])
    assert {"paper", "perfect", "stim210_datasheet"} <= set(preset_names("imu"))
    # defaults of the dataclasses are the paper preset
    for k, v in paper["gyro"].items():
        assert getattr(GyroErrors(), k) == pytest.approx(v, rel=1e-8), k


def scenario(**sensors):
    return Scenario.model_validate({"name": "t", "epoch": "2019-09-18T08:14:00Z", "duration_s": 10,
                                    "origin": {"lat_deg": 39.979, "lon_deg": 116.339}, "sensors": sensors})


def test_scenario_overrides_apply_on_top_of_the_preset():
    from emulator.devices.sensors import accel_errors, gyro_errors

    scn = scenario(imu={"preset": "stim210_datasheet", "gyro": {"arw_deg_rt_h": 0.3}, "accel": {"noise_ug_rt_hz": 50}})
    g = gyro_errors(scn)
    assert g.arw_deg_rt_h == 0.3 and g.bias_instability_deg_h == 0.5
    assert accel_errors(scn).noise_ug_rt_hz == 50
    with pytest.raises(ValueError, match="unknown imu preset"):
        scenario(imu={"preset": "nonsense"})


def test_perfect_gyro_words_are_truth_quantized():
    import asyncio

    from emulator.clock import EmulatorLoop
    from emulator.devices.imu import ImuTruthTap, Stim210Gyro
    from emulator.links import LineConfig, MemHub
    from emulator.world.trajectory import StaticTrajectory
    from protocols.stim import GYRO_RATE_LSB_DPS, Stim210Format
    from protocols.stream import StreamDecoder

    loop = EmulatorLoop("fast")
    a, b = MemHub().pair("gyro", LineConfig(baud=460800), loop)
    traj = StaticTrajectory(39.979, 116.339, 50.0, 30.0)
    errs = GyroErrors(**{k: v for k, v in preset("imu", "perfect")["gyro"].items()})
    gyro = Stim210Gyro(a, ImuTruthTap(traj), np.random.default_rng(1), errs)
    dec = StreamDecoder([Stim210Format("m")])
    got = []
    b.on_receive = lambda d: got.extend(dec.feed(d))

    async def main():
        for k in range(1, 11):
            gyro.trigger(k * 0.005, (k - 1) * 0.005)
        await asyncio.sleep(0.1)

    loop.run_until_complete(main())
    loop.close()
    assert len(got) == 10
    w = traj.angular_rate(0.0) / DEG / GYRO_RATE_LSB_DPS
    for d in got:
        assert d.gyro == tuple(round(x) for x in w)
    assert [d.counter for d in got] == [(10 * k) & 0xFF for k in range(1, 11)]


def test_inertial_model_blocks_are_continuous():
    """Per-sample calls consume one vectorised block after another without resetting the processes."""
    e = GyroErrors(arw_deg_rt_h=0.0, bias_instability_deg_h=50.0, bias_repeatability_deg_h=0.0)
    m = gyro_error_model(e, np.random.default_rng(9))
    seq = np.array([m.next_noise(0.005) for _ in range(1000)])
    jumps = np.abs(np.diff(seq, axis=0))
    assert jumps[199].max() < 10 * np.median(jumps)  # no discontinuity at the block boundary
    assert isinstance(m, InertialErrorModel)


@pytest.mark.parametrize("lp_filter_hz", [262.0, 16.0])
def test_first_datagrams_after_the_filter_delay_integrate_a_whole_interval(lp_filter_hz):
    """Issue 36 item 6: with the low-pass group delay the first trigger's interval lies before t = 0; it used to be
    clipped to 1 ns (80-140 deg/s of white noise with STATUS 0, a 0.7 deg step for a DSP integrating from frame 0).
    Every datagram from the first on integrates a whole 5 ms interval: its rate is the truth within the white
    noise of 5 ms at the STIM210's ARW (0.15 deg/sqrt(h): 0.035 deg/s rms), not within 1000 times that."""
    import asyncio

    from emulator.clock import EmulatorLoop
    from emulator.devices.imu import ImuTruthTap, Stim210Gyro
    from emulator.devices.imu.lookahead import delayed_interval
    from emulator.links import LineConfig, MemHub
    from emulator.world.trajectory import StaticTrajectory
    from protocols.stim import GYRO_RATE_LSB_DPS, Stim210Format
    from protocols.stream import StreamDecoder

    period = 0.005
    delay = math.sqrt(2.0) / (2.0 * math.pi * lp_filter_hz)
    assert delayed_interval(0.0, -period, delay) == (period, 0.0)  # before the start: the first interval
    t1, t0 = delayed_interval(10 * period, 9 * period, delay)
    assert t1 - t0 == pytest.approx(period) and t0 == pytest.approx(9 * period - delay)
    loop = EmulatorLoop("fast")
    a, b = MemHub().pair("gyro", LineConfig(baud=460800), loop)
    traj = StaticTrajectory(39.979, 116.339, 50.0, 30.0)
    errs = GyroErrors(**{**preset("imu", "perfect")["gyro"], "arw_deg_rt_h": 0.15})
    gyro = Stim210Gyro(a, ImuTruthTap(traj), np.random.default_rng(1), errs, lp_filter_hz=lp_filter_hz)
    dec = StreamDecoder([Stim210Format("m")])
    got = []
    b.on_receive = lambda d: got.extend(dec.feed(d))

    async def main():
        for k in range(0, 40):  # the FPGA's first trigger is at t = 0 (its interval starts one period earlier)
            gyro.trigger(k * period, (k - 1) * period)
        await asyncio.sleep(0.3)

    loop.run_until_complete(main())
    loop.close()
    assert len(got) == 40
    truth = traj.angular_rate(0.0) / DEG
    err = np.array([d.gyro for d in got]) * GYRO_RATE_LSB_DPS - truth  # deg/s
    sigma = 0.15 / 60.0 / math.sqrt(period)  # ARW over one interval, deg/s
    assert np.all(np.abs(err[:3]) < 5.0 * sigma), err[:3]  # the first datagrams: no 1 ns interval
    assert np.std(err) == pytest.approx(sigma, rel=0.3)
    assert all(d.status == 0 for d in got)


def test_a_fixed_turn_on_bias_replaces_the_draw_and_leaves_the_rest_of_the_unit():
    """The envelope draws a unit's turn-on bias itself (up to 7 mg, 40 deg/h): the figure replaces the draw from
    the repeatability, and every other constant of the unit stays what that seed drew."""
    drawn = accel_error_model(AccelErrors(), np.random.default_rng(3))
    fixed = accel_error_model(AccelErrors(turn_on_bias_mg=(7.0, -6.5, 0.25)), np.random.default_rng(3))
    np.testing.assert_allclose(fixed.bias0 / (1e-3 * G), [7.0, -6.5, 0.25])
    np.testing.assert_array_equal(fixed.m, drawn.m)
    g = gyro_error_model(GyroErrors(turn_on_bias_deg_h=(40.0, 0.0, -12.0)), np.random.default_rng(3))
    np.testing.assert_allclose(g.bias0 / DPH, [40.0, 0.0, -12.0])
