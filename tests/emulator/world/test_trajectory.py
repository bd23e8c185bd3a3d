"""Truth trajectory: kinematic consistency and a perfect IMU through the firmware's strapdown."""

from __future__ import annotations

import math

import numpy as np
import pytest

from emulator.errors import ScenarioError
from emulator.scenario.world_schema import MotionSegment
from emulator.world.build import trajectory_from_segments
from emulator.world.trajectory import StaticTrajectory, _gravity, euler_to_cbn
from firmware_model import earth
from firmware_model.attitude import a2mat, mat2q
from firmware_model.strapdown import NavState, coning_sculling, strapdown_step

LAT, LON, H = 39.979, 116.339, 50.0

MANOEUVRES = [
    {"static": {"duration_s": 10}},
    {"accelerate": {"duration_s": 20, "to_speed_mps": 30}},
    {"turn": {"rate_dps": 6, "angle_deg": 90}},
    {"cruise": {"duration_s": 15}},
    {"climb": {"duration_s": 30, "vertical_speed_mps": 3, "transition_s": 4}},
    {"roll": {"by_deg": 20, "rate_dps": 10, "duration_s": 5}},
    {"turn": {"rate_dps": 3, "angle_deg": -120}},
    {"roll": {"to_deg": 0, "rate_dps": 10, "duration_s": 5}},
    {"pitch": {"by_deg": 5, "rate_dps": 2, "duration_s": 6}},
    {"pitch": {"by_deg": -5, "rate_dps": 2, "duration_s": 6}},
    {"descend": {"duration_s": 30, "vertical_speed_mps": 3}},
    {"accelerate": {"duration_s": 10, "accel_mps2": 1.5}},
]


def segments(items):
    return [MotionSegment(**d) for d in items]


def manoeuvring(duration):
    return trajectory_from_segments(segments(MANOEUVRES), LAT, LON, H, 30.0, 0.0, 0.0, duration=duration)


def pos_error_m(pos, truth_pos):
    rm, rn = earth.radii(truth_pos[0])
    return np.array([(pos[1] - truth_pos[1]) * (rn + truth_pos[2]) * math.cos(truth_pos[0]),
                     (pos[0] - truth_pos[0]) * (rm + truth_pos[2]), pos[2] - truth_pos[2]])


def gravity_model_height(traj, t):
    """Height error (m) a perfect strapdown accumulates by ``t`` from the world's and the firmware's normal-gravity
    models alone: ``d2(dh)/dt2 = dg + (2 g / R) dh`` gives ``dg / w_s^2 (cosh(w_s t) - 1)``."""
    st = traj.state(0.0)
    lat0, h0 = float(st.pos[0]), float(st.pos[2])
    dg = float(_gravity(np.array(lat0), np.array(h0))) - earth.gravity(lat0, h0)
    w_s = math.sqrt(2.0 * earth.gravity(lat0, h0) / earth.A_WGS84)
    return dg / w_s**2 * (math.cosh(w_s * t) - 1.0)


