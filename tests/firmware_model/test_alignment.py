"""Coarse alignment kernels: levelling and gravity + Sun TRIAD."""


import numpy as np
import pytest

from firmware_model.alignment import level_from_specific_force, solar_heading_alignment, triad
from firmware_model.attitude import a2mat, m2att, yaw_from_heading
from protocols.constants import DEG

S_N = np.array([0.532125, -0.757852, 0.377496])  # Taiyuan case, docs/reference/algorithms.md section 3


@pytest.mark.parametrize("heading, pitch, roll", [(0, 0, 0), (30, 2, -3), (215, -8, 12), (359, 20, -25)])
def test_triad_recovers_attitude_and_sign(heading, pitch, roll):
    cbn = a2mat(pitch * DEG, roll * DEG, yaw_from_heading(heading * DEG))
    f_b = cbn.T @ np.array([0.0, 0.0, 9.8])
    s_b = cbn.T @ (S_N / np.linalg.norm(S_N))
    for sgn in (1, -1):
        c, sign = solar_heading_alignment(f_b, sgn * s_b, S_N / np.linalg.norm(S_N))
        assert sign == sgn
        assert np.allclose(c, cbn, atol=1e-12)


def test_levelling_matches_a2mat_convention():
    cbn = a2mat(5 * DEG, -7 * DEG, 1.0)
    p, r = level_from_specific_force(cbn.T @ np.array([0, 0, 9.8]))
    assert p == pytest.approx(5 * DEG) and r == pytest.approx(-7 * DEG)
    assert m2att(cbn)[:2] == pytest.approx((p, r))


def test_triad_rejects_parallel_vectors():
    with pytest.raises(ValueError):
        triad(np.array([0, 0, 1.0]), np.array([0, 0, 2.0]), np.array([0, 0, 1.0]), np.array([1.0, 0, 0]))


def test_triad_with_sun_error_only_moves_heading_not_level():
    cbn = a2mat(2 * DEG, -3 * DEG, yaw_from_heading(30 * DEG))
    s_n = S_N / np.linalg.norm(S_N)
    f_b = cbn.T @ np.array([0.0, 0.0, 9.8])
    s_b = cbn.T @ s_n + np.array([0.001, -0.002, 0.0005])
    c, _ = solar_heading_alignment(f_b, s_b / np.linalg.norm(s_b), s_n)
    p, r, y = m2att(c)
    p0, r0, y0 = m2att(cbn)
    assert abs(p - p0) < 1e-12 and abs(r - r0) < 1e-12  # gravity is the primary vector
    assert 0 < abs(y - y0) < 0.5 * DEG
