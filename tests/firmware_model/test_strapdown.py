"""Strapdown mechanization against closed-form truth."""

import math

import numpy as np
import pytest

from firmware_model import earth
from firmware_model.attitude import a2mat, m2att, mat2q, q2mat, yaw_from_heading
from firmware_model.strapdown import NavState, strapdown_step
from protocols.constants import DEG


@pytest.mark.parametrize("dtype", [np.float64, np.float32])
def test_perfect_static_imu_stays_put_for_10_minutes(dtype):
    lat, lon, h = 39.979 * DEG, 116.339 * DEG, 50.0
    cbn = a2mat(2 * DEG, -3 * DEG, yaw_from_heading(30 * DEG))
    w_b = cbn.T @ earth.omega_ie_n(lat)
    f_b = cbn.T @ np.array([0, 0, earth.gravity(lat, h)])
    T = 0.005
    s = NavState(q=mat2q(cbn).astype(dtype), v=np.zeros(3, dtype=dtype), pos=np.array([lat, lon, h]))
    for _ in range(int(600 / T)):
        strapdown_step(s, (w_b * T).astype(dtype), (f_b * T).astype(dtype), T, dtype=dtype)
    rm, rn = earth.radii(lat)
    dn = (s.pos[0] - lat) * (rm + h)
    de = (s.pos[1] - lon) * (rn + h) * math.cos(lat)
    du = s.pos[2] - h
    err = math.sqrt(dn * dn + de * de + du * du)
    assert err < 1.0, err  # strapdown accuracy bound: < 1 m after 10 min static
    p, r, y = m2att(q2mat(s.q.astype(np.float64)))
    p0, r0, y0 = m2att(cbn)
    assert abs(p - p0) < 1e-4 and abs(r - r0) < 1e-4 and abs(y - y0) < 1e-4


def test_euler_round_trip_and_heading_convention():
    # heading 30 deg clockwise from north: body y axis (forward) points N30E
    cbn = a2mat(0.0, 0.0, yaw_from_heading(30 * DEG))
    fwd = cbn @ np.array([0, 1.0, 0])
    assert fwd[0] == pytest.approx(math.sin(30 * DEG)) and fwd[1] == pytest.approx(math.cos(30 * DEG))
    # positive pitch: nose up; positive roll: right wing down
    assert (a2mat(10 * DEG, 0, 0) @ np.array([0, 1.0, 0]))[2] > 0
    assert (a2mat(0, 10 * DEG, 0) @ np.array([1.0, 0, 0]))[2] < 0


def test_gravity_reference_value():
    # docs/reference/algorithms.md 1.1: 39.979 deg, 50 m -> 9.801492 m/s^2
    assert earth.gravity(39.979 * DEG, 50.0) == pytest.approx(9.801492, abs=1e-6)


def _coning_truth(t, a, w):
    """Classical coning attitude q_b^i(t) = qz(w t) qx(a) qz(-w t)."""
    from firmware_model.attitude import qmul, rv2q

    return qmul(qmul(rv2q(np.array([0.0, 0.0, w * t])), rv2q(np.array([a, 0.0, 0.0]))),
                rv2q(np.array([0.0, 0.0, -w * t])))


def _body_rate(t, a, w, h=1e-6):
    from firmware_model.attitude import qconj, qmul

    dq = (_coning_truth(t + h, a, w) - _coning_truth(t - h, a, w)) / (2 * h)
    return 2.0 * qmul(qconj(_coning_truth(t, a, w)), dq)[1:]


def _increment(t0, t1, a, w):
    x, wt = np.polynomial.legendre.leggauss(8)
    mid, half = 0.5 * (t0 + t1), 0.5 * (t1 - t0)
    return sum(wi * _body_rate(mid + half * xi, a, w) for xi, wi in zip(x, wt)) * half


def test_two_sample_coning_removes_the_coning_drift():
    """Classical coning (1 deg half-angle, 5 Hz): two-sample coning vs plain summed increments at 100 Hz."""
    from firmware_model.attitude import qconj, qmul, qnormalize, rv2q
    from firmware_model.strapdown import coning_sculling

    a, w, T = 1.0 * DEG, 2 * math.pi * 5.0, 0.01
    q1 = q2 = _coning_truth(0.0, a, w)
    n = 100
    for k in range(n):
        t0 = k * T
        d1, d2 = _increment(t0, t0 + T / 2, a, w), _increment(t0 + T / 2, t0 + T, a, w)
        phi, _ = coning_sculling(np.stack([d1, d2]), np.zeros((2, 3)))
        q2 = qnormalize(qmul(q2, rv2q(phi)))
        q1 = qnormalize(qmul(q1, rv2q(d1 + d2)))
    truth = _coning_truth(n * T, a, w)

    def err(q):
        return 2 * np.linalg.norm(qmul(qconj(truth), q)[1:])

    # single-sample drift: a^2 w / 2 (1 - sin(wT)/(wT)) * 1 s = 7.9e-5 rad (Savage, coning error)
    assert err(q1) == pytest.approx(7.9e-5, rel=0.05)
    assert err(q2) < 0.05 * err(q1)


def test_two_sample_sculling_term():
    """Rotation about z while accelerating along x: sculling adds the rotation of dv inside the interval."""
    from firmware_model.strapdown import coning_sculling

    th = np.array([[0.0, 0.0, 0.01], [0.0, 0.0, 0.01]])
    dv = np.array([[0.1, 0.0, 0.0], [0.1, 0.0, 0.0]])
    phi, dvm = coning_sculling(th, dv)
    assert np.allclose(phi, [0, 0, 0.02])  # parallel increments: no coning term
    # 1/2 (th1+th2) x (dv1+dv2) + 2/3 (th1 x dv2 + dv1 x th2) = 1/2*0.02*0.2 y + 2/3*(0.001 - 0.001) y
    assert np.allclose(dvm, [0.2, 0.002, 0.0])


def _firmware_precision_run(duration_s: float) -> float:
    """Perfect increments rounded to float32 (the IMU conversion's precision), single-sample
    rotation compensation in float32, strapdown state in the firmware's nav-state precision
    (float64 q and v, D-L.1); returns the worst position error against truth (m)."""
    from firmware_model.attitude import cross3
    from tests.emulator.world.test_trajectory import gravity_model_height, manoeuvring, pos_error_m

    traj = manoeuvring(600.0)
    T = 0.005
    st = traj.state(0.0)
    s = NavState(mat2q(st.c_bn), st.v_enu.copy(), st.pos.copy(), a_prev=np.zeros(3))
    worst = 0.0
    for k in range(1, round(duration_s / T) + 1):
        dth, dv = traj.imu_increments((k - 1) * T, k * T)
        dth, dv = dth.astype(np.float32), dv.astype(np.float32)
        dv_m = dv + np.float32(0.5) * cross3(dth, dv)
        strapdown_step(s, dth, dv_m, T, dtype=np.float64)
        if k % 200 == 0:
            err = pos_error_m(s.pos, traj.state(k * T).pos)
            err[2] -= gravity_model_height(traj, k * T)  # the world's gravity is not the firmware's (test_trajectory)
            worst = max(worst, float(np.linalg.norm(err)))
    return worst


def test_firmware_precision_strapdown_follows_a_manoeuvring_trajectory_for_5_min():
    assert _firmware_precision_run(300.0) < 1.0


@pytest.mark.slow
def test_firmware_precision_strapdown_follows_a_manoeuvring_trajectory_for_10_min():
    # strapdown accuracy bound: < 5 m after a 10 min manoeuvring trajectory, through the firmware's own precisions
    assert _firmware_precision_run(600.0) < 5.0
