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
    assert o.multipath_range_m < s.multipath_range_m < u.multipath_range_m
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


def test_environment_errors_follow_the_reported_hdop():
    base = GnssErrors(pos_sigma_h_m=3.5, pos_sigma_v_m=7.0, vel_sigma_h_mps=0.05, vel_sigma_v_mps=0.1)
    e = environment_errors(ENVIRONMENTS["urban_canyon"], base, hdop=4.0, hdop_receiver=0.8)
    # sigma = DOP x UERE: the receiver's figures (stated at HDOP 0.8) times 5, the canyon's 5 m range multipath
    # through HDOP 4 (per horizontal axis 4 x 5 / sqrt 2), vertically in the receiver's ratio 2
    assert (e.pos_sigma_h_m, e.pos_sigma_v_m) == pytest.approx((17.5, 35.0))
    assert e.multipath_sigma_h_m == pytest.approx(20.0 / math.sqrt(2.0))
    assert e.multipath_sigma_v_m == pytest.approx(40.0 / math.sqrt(2.0)) and e.multipath_corr_time_s == 30.0
    assert (e.vel_sigma_h_mps, e.vel_sigma_v_mps) == pytest.approx((0.25, 0.5))
    # twice the HDOP, twice every sigma
    e2 = environment_errors(ENVIRONMENTS["urban_canyon"], base, hdop=2.0, hdop_receiver=0.8)
    assert e.pos_sigma_h_m == pytest.approx(2 * e2.pos_sigma_h_m)
    assert e.multipath_sigma_h_m == pytest.approx(2 * e2.multipath_sigma_h_m)
    with pytest.raises(ValueError, match="HDOP"):
        environment_errors(ENVIRONMENTS["suburban"], base, hdop=0.0, hdop_receiver=0.8)


def test_the_receivers_error_follows_the_hdop_it_reports():
    """Over many runs of a suburban receiver, the horizontal error grows with the HDOP its GGA reports."""
    scn = load_scenario(ROOT / "scenarios" / "quickstart.yaml", overrides=["sensors.gnss.environment=suburban"])
    rows = []
    for seed in range(40):
        cfg = gnss_config(scn, seed)
        e = cfg.errors
        sig_h = math.hypot(e.pos_sigma_h_m, e.multipath_sigma_h_m)
        rows.append((cfg.hdop, sig_h))
    h, s = np.array(rows).T
    assert np.all((h >= 1.2) & (h <= 2.0))
    assert np.allclose(s / h, s[0] / h[0])  # one UERE: sigma / HDOP is the same in every run


def test_the_scenario_key_reaches_the_receiver_and_the_fix():
    scn = load_scenario(ROOT / "scenarios" / "quickstart.yaml", overrides=["sensors.gnss.environment=urban_canyon"])
    a, b = gnss_config(scn, 9), gnss_config(scn, 9)
    assert a.environment is not None and np.array_equal(a.environment.bias_enu, b.environment.bias_enu)
    assert 4 <= a.num_sats <= 7
    assert a.errors.multipath_sigma_h_m == pytest.approx(a.hdop * 5.0 / math.sqrt(2.0))
    plain = gnss_config(load_scenario(ROOT / "scenarios" / "quickstart.yaml"))
    assert plain.environment is None and plain.num_sats == 12


def test_the_receivers_gst_estimate_sees_its_multipath_through_its_residuals():
    """D-4.14: GST reports the receiver's figures plus the multipath as a chi-square estimate with ``(n - 4) x 10``
    degrees of freedom (mean the truth, relative spread sqrt(2 / k)); nothing with 4 satellites; an outlier episode
    adds its size while it lasts; the NLOS bias never shows."""
    from emulator.devices.gnss_environment import RESIDUAL_WINDOW_EPOCHS

    env = ENVIRONMENTS["urban_canyon"]
    e = environment_errors(env, GnssErrors(), hdop=3.0, hdop_receiver=0.8)
    proc = GnssEnvironmentProcess(env, np.random.default_rng(1), np.random.default_rng(2))
    k = 3 * RESIDUAL_WINDOW_EPOCHS
    draws = np.array([proc.reported_std_m(e, 7) for _ in range(4000)])
    f = (draws[:, 0] ** 2 - e.pos_sigma_h_m**2) / e.multipath_sigma_h_m**2
    assert f.mean() == pytest.approx(1.0, abs=0.03) and f.std() == pytest.approx(math.sqrt(2.0 / k), rel=0.1)
    assert np.all(draws[:, 0] == draws[:, 1])
    assert proc.reported_std_m(e, 4) == pytest.approx((e.pos_sigma_h_m, e.pos_sigma_h_m, e.pos_sigma_v_m))
    # without a stream of its own the estimate is the truth; an outlier episode widens it
    plain = GnssEnvironmentProcess(env, np.random.default_rng(1))
    h0 = math.hypot(e.pos_sigma_h_m, e.multipath_sigma_h_m)
    assert plain.reported_std_m(e, 6)[0] == pytest.approx(h0)
    plain.in_episode = True
    assert plain.reported_std_m(e, 6)[0] == pytest.approx(math.sqrt(h0**2 + env.nlos_sigma_h_m**2))


def test_gst_leaves_the_receivers_errors_unchanged():
    """The residual estimate draws from its own stream: a receiver that sends GST makes the same errors."""
    scn = load_scenario(ROOT / "scenarios" / "quickstart.yaml", overrides=["sensors.gnss.environment=urban_canyon"])
    a, b = gnss_config(scn, 5), gnss_config(scn, 5)
    assert a.environment is not None and b.environment is not None
    for _ in range(50):
        a.environment.reported_std_m(a.errors, a.num_sats)
    for t in range(1, 200):
        np.testing.assert_array_equal(a.environment.position_offset(float(t), 1.0),
                                      b.environment.position_offset(float(t), 1.0))