def run_strapdown(traj, duration, T=0.005, dtype=np.float64, samples=1):
    """Feed exact 200 Hz increments to firmware_model.strapdown (``samples`` per update, 1 or 2 with
    two-sample coning/sculling); return the max position error against truth (m).

    The world's normal gravity (Somigliana, TR8350.2) is not the firmware's (the PSINS series): their difference
    ``dg`` drives the strapdown's unstable vertical channel, ``d2(dh)/dt2 = dg + (2 g / R) dh``, so the height
    error expected from the model difference alone, ``dg / w_s^2 (cosh(w_s t) - 1)``, is removed before the bound
    (a trajectory inconsistency would not follow that curve)."""
    st = traj.state(0.0)
    lat0, h0 = float(st.pos[0]), float(st.pos[2])
    dg = float(_gravity(np.array(lat0), np.array(h0))) - earth.gravity(lat0, h0)
    w_s = math.sqrt(2.0 * earth.gravity(lat0, h0) / earth.A_WGS84)
    s = NavState(mat2q(st.c_bn).astype(dtype), st.v_enu.astype(dtype), st.pos.copy(), a_prev=np.zeros(3, dtype))
    n = round(duration / (T * samples))
    worst = 0.0
    for k in range(1, n + 1):
        first = samples * (k - 1)
        incs = [traj.imu_increments((first + j) * T, (first + j + 1) * T) for j in range(samples)]
        phi, dvm = coning_sculling(np.array([a for a, _ in incs]), np.array([b for _, b in incs]))
        strapdown_step(s, phi, dvm, T * samples, dtype)
        if k % (200 // samples) == 0 or k == n:
            t = k * T * samples
            err = pos_error_m(s.pos, traj.state(t).pos)
            err[2] -= dg / w_s**2 * (math.cosh(w_s * t) - 1.0)
            worst = max(worst, float(np.linalg.norm(err)))
    return worst


def test_gravity_is_the_worlds_own_and_agrees_with_the_firmware_series():
    """The world uses the closed Somigliana formula (TR8350.2), the firmware the PSINS series: the two are
    independent models of the same WGS-84 normal gravity and agree to the series' truncation (< 2e-4 m/s^2)."""
    lat = np.linspace(-1.5, 1.5, 7)
    h = np.linspace(-100, 9000, 7)
    fw = np.array([earth.gravity(a, b) for a, b in zip(lat, h)])
    assert np.allclose(_gravity(lat, h), fw, rtol=0, atol=2e-4)
    assert not np.allclose(_gravity(lat, h), fw, rtol=0, atol=1e-12)


def test_euler_to_cbn_matches_a2mat():
    rng = np.random.default_rng(3)
    ang = rng.uniform(-1.5, 1.5, (5, 3))
    c = euler_to_cbn(ang[:, 0], ang[:, 1], ang[:, 2])
    for i in range(5):
        assert np.allclose(c[i], a2mat(*ang[i]), atol=1e-15)


def test_static_strapdown_10_min_below_1_m():
    traj = StaticTrajectory(LAT, LON, H, heading_deg=30.0, pitch_deg=2.0, roll_deg=-1.0)
    assert run_strapdown(traj, 600.0) < 1.0


def test_static_segments_strapdown_10_min_below_1_m():
    # a static segment followed by an in-place rotation (turntable), then static: still < 1 m
    traj = trajectory_from_segments(segments([{"static": {"duration_s": 100}},
                                              {"turn": {"rate_dps": 10, "angle_deg": 90}},
                                              {"static": {"duration_s": 491}}]),
                                    LAT, LON, H, 30.0, 2.0, -1.0, duration=600)
    assert run_strapdown(traj, 600.0, samples=2) < 1.0


def test_manoeuvring_strapdown_fast_below_5_m():
    traj = manoeuvring(200.0)
    assert run_strapdown(traj, 200.0) < 5.0
    assert run_strapdown(traj, 200.0, samples=2) < 5.0


def test_manoeuvring_strapdown_10_min_below_5_m():  # ~12 s: fast enough for the default run
    traj = manoeuvring(600.0)  # the segments end at 202 s; the rest is a 31.5 m/s hold
    err = run_strapdown(traj, 600.0)
    assert err < 5.0


def test_kinematics_are_mutually_consistent():
    """omega_nb^b from dC/dt, a^n from dv/dt, position rate from v, by central differences."""
    traj = manoeuvring(200.0)
    h = 1e-4
    for t in (25.0, 40.0, 75.0, 96.0, 104.0, 130.0, 150.0, 165.0):
        ev = traj.sample(np.array([t - h, t, t + h]))
        c0, c1, c2 = ev["c_bn"]
        dc = (c2 - c0) / (2 * h)
        w_nb = c1.T @ dc  # skew(omega_nb^b)
        lat, hgt = ev["pos"][1, 0], ev["pos"][1, 2]
        v = ev["v"][1]
        w_in = earth.omega_ie_n(lat) + earth.omega_en_n(lat, hgt, v)
        w_ib = np.array([w_nb[2, 1], w_nb[0, 2], w_nb[1, 0]]) + c1.T @ w_in
        assert np.allclose(w_ib, ev["w_ib_b"][1], atol=1e-8), t
        a_n = (ev["v"][2] - ev["v"][0]) / (2 * h)
        f_n = a_n - earth.gravity_n(lat, hgt) + np.cross(2 * earth.omega_ie_n(lat) + earth.omega_en_n(lat, hgt, v), v)
        assert np.allclose(c1.T @ f_n, ev["f_b"][1], atol=1e-6), t
        dp = (ev["pos"][2] - ev["pos"][0]) / (2 * h)
        assert np.allclose(dp, earth.m_pv(lat, hgt) @ v, rtol=1e-5, atol=1e-12), t  # float64 differencing


def test_block_increments_equal_exact_and_fine_quadrature():
    traj = manoeuvring(200.0)
    T = 0.005
    for k in (0, 1999, 2000, 2001, 6000, 12345, 39999):
        a, b = traj.imu_increments(k * T, (k + 1) * T)
        ea, eb = traj.imu_increments_exact(k * T, (k + 1) * T)
        assert np.allclose(a, ea, rtol=0, atol=1e-15) and np.allclose(b, eb, rtol=0, atol=1e-13)
        # fine composite Simpson on 1 kHz x 50 sub-samples as an independent check
        # (the last node is nudged inside the interval: at a phase boundary f^b jumps)
        ts = np.linspace(k * T, (k + 1) * T - 1e-12, 251)
        ev = traj.sample(ts)
        wts = np.ones(251)
        wts[1:-1:2], wts[2:-1:2] = 4, 2
        wts *= (ts[1] - ts[0]) / 3
        assert np.allclose(wts @ ev["w_ib_b"], a, atol=1e-14)
        assert np.allclose(wts @ ev["f_b"], b, atol=1e-11)


def test_segment_state_is_continuous_and_reports_euler_angles():
    traj = manoeuvring(200.0)
    st = traj.state(0.0)
    assert math.isclose(math.degrees(st.heading), 30.0, abs_tol=1e-12)
    # after the 90 deg right turn the heading is 120 deg and the speed is 30 m/s
    t_after_turn = 10 + 20 + 15 + 1
    st = traj.state(t_after_turn)
    assert math.isclose(math.degrees(st.heading), 120.0, abs_tol=1e-9)
    assert math.isclose(float(np.linalg.norm(st.v_enu)), 30.0, rel_tol=1e-12)
    # climb: vertical speed 3 m/s in the hold, level again at the end
    st = traj.state(10 + 20 + 15 + 15 + 15)
    assert math.isclose(float(st.v_enu[2]), 3.0, rel_tol=1e-9)
    st = traj.state(10 + 20 + 15 + 15 + 30 + 0.5)
    assert abs(st.pitch) < 1e-12 and math.isclose(math.degrees(st.roll), 5.0, rel_tol=1e-9)
    for t in np.linspace(0.0, 199.99, 400):
        a, b = traj.state(float(t)), traj.state(float(t) + 1e-6)
        assert np.linalg.norm(pos_error_m(a.pos, b.pos)) < 1e-4


def test_motion_errors_name_the_segment():
    with pytest.raises(ScenarioError, match=r"motion\[2\]\.static"):
        trajectory_from_segments(segments([{"static": {"duration_s": 1}},
                                           {"accelerate": {"duration_s": 5, "to_speed_mps": 3}},
                                           {"static": {"duration_s": 1}}]), LAT, LON, H)
    with pytest.raises(ScenarioError, match="vertical_speed_mps"):
        trajectory_from_segments(segments([{"climb": {"duration_s": 10, "vertical_speed_mps": 3}}]), LAT, LON, H)
    with pytest.raises(ScenarioError, match="limit 89"):
        trajectory_from_segments(segments([{"pitch": {"by_deg": 95, "rate_dps": 10}}]), LAT, LON, H)


def test_schema_durations_and_validation():
    assert MotionSegment(turn={"rate_dps": 3, "angle_deg": -90}).duration_s == 30.0
    assert MotionSegment(pitch={"by_deg": -10, "rate_dps": 5}).duration_s == 2.0
    assert MotionSegment(static={"duration_s": 7}).duration_s == 7.0
    with pytest.raises(ValueError):
        MotionSegment(turn={"rate_dps": 3})
    with pytest.raises(ValueError):
        MotionSegment(pitch={"to_deg": 3, "rate_dps": 1})
    with pytest.raises(ValueError):
        MotionSegment(accelerate={"duration_s": 3})
