"""Shared variant kernels against independent references (scipy, the shared compass geometry, closed forms)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.stats import chi2

from firmware_model.attitude import a2mat, q2mat, rv2q
from firmware_model.psns_geometry import compass_unit_mountings
from firmware_model.variants.common import (
    CHI2_TABLE,
    chi2_threshold,
    compass_mountings,
    misalignment_between,
    plane_basis,
    spd_inverse,
    spd_solve,
    unit_mounting,
)
from protocols.constants import DEG


@pytest.mark.parametrize("alpha", sorted(CHI2_TABLE))
def test_chi_square_table_matches_scipy(alpha):
    for dof in range(1, 7):
        assert chi2_threshold(dof, alpha) == pytest.approx(chi2.ppf(1.0 - alpha, dof), abs=6e-4)


def test_chi_square_table_refuses_what_it_does_not_hold():
    with pytest.raises(ValueError, match="alpha"):
        chi2_threshold(2, 0.02)
    with pytest.raises(ValueError, match="degrees of freedom"):
        chi2_threshold(7, 0.001)


def test_unit_mounting_reproduces_the_shared_nine_unit_compass():
    ref = compass_unit_mountings()
    mine = compass_mountings([(0.0, 0.0)] + [(45.0, 45.0 * k) for k in range(8)])
    assert np.allclose(mine, ref, atol=1e-12)
    for m in mine:  # proper rotations
        assert np.allclose(m.T @ m, np.eye(3), atol=1e-12) and np.linalg.det(m) == pytest.approx(1.0)


def test_unit_mounting_convention_ray_and_up_the_hemisphere():
    m = unit_mounting(30 * DEG, 90 * DEG)  # 30 deg from zenith towards body +x (right)
    assert np.allclose(m[:, 2], [math.sin(30 * DEG), 0.0, math.cos(30 * DEG)], atol=1e-12)
    assert m[2, 1] > 0  # the unit's +y points up the hemisphere


def test_misalignment_between_is_the_phi_convention():
    cbn = a2mat(3 * DEG, -4 * DEG, 70 * DEG)
    phi = np.array([0.002, -0.001, 0.003])
    computed = q2mat(rv2q(-phi)) @ cbn  # C_b^{n'} = (I - [phi x]) C_b^n to first order
    assert np.allclose(misalignment_between(computed, cbn), phi, atol=1e-8)


def test_spd_solve_and_inverse():
    rng = np.random.default_rng(3)
    a = rng.normal(size=(6, 6))
    A = a @ a.T + 6 * np.eye(6)
    b = rng.normal(size=6)
    assert np.allclose(spd_solve(A, b), np.linalg.solve(A, b))
    assert np.allclose(spd_inverse(A) @ A, np.eye(6), atol=1e-10)


def test_plane_basis_is_orthonormal_and_perpendicular():
    for s in (np.array([0.0, 0.0, 1.0]), np.array([1.0, 0.0, 0.0]), np.array([-0.876416, -0.282797, 0.389770])):
        s = s / np.linalg.norm(s)
        u1, u2 = plane_basis(s)
        for u in (u1, u2):
            assert abs(u @ s) < 1e-12 and abs(u @ u - 1) < 1e-12
        assert abs(u1 @ u2) < 1e-12
