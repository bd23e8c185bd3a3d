"""The field error models: suite presets, Zhang's DOP law, STIM210 filter delay, GNSS multipath, iron."""

from __future__ import annotations

import datetime as dt
import math

import numpy as np
import pytest

from emulator.devices.compass import CompassConfig, CompassModel, zhang_aop_error_deg
from emulator.devices.gnss import GnssErrorModel, GnssErrors
from emulator.devices.imu.stim210 import group_delay_s
from emulator.devices.sensors import compass_config, gnss_config, gyro_errors, gyro_lp_filter_hz, mag_config
from emulator.scenario.sensor_schema import Sensors, preset_of
from emulator.world.sky import SkyModel
from emulator.world.sun import SunModel
from emulator.world.trajectory import StaticTrajectory
from protocols.constants import DEG


class _Scn:
    def __init__(self, sensors: Sensors) -> None:
        self.sensors = sensors


def test_suite_preset_picks_each_sensor_preset_and_a_sensor_preset_wins():
    s = Sensors.model_validate({"preset": "field", "imu": {"preset": "paper"}})
    assert preset_of(s, "imu", s.imu) == "paper"
    assert preset_of(s, "gnss", s.gnss) == "field" and preset_of(s, "compass", None) == "field"
    ideal = Sensors.model_validate({"preset": "ideal"})
    assert gyro_errors(_Scn(ideal)).arw_deg_rt_h == 0.0  # type: ignore[arg-type]
    f = _Scn(Sensors.model_validate({"preset": "field"}))
    assert gyro_lp_filter_hz(f) == 262.0  # type: ignore[arg-type]
    assert gnss_config(f).errors.multipath_sigma_h_m > 0  # type: ignore[arg-type]
    assert compass_config(f).dop_noise_model == "zhang"  # type: ignore[arg-type]
    assert np.any(mag_config(f).soft_iron != np.eye(3))  # type: ignore[arg-type]
    with pytest.raises(ValueError):
        Sensors.model_validate({"preset": "lab"})


def test_zhang_law_reproduces_the_measured_bins_and_is_not_inverse_dop():
    mean, sd = zhang_aop_error_deg(np.array([0.275, 0.525]))
    assert mean == pytest.approx([2.05, 0.14]) and sd == pytest.approx([2.38, 0.17])
    m5, _ = zhang_aop_error_deg(np.array([0.5]))
    m27, _ = zhang_aop_error_deg(np.array([0.27]))
    assert 10.0 < m27[0] / m5[0] < 18.0  # 1/DOP would give 1.85x


def test_zhang_compass_errors_match_the_law_in_a_reading():
    traj = StaticTrajectory(39.98, 116.34, 50.0, 10.0, 0.0, 0.0)
    sun = SunModel(dt.datetime(2019, 9, 18, 8, 14, tzinfo=dt.UTC), 69.0)
    cfg_true = CompassConfig(noise=False)
    ref = CompassModel(cfg_true, SkyModel(), sun, traj, np.random.default_rng(0)).read(0.0)
    cm = CompassModel(CompassConfig(dop_noise_model="zhang"), SkyModel(), sun, traj, np.random.default_rng(3))
    errs = []
    for _ in range(400):
        r = cm.read(0.0)
        d = (r.aop - ref.aop + math.pi / 2) % math.pi - math.pi / 2
        errs.append(np.degrees(d))
    e = np.array(errs)
    mean, sd = zhang_aop_error_deg(ref.dop)
    assert np.allclose(np.abs(e.mean(axis=0)), mean, atol=0.05 + 0.2 * mean)
    assert np.allclose(e.std(axis=0), sd, rtol=0.2)


def test_stim_group_delay_follows_the_filter_setting():
    assert group_delay_s(262.0) == pytest.approx(0.859e-3, rel=1e-3)
    assert group_delay_s(16.0) == pytest.approx(14.07e-3, rel=1e-3)
    assert group_delay_s(0.0) == 0.0


def test_gnss_multipath_adds_a_fast_correlated_error_and_jumps_on_reacquisition():
    e = GnssErrors(pos_sigma_h_m=0.0, pos_sigma_v_m=0.0, pos_white_fraction=0.0, multipath_sigma_h_m=1.2,
                   multipath_sigma_v_m=2.0, multipath_corr_time_s=15.0)
    m = GnssErrorModel(e, np.random.default_rng(1), batch=4000)
    p = np.stack([m.step(1.0)[0] for _ in range(60)])  # (60, batch, 3)
    assert p[-1, :, 0].std() == pytest.approx(1.2, rel=0.08) and p[-1, :, 2].std() == pytest.approx(2.0, rel=0.08)
    lag1 = np.corrcoef(p[-2, :, 0], p[-1, :, 0])[0, 1]
    assert lag1 == pytest.approx(math.exp(-1.0 / 15.0), abs=0.03)
    before = m.mp.copy()
    m.restart()
    assert np.corrcoef(before[:, 0], m.mp[:, 0])[0, 1] == pytest.approx(0.0, abs=0.05)


