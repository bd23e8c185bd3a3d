"""Strapdown mechanization against closed-form truth."""

import math

import numpy as np
import pytest

from firmware_model import earth
from firmware_model.attitude import a2mat, m2att, mat2q, q2mat, yaw_from_heading
from firmware_model.strapdown import NavState, strapdown_step

DEG = math.pi / 180


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
    assert err < 1.0, err  # issue 4 bound: < 1 m after 10 min static
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
    # algorithms.md 1.1: 39.979 deg, 50 m -> 9.801492 m/s^2
    assert earth.gravity(39.979 * DEG, 50.0) == pytest.approx(9.801492, abs=1e-6)
