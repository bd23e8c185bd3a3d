"""Magnetometer: field model, IGRF defaults, hard and soft iron, noise, MAG words."""

from __future__ import annotations

import datetime as dt
import math

import numpy as np
import pytest

from emulator.devices.magnetometer import (
    BEIJING_FIELD,
    MAG_LSB_NT,
    MagConfig,
    Magnetometer,
    field_enu,
    soft_iron_matrix,
)
from emulator.world.trajectory import StaticTrajectory
from firmware_model.attitude import a2mat, yaw_from_heading
from protocols.constants import DEG


def test_beijing_defaults_are_igrf():
    ppigrf = pytest.importorskip("ppigrf")
    be, bn, bu = (float(np.squeeze(x)) for x in ppigrf.igrf(116.339, 39.979, 0.05, dt.datetime(2019, 9, 18, 8, 14)))
    b = field_enu(*BEIJING_FIELD)
    assert np.allclose(b, [be, bn, bu], atol=20.0)


def test_field_direction_and_heading():
    b = field_enu(-7.0, 59.0, 50000.0)
    assert math.isclose(float(np.linalg.norm(b)), 50000.0)
    assert math.degrees(math.atan2(b[0], b[1])) == pytest.approx(-7.0)
    assert math.degrees(math.atan2(-b[2], math.hypot(b[0], b[1]))) == pytest.approx(59.0)
    # a level vehicle heading north-west sees the horizontal field along body -x/+y accordingly
    traj = StaticTrajectory(39.979, 116.339, 50.0, heading_deg=315.0)
    mag = Magnetometer(traj, np.random.default_rng(1), MagConfig(noise_nt=0.0))
    fb = mag.field_body(0.0)
    heading = math.degrees(math.atan2(-fb[0], fb[1])) % 360  # field azimuth in body minus declination
    assert (315.0 - (heading + BEIJING_FIELD[0])) % 360 == pytest.approx(0.0, abs=1e-9)


def test_hard_soft_iron_and_noise():
    traj = StaticTrajectory(39.979, 116.339, 50.0, heading_deg=30.0, pitch_deg=5.0, roll_deg=-3.0)
    w = soft_iron_matrix((1.02, 0.98, 1.01), (0.01, -0.005, 0.002))
    h = (300.0, -150.0, 80.0)
    mag = Magnetometer(traj, np.random.default_rng(2), MagConfig(noise_nt=15.0, hard_iron_nt=h, soft_iron=w))
    c_nb = a2mat(5 * DEG, -3 * DEG, yaw_from_heading(30 * DEG)).T
    expect = w @ (c_nb @ field_enu(*BEIJING_FIELD)) + np.array(h)
    m = np.array([mag.measure(0.0) for _ in range(4000)])
    assert np.allclose(m.mean(axis=0), expect, atol=1.5)
    assert np.allclose(m.std(axis=0), 15.0, rtol=0.06)
    words, status = mag.sample(0.005, 0.0)
    assert status == 0 and np.allclose(np.array(words) * MAG_LSB_NT, mag.last_measured, atol=MAG_LSB_NT / 2 + 1e-9)