def test_every_preset_figure_is_a_number():
    """PyYAML reads 1.0e12 (no exponent sign) as a string; the suite presets must build every sensor."""
    from emulator.scenario.presets import preset, preset_names

    def walk(x):
        if isinstance(x, dict):
            for v in x.values():
                walk(v)
        elif isinstance(x, list):
            for v in x:
                walk(v)
        else:
            assert not isinstance(x, str) or x in ("pinhole", "fisheye", "zhang", "inverse"), x

    for kind in ("imu", "gnss", "camera", "compass", "magnetometer"):
        for name in preset_names(kind):
            walk(preset(kind, name))


def test_stim_filter_delays_the_rate_and_fills_the_latency_field():
    """A 16 Hz filter (14.1 ms delay) during a rate ramp: each word is the rate one group delay earlier."""
    import asyncio

    from emulator.clock import EmulatorLoop
    from emulator.devices.imu import GyroErrors, Stim210Gyro
    from emulator.links import LineConfig, MemHub
    from emulator.scenario.presets import preset
    from protocols.stim import GYRO_RATE_LSB_DPS, Stim210Format
    from protocols.stream import StreamDecoder

    class Ramp:  # z rate = 10 deg/s^2 * t: the mean over [t0, t1] is 10 (t0 + t1) / 2 deg/s
        def increments(self, t0, t1):
            return np.array([0.0, 0.0, 5.0 * (t1 * t1 - t0 * t0) * DEG]), np.zeros(3)

        def specific_force(self, t):
            return np.zeros(3)

        def vibration_at(self, t):  # no vibration (ImuTruthTap's interface)
            return None

    loop = EmulatorLoop("fast")
    a, b = MemHub().pair("gyro", LineConfig(baud=460800), loop)
    errs = GyroErrors(**dict(preset("imu", "perfect")["gyro"].items()))
    gyro = Stim210Gyro(a, Ramp(), np.random.default_rng(1), errs, lp_filter_hz=16.0)  # type: ignore[arg-type]
    gyro._look_ahead = False
    dec = StreamDecoder([Stim210Format("m")])
    got = []
    b.on_receive = lambda d: got.extend(dec.feed(d))

    async def main():
        for k in range(10, 20):
            gyro.trigger(k * 0.005, (k - 1) * 0.005)
        await asyncio.sleep(0.1)

    loop.run_until_complete(main())
    loop.close()
    tau = group_delay_s(16.0)
    assert len(got) == 10
    for k, d in zip(range(10, 20), got):
        expect = 10.0 * ((k - 0.5) * 0.005 - tau) / GYRO_RATE_LSB_DPS
        assert d.gyro[2] == pytest.approx(expect, abs=1.0)
        assert d.latency_us == round((tau + 40e-6) * 1e6)


@pytest.mark.parametrize(("response_delay_s", "expect_us"), [(40e-6, 40), (86e-6, 86)])
def test_stim_latency_field_without_a_filter_is_the_response_delay(response_delay_s, expect_us):
    """TS1524: the latency field is sampling to start of transmission; with no low-pass filter (group delay 0) the
    datagram still reports the response delay, never 0 (issue 37, from the earlier round)."""
    import asyncio

    from emulator.clock import EmulatorLoop
    from emulator.devices.imu import Stim210Gyro
    from emulator.links import LineConfig, MemHub
    from protocols.stim import Stim210Format
    from protocols.stream import StreamDecoder

    class Still:
        def increments(self, t0, t1):
            return np.zeros(3), np.zeros(3)

        def specific_force(self, t):
            return np.zeros(3)

        def vibration_at(self, t):
            return None

    loop = EmulatorLoop("fast")
    a, b = MemHub().pair("gyro", LineConfig(baud=460800), loop)
    gyro = Stim210Gyro(a, Still(), np.random.default_rng(1), response_delay_s=response_delay_s)  # type: ignore[arg-type]
    gyro._look_ahead = False
    dec = StreamDecoder([Stim210Format("m")])
    got = []
    b.on_receive = lambda d: got.extend(dec.feed(d))

    async def main():
        for k in range(1, 4):
            gyro.trigger(k * 0.005, (k - 1) * 0.005)
        await asyncio.sleep(0.05)

    loop.run_until_complete(main())
    loop.close()
    assert [d.latency_us for d in got] == [expect_us] * 3
