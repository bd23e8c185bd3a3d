"""The camera as an instrument: lens, polarization transfer through it, sensor defects, both fidelities."""

from __future__ import annotations

import datetime as dt
import math

import numpy as np

from emulator.devices.camera import CameraConfig, PolarizationCameraModel
from emulator.devices.camera.optics import LensModel, SensorDefects, defect_maps, sensor_plane_field
from emulator.world.sky import SkyModel
from emulator.world.sun import SunModel
from emulator.world.trajectory import StaticTrajectory

EPOCH = dt.datetime(2019, 9, 18, 8, 14, tzinfo=dt.UTC)
DEFECTS = SensorDefects(orientation_sigma_deg=0.5, orientation_bias_deg=(0.3, -0.2, 0.1, -0.4),
                        extinction_spread=0.1, prnu=0.01, dark_e=2.0, crosstalk=0.015, vignetting=True)


def model(fidelity, noise=False, seed=1, **kw):
    cfg = CameraConfig(fidelity=fidelity, noise=noise, **kw)
    return PolarizationCameraModel(cfg, SkyModel(), SunModel(EPOCH, 69.0),
                                   StaticTrajectory(39.979, 116.339, 50.0, 30.0, 0.0, 0.0), np.random.default_rng(seed))


def test_lens_projection_round_trip_with_distortion_and_principal_point():
    rng = np.random.default_rng(2)
    x, y = rng.uniform(1, 2448, 200), rng.uniform(1, 2048, 200)
    for lens in (LensModel(k1=-0.03, k2=0.004, cx_px=1236.5, cy_px=1016.0),
                 LensModel(projection="fisheye", focal_m=1.8e-3, k1=-0.02, k2=0.001)):
        v, _th, _, _ = lens.rays(x, y)
        assert np.allclose(np.linalg.norm(v, axis=0), 1.0)
        px, py = lens.project(v)
        assert np.allclose(px, x, atol=1e-6) and np.allclose(py, y, atol=1e-6)
    # barrel distortion (k1 < 0) pulls the image in: a corner pixel sees further out than the pinhole says
    v_d = LensModel(k1=-0.03).rays(np.array([1.0]), np.array([1.0]))[1]
    v_p = LensModel().rays(np.array([1.0]), np.array([1.0]))[1]
    assert v_d[0] > v_p[0]


def _field(theta, phi, e_s, e_p):
    v = np.array([math.sin(theta) * math.cos(phi), math.sin(theta) * math.sin(phi), math.cos(theta)])
    s = np.array([-math.sin(phi), math.cos(phi), 0.0])
    p = np.array([math.cos(theta) * math.cos(phi), math.cos(theta) * math.sin(phi), -math.sin(theta)])
    e = e_s * s + e_p * p
    return [np.array([c]) for c in (*v, *e)], s, np.array([math.cos(phi), math.sin(phi)])


def test_meridional_transfer_keeps_s_and_p_and_scales_p_by_the_chief_ray_angle():
    theta, phi = 40 * math.pi / 180, 0.7
    (vx, vy, vz, ex, ey, ez), s, e_rho = _field(theta, phi, 1.0, 0.0)
    ax, ay = sensor_plane_field(vx, vy, vz, ex, ey, ez, np.array([math.cos(0.2)]))
    assert np.allclose([ax[0], ay[0]], s[:2])  # pure s stays azimuthal, whatever the lens
    (vx, vy, vz, ex, ey, ez), s, e_rho = _field(theta, phi, 0.0, 1.0)
    ax, ay = sensor_plane_field(vx, vy, vz, ex, ey, ez, np.array([math.cos(0.2)]))
    assert np.allclose([ax[0], ay[0]], math.cos(0.2) * e_rho)  # pure p stays radial, scaled by cos(theta')
    # mixed: the in-plane angle from e_rho is atan(E_s / (E_p cos theta')), not the orthographic atan(.. cos theta)
    (vx, vy, vz, ex, ey, ez), s, e_rho = _field(theta, phi, 1.0, 1.0)
    for cra in (0.0, 0.2, theta):
        ax, ay = sensor_plane_field(vx, vy, vz, ex, ey, ez, np.array([math.cos(cra)]))
        a = np.array([ax[0], ay[0]])
        assert math.isclose(math.atan2(a @ s[:2], a @ e_rho), math.atan2(1.0, math.cos(cra)), abs_tol=1e-12)
    # a thin lens (theta' = theta) is the paper's orthographic projection of the object-space E-vector
    ax, ay = sensor_plane_field(vx, vy, vz, ex, ey, ez, vz)
    assert np.allclose([ax[0], ay[0]], [ex[0], ey[0]])


def test_crosstalk_scales_dop_and_keeps_the_aop():
    a = model("binned", extinction_ratio=1e12).observe(0.0)
    c = 0.02
    b = model("binned", extinction_ratio=1e12, defects=SensorDefects(crosstalk=c)).observe(0.0)
    assert np.allclose(b.dop, (1 - 4 * c) * a.dop, rtol=1e-9)
    assert np.allclose(b.aop, a.aop, atol=1e-12)


def test_both_fidelities_see_the_same_instrument():
    kw = dict(k1=-0.03, cx_px=1236.5, cy_px=1016.5, exit_pupil_m=15e-3, defects=DEFECTS, defect_seed=7,
              extinction_ratio=150.0)
    of, ob = model("full", **kw).observe(0.0), model("binned", **kw).observe(0.0)
    good = of.dop > 0.1
    assert good.sum() > 100
    d = np.degrees((of.aop - ob.aop + math.pi / 2) % math.pi - math.pi / 2)
    assert np.max(np.abs(d[good])) < 0.02
    assert np.max(np.abs(of.dop - ob.dop)[good]) < 5e-4
    # and the defects are visible: the same scene through an ideal instrument differs by more than that
    ideal = model("binned").observe(0.0)
    d0 = np.degrees((ideal.aop - ob.aop + math.pi / 2) % math.pi - math.pi / 2)
    assert np.median(np.abs(d0[good])) > 0.1


def test_defect_maps_at_indices_are_the_whole_maps_indexed():
    # the binned camera evaluates the fixed pattern at its windows only: same draw, same values
    d = SensorDefects(orientation_sigma_deg=0.2, orientation_bias_deg=(0.1, -0.1, 0.05, -0.05),
                      extinction_spread=0.1, prnu=0.006)
    shape = (64, 80)
    pick = np.random.default_rng(5)
    at = (pick.integers(0, shape[0], (7, 3, 1)), pick.integers(0, shape[1], (7, 1, 3)))
    whole = defect_maps(d, 280.0, shape, np.random.default_rng(0))
    sub = defect_maps(d, 280.0, shape, np.random.default_rng(0), at=at)
    for theta in (0, 45, 90, 135):
        for k in range(3):
            assert sub[theta][k].shape == (7, 3, 3)
            assert np.array_equal(sub[theta][k], whole[theta][k][at])
    assert np.std(whole[0][0]) > 0.0 and np.std(whole[0][2]) > 0.0  # the maps are not constant
