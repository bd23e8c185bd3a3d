"""The firmware's PSNS solve against the emulator's IMX250MZR camera model (the conventions of docs/architecture.md on
both sides).

The camera model (``emulator.devices.camera``, the world helper's) is independent code: if both sides
keep the camera conventions (docs/architecture.md "Conventions"), the firmware recovers the model's true sun direction
in the camera frame.
"""

from __future__ import annotations

import datetime as dt
import math

import numpy as np
import pytest

from protocols.constants import DEG

camera = pytest.importorskip("emulator.devices.camera")

from emulator.world.sky import SkyModel  # noqa: E402
from emulator.world.sun import SunModel  # noqa: E402
from emulator.world.trajectory import StaticTrajectory  # noqa: E402
from firmware_model import psns  # noqa: E402
from firmware_model.psns_geometry import CameraGeometry  # noqa: E402

EPOCH = dt.datetime(2019, 9, 18, 8, 14, tzinfo=dt.UTC)


def _angle_deg(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return math.degrees(math.atan2(np.linalg.norm(np.cross(a, b)), abs(float(a @ b))))


def _solve_from_model(heading: float, seed: int, wire: bool = True, **cfg_kw) -> tuple[float, int]:
    traj = StaticTrajectory(39.979, 116.339, 50.0, heading, 2.0, -3.0)
    cfg = camera.CameraConfig(**cfg_kw)
    model = camera.PolarizationCameraModel(cfg, SkyModel(), SunModel(EPOCH, 69.0), traj, np.random.default_rng(seed))
    obs = model.observe(0.0)
    _, s_c, _ = model.camera_attitude(0.0)
    aop, dop = np.asarray(obs.aop), np.asarray(obs.dop, dtype=np.float32)
    if wire:  # what goes over the wire: AOP in 0.01 deg, DOP in 1/65535
        aop = camera.wire_aop_cdeg(aop) * (0.01 * DEG)
        dop = (np.round(dop * 65535) / 65535).astype(np.float32)
    geo = CameraGeometry(nx=cfg.nx, ny=cfg.ny, dx_m=cfg.pixel_m, dy_m=cfg.pixel_m, focal_m=cfg.focal_m,
                         projection=cfg.lens)
    sol = psns.solve_solar_vector(psns.evectors_camera(obs.x_px, obs.y_px, aop, geo), dop)
    assert sol.valid
    return _angle_deg(sol.s, s_c), sol.n_used


@pytest.mark.parametrize("lens, focal", [("pinhole", 4.0e-3), ("fisheye", 1.8e-3)])
def test_noise_free_camera_model_below_0p001_deg(lens, focal):
    for k, heading in enumerate(range(0, 360, 60)):
        err, n = _solve_from_model(float(heading), k, wire=False, noise=False, lens=lens, focal_m=focal)
        assert n > 50
        assert err < 0.001, (heading, err)
        # through the wire's 0.01 deg AOP quantisation (76 fisheye / 225 pinhole points)
        assert _solve_from_model(float(heading), k, wire=True, noise=False, lens=lens, focal_m=focal)[0] < 0.003


def test_reference_noise_camera_model_median_below_0p05_deg():
    errs = [_solve_from_model(float(h), k, noise=True)[0] for k, h in enumerate(range(0, 360, 30))]
    assert np.median(errs) < 0.05, errs


def test_camera_polarizer_biases_known_to_the_calibration_are_removed():
    """The camera device renders with per-channel micro-polarizer biases (noise off, no other defects). With the
    calibrated angles the firmware's correction brings the solar vector back to the noise-free floor (< 0.003 deg
    through the wire's quantisation); with the nominal angles (the bias unknown) the error stays at 0.7-0.9 deg."""
    from emulator.devices.camera.optics import SensorDefects

    bias = (1.0, -0.6, 0.4, -0.8)
    known = tuple(t + b for t, b in zip((0.0, 45.0, 90.0, 135.0), bias, strict=True))
    for k, heading in enumerate(range(0, 360, 90)):
        traj = StaticTrajectory(39.979, 116.339, 50.0, float(heading), 2.0, -3.0)
        cfg = camera.CameraConfig(noise=False, defects=SensorDefects(orientation_bias_deg=bias))
        model = camera.PolarizationCameraModel(cfg, SkyModel(), SunModel(EPOCH, 69.0), traj,
                                               np.random.default_rng(k))
        obs = model.observe(0.0)
        _, s_c, _ = model.camera_attitude(0.0)
        aop = (camera.wire_aop_cdeg(np.asarray(obs.aop)) * (0.01 * DEG)).astype(np.float32)
        dop = (np.round(np.asarray(obs.dop) * 65535) / 65535).astype(np.float32)
        errs = []
        for angles in (known, (0.0, 45.0, 90.0, 135.0)):
            geo = CameraGeometry(nx=cfg.nx, ny=cfg.ny, dx_m=cfg.pixel_m, dy_m=cfg.pixel_m, focal_m=cfg.focal_m,
                                 polarizer_deg=angles, extinction_ratio=cfg.extinction_ratio)
            a, d = psns.correct_polarizer(aop, dop, geo)
            sol = psns.solve_solar_vector(psns.evectors_camera(obs.x_px, obs.y_px, a, geo), d)
            assert sol.valid
            errs.append(_angle_deg(sol.s, s_c))
        assert errs[0] < 0.003 and errs[1] > 0.5, (heading, errs)
