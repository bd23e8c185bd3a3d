"""The GNSS antenna's surroundings (emulator/devices/gnss_environment.py): open sky, suburbs, urban canyon."""

from __future__ import annotations

import math

import numpy as np
import pytest

from emulator.devices.gnss import GnssErrors
from emulator.devices.gnss_environment import ENVIRONMENTS, GnssEnvironmentProcess, environment_errors
from emulator.devices.sensors import gnss_config
from emulator.scenario.loader import load_scenario
from tests.conftest import ROOT


def _offsets(name: str, seed: int, hours: float = 2.0) -> tuple[GnssEnvironmentProcess, np.ndarray]:
    p = GnssEnvironmentProcess(ENVIRONMENTS[name], np.random.default_rng(seed))
    return p, np.array([p.position_offset(float(t), 1.0) for t in range(int(hours * 3600))])


def test_environments_order_from_benign_to_hostile():
    o, s, u = (ENVIRONMENTS[k] for k in ("open_sky", "suburban", "urban_canyon"))
    assert o.multipath_sigma_h_m < s.multipath_sigma_h_m < u.multipath_sigma_h_m
    assert o.nlos_rate_hz == 0.0 < s.nlos_rate_hz < u.nlos_rate_hz
    assert o.num_sats[0] > s.num_sats[0] > u.num_sats[0] >= 4
    assert o.hdop[1] <= s.hdop[0] and s.hdop[1] <= u.hdop[0]


def test_urban_canyon_has_a_nlos_bias_outlier_episodes_and_poor_geometry():
    p, off = _offsets("urban_canyon", 3)
    bias_h = math.hypot(*p.bias_enu[:2])
    assert 3.0 <= bias_h <= 15.0 and p.bias_enu[2] == 0.0
    # episodes at ~1 per minute over 2 h, each 3-20 s: ~10 % of the fixes are outliers
    assert 80 < p.episodes < 170
    frac = p.outlier_fixes / len(off)
    assert 0.05 < frac < 0.2
    jumps = np.linalg.norm(off[:, :2] - p.bias_enu[:2], axis=1)
    assert np.percentile(jumps[jumps > 0], 50) > 10.0  # tens of metres (Hsu 2018)
    assert 4 <= p.num_sats <= 7 and 2.0 <= p.hdop <= 5.0


def test_open_sky_adds_nothing_but_geometry():
    p, off = _offsets("open_sky", 4, hours=0.5)
    assert np.all(off == 0.0) and p.episodes == 0 and p.num_sats >= 10


def test_environment_errors_replace_multipath_and_scale_velocity():
    e = environment_errors(ENVIRONMENTS["urban_canyon"], GnssErrors(vel_sigma_h_mps=0.05, vel_sigma_v_mps=0.1))
    assert (e.multipath_sigma_h_m, e.multipath_corr_time_s) == (5.0, 30.0)
    assert e.vel_sigma_h_mps == pytest.approx(0.2)


def test_the_scenario_key_reaches_the_receiver_and_the_fix():
    scn = load_scenario(ROOT / "scenarios" / "quickstart.yaml", overrides=["sensors.gnss.environment=urban_canyon"])
    a, b = gnss_config(scn, 9), gnss_config(scn, 9)
    assert a.environment is not None and np.array_equal(a.environment.bias_enu, b.environment.bias_enu)
    assert 4 <= a.num_sats <= 7 and a.errors.multipath_sigma_h_m == 5.0
    plain = gnss_config(load_scenario(ROOT / "scenarios" / "quickstart.yaml"))
    assert plain.environment is None and plain.num_sats == 12
