"""Lens terms beyond the firmware's family (k3, decentering) and the lens's radial diattenuation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from emulator.devices.camera import CameraConfig
from emulator.devices.camera.geometry import CameraGeometry
from emulator.devices.camera.optics import LensModel, radial_diattenuation


def test_brown_conrady_lens_round_trips_and_reduces_to_the_radial_lens():
    lens = LensModel(k1=-0.03, k2=0.004, k3=0.002, p1=4e-4, p2=-3e-4, cx_px=1240.0, cy_px=1010.0)
    x = np.array([1.0, 600.0, 1224.0, 2000.0, 2448.0])
    y = np.array([1.0, 1500.0, 1024.0, 300.0, 2048.0])
    v, th, _, _ = lens.rays(x, y)
    assert np.all(np.isfinite(th)) and th.max() > 0.8  # the corners at ~50 deg
    u, w = lens.project(v)
    np.testing.assert_allclose(u, x, atol=1e-6)
    np.testing.assert_allclose(w, y, atol=1e-6)
    radial = LensModel(k1=-0.03, k2=0.004, cx_px=1240.0, cy_px=1010.0)
    same = LensModel(k1=-0.03, k2=0.004, cx_px=1240.0, cy_px=1010.0, p1=1e-300)  # takes the Brown-Conrady path
    assert same.brown_conrady and not radial.brown_conrady
    np.testing.assert_allclose(same.rays(x, y)[0], radial.rays(x, y)[0], atol=1e-12)
    # decentering moves the corner by pixels: the firmware's radial family cannot hold it
    u0, w0 = radial.project(v)
    assert np.max(np.hypot(u - u0, w - w0)) > 2.0


def test_unpolarized_light_behind_the_radial_diattenuator_is_polarized_radially_by_d():
    d = np.array([0.01])
    for phi in (0.0, 0.3, 1.2):
        s0, s1, s2 = radial_diattenuation(np.array([1.0]), np.array([0.0]), np.array([0.0]), d,
                                          np.array([math.cos(2 * phi)]), np.array([math.sin(2 * phi)]))
        assert math.hypot(s1[0], s2[0]) / s0[0] == pytest.approx(0.01)
        assert 0.5 * math.atan2(s2[0], s1[0]) == pytest.approx(phi)
    # a polarized beam along the axis gains, across it loses: (1 +- D)
    s0, _, _ = radial_diattenuation(np.array([1.0, 1.0]), np.array([1.0, -1.0]), np.array([0.0, 0.0]),
                                    np.array([0.01, 0.01]), np.array([1.0, 1.0]), np.array([0.0, 0.0]))
    np.testing.assert_allclose(s0, [1.01, 0.99])


def test_lens_diattenuation_reaches_its_edge_value_at_the_corner_and_vanishes_on_axis():
    cfg = CameraConfig(k1=-0.03, lens_diattenuation_edge=0.008)
    geo = CameraGeometry(cfg)
    d, c, s = geo.lens_diattenuation(np.array([1.0, 1224.5]), np.array([1.0, 1024.5]),
                                     geo.rays(np.array([1.0, 1224.5]), np.array([1.0, 1024.5]))[2])
    assert d[0] == pytest.approx(0.008, rel=1e-6) and d[1] < 1e-9
    phi = math.atan2(1.0 - 1024.5, 1.0 - 1224.5)  # the corner's image azimuth from the principal point
    assert (c[0], s[0]) == pytest.approx((math.cos(2 * phi), math.sin(2 * phi)))
    assert geo.pt_lens_dia is not None and np.max(geo.pt_lens_dia[0]) <= 0.008
    assert CameraGeometry(CameraConfig()).pt_lens_dia is None
