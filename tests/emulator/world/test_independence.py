"""The world and the firmware do not share models; where they model the same thing, they agree.

The firmware's hand-written kernels (``firmware_model.attitude``, ``firmware_model.earth``) are checked against the
well-kept libraries the world is built on (scipy's ``Rotation``, pymap3d) and the world's own Earth model.
"""

from __future__ import annotations

import ast
import math
from pathlib import Path

import numpy as np
import pymap3d
import pytest
from scipy.spatial.transform import Rotation

from emulator.world import frames, geodesy
from firmware_model import attitude, earth

ROOT = Path(__file__).resolve().parents[3]


@pytest.mark.parametrize("package", ["emulator/world", "emulator/devices/camera"])
def test_no_firmware_import(package):
    for path in (ROOT / package).rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text())):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            assert not any(n.split(".")[0] == "firmware_model" for n in names), f"{path}: imports {names}"


def _angles(n=200, seed=11):
    rng = np.random.default_rng(seed)
    return rng.uniform(-1.55, 1.55, n), rng.uniform(-math.pi, math.pi, n), rng.uniform(-math.pi, math.pi, n)


def test_firmware_a2mat_m2att_agree_with_scipy_rotation():
    pitch, roll, yaw = _angles()
    c = Rotation.from_euler("ZXY", np.stack([yaw, pitch, roll], axis=1)).as_matrix()
    for i in range(len(pitch)):
        assert np.allclose(attitude.a2mat(pitch[i], roll[i], yaw[i]), c[i], atol=1e-14)
        assert np.allclose(attitude.m2att(c[i]), (pitch[i], roll[i], yaw[i]), atol=1e-9)


def test_firmware_quaternions_agree_with_scipy_rotation():
    pitch, roll, yaw = _angles(seed=12)
    r = Rotation.from_euler("ZXY", np.stack([yaw, pitch, roll], axis=1))
    q_scipy = r.as_quat(scalar_first=True)
    rv = r.as_rotvec()
    for i in range(len(pitch)):
        q = attitude.att2q(pitch[i], roll[i], yaw[i])
        assert min(np.abs(q - q_scipy[i]).max(), np.abs(q + q_scipy[i]).max()) < 1e-12
        assert np.allclose(attitude.q2mat(q), r[i].as_matrix(), atol=1e-14)
        q_rv = attitude.rv2q(rv[i])
        assert min(np.abs(q_rv - q_scipy[i]).max(), np.abs(q_rv + q_scipy[i]).max()) < 1e-12
        p2 = attitude.qmul(q, attitude.qconj(q))
        assert np.allclose(p2, [1.0, 0.0, 0.0, 0.0], atol=1e-14)


def test_world_frames_heading_round_trip():
    for h in np.linspace(0.0, 2 * math.pi, 37, endpoint=False):
        assert math.isclose(frames.heading_from_yaw(frames.yaw_from_heading(h)), h, abs_tol=1e-12)
        assert math.isclose(frames.yaw_from_heading(h), attitude.yaw_from_heading(h), abs_tol=1e-12)


def test_firmware_geodesy_agrees_with_pymap3d():
    rng = np.random.default_rng(5)
    for lat, lon, h in zip(rng.uniform(-1.5, 1.5, 50), rng.uniform(-3, 3, 50), rng.uniform(-400, 9000, 50)):
        x = np.array(pymap3d.geodetic2ecef(lat, lon, h, deg=False))
        assert np.allclose(earth.geodetic_to_ecef(lat, lon, h), x, rtol=0, atol=1e-6)
        assert np.allclose(geodesy.geodetic_to_ecef(lat, lon, h), x, rtol=0, atol=1e-9)


def test_firmware_radii_agree_with_pymap3d_curvature():
    ell = pymap3d.Ellipsoid.from_name("wgs84")
    for lat in np.linspace(-1.5, 1.5, 31):
        rm, rn = earth.radii(float(lat))
        # prime vertical: the ECEF distance to the polar axis is (R_N + h) cos L
        x, y, _ = pymap3d.geodetic2ecef(lat, 0.0, 0.0, ell=ell, deg=False)
        assert math.isclose(math.hypot(x, y), rn * math.cos(lat), rel_tol=0, abs_tol=1e-6)
        # meridian: arc length of a small latitude step
        d = 1e-6
        p0 = np.array(pymap3d.geodetic2ecef(lat - d, 0.0, 0.0, ell=ell, deg=False))
        p1 = np.array(pymap3d.geodetic2ecef(lat + d, 0.0, 0.0, ell=ell, deg=False))
        assert math.isclose(float(np.linalg.norm(p1 - p0)) / (2 * d), rm, rel_tol=1e-8)


def test_firmware_gravity_series_agrees_with_somigliana():
    """PSINS' series against the closed Somigliana formula with the TR8350.2 free-air term."""
    for lat in np.linspace(-1.55, 1.55, 31):
        for h in (-400.0, 0.0, 1000.0, 9000.0):
            assert abs(earth.gravity(float(lat), h) - float(geodesy.normal_gravity(lat, h))) < 2e-4
    # the TR8350.2 values at the equator and pole (Table 3.4)
    assert math.isclose(float(geodesy.normal_gravity(0.0, 0.0)), 9.7803253359, abs_tol=1e-10)
    assert math.isclose(float(geodesy.normal_gravity(math.pi / 2, 0.0)), 9.8321849378, abs_tol=1e-9)


def test_firmware_earth_rate_agrees_with_the_defining_constant():
    lat = 0.7
    assert np.allclose(earth.omega_ie_n(lat), [0.0, earth.OMEGA_IE * math.cos(lat), earth.OMEGA_IE * math.sin(lat)])


def test_world_cbn_from_euler_agrees_with_scipy_rotation():
    # the world's C_b^n is the product of its three axis rotations (not scipy's quaternion path, for speed):
    # the same rotation as scipy's intrinsic ZXY to rounding, for arrays and for single triples
    pitch, roll, yaw = _angles(seed=13)
    ref = Rotation.from_euler("ZXY", np.stack([yaw, pitch, roll], axis=1)).as_matrix()
    c = frames.cbn_from_euler(pitch, roll, yaw)
    assert c.shape == (len(pitch), 3, 3)
    assert np.abs(c - ref).max() < 2e-15
    for i in range(0, len(pitch), 17):
        c1 = frames.cbn_from_euler(float(pitch[i]), float(roll[i]), float(yaw[i]))
        assert c1.shape == (3, 3)
        assert np.array_equal(c1, c[i])
        assert np.allclose(frames.euler_from_cbn(c1), (pitch[i], roll[i], yaw[i]), atol=1e-12)
