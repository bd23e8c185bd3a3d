"""Sun truth: our SPA path against pvlib's full SPA, the reference cases, and skyfield (DE421)."""

from __future__ import annotations

import datetime as dt
import math
import warnings

import numpy as np
import pytest

from emulator.world.sun import SunModel
from protocols.constants import DEG

UTC = dt.UTC

# docs/reference/algorithms.md section 3 (pvlib 0.16.1, delta_t = 69 s, altitude 0)
REFERENCE = [
    (dt.datetime(2019, 9, 18, 8, 14, tzinfo=UTC), 39.979, 116.339, 252.1164, 22.9402,
     [-0.876416, -0.282797, 0.389770]),
    (dt.datetime(2019, 12, 1, 2, 0, tzinfo=UTC), 37.59, 112.24, 144.9255, 22.1787,
     [0.532125, -0.757852, 0.377496]),
]


def angle_deg(a, b):
    return math.degrees(math.acos(max(-1.0, min(1.0, float(np.dot(a, b) / np.linalg.norm(a) / np.linalg.norm(b))))))


@pytest.mark.parametrize("epoch, lat, lon, az, el, s_enu", REFERENCE)
def test_reference_cases(epoch, lat, lon, az, el, s_enu):
    sun = SunModel(epoch, delta_t_s=69.0)
    a, e = sun.az_el(0.0, lat * DEG, lon * DEG, 0.0)
    assert abs(math.degrees(a) - az) < 1e-4 and abs(math.degrees(e) - el) < 1e-4
    assert np.allclose(sun.sun_enu(0.0, lat * DEG, lon * DEG, 0.0), s_enu, atol=2e-6)


def test_interpolated_geocentric_path_equals_full_spa():
    rng = np.random.default_rng(7)
    epoch = dt.datetime(2021, 6, 21, 0, 0, tzinfo=UTC)
    sun = SunModel(epoch)
    for _ in range(40):
        t = float(rng.uniform(0, 86400))
        lat, lon, h = rng.uniform(-60, 60), rng.uniform(-180, 180), rng.uniform(0, 9000)
        a, e = sun.az_el(t, lat * DEG, lon * DEG, h)
        az, el, _ = sun.spa_az_el(t, lat * DEG, lon * DEG, h)
        assert abs(math.degrees(e) - el) < 1e-4
        if el < 89.9:  # azimuth is ill-defined at the zenith
            assert abs((math.degrees(a) - az + 180) % 360 - 180) < 1e-4 / max(math.cos(el * DEG), 1e-3)


def test_against_skyfield_de421_within_0_01_deg():
    skyfield_data = pytest.importorskip("skyfield_data")
    from skyfield.api import Loader, wgs84

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # skyfield-data's IERS table "expired" notice
        load = Loader(skyfield_data.get_skyfield_data_path())
        ts = load.timescale(builtin=True)
        eph = load("de421.bsp")
    earth_, sun_ = eph["earth"], eph["sun"]
    rng = np.random.default_rng(11)
    epoch = dt.datetime(2019, 9, 18, 0, 0, tzinfo=UTC)
    sun = SunModel(epoch)
    worst = 0.0
    for _ in range(30):
        t = float(rng.uniform(0, 5 * 86400))
        lat, lon, h = rng.uniform(-70, 70), rng.uniform(-180, 180), rng.uniform(0, 3000)
        utc = epoch + dt.timedelta(seconds=t)
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            alt, az, _ = (earth_ + wgs84.latlon(lat, lon, elevation_m=h)).at(ts.from_datetime(utc)).observe(
                sun_).apparent().altaz()
        ref = np.array([math.sin(az.radians) * math.cos(alt.radians), math.cos(az.radians) * math.cos(alt.radians),
                        math.sin(alt.radians)])
        worst = max(worst, angle_deg(sun.sun_enu(t, lat * DEG, lon * DEG, h), ref))
    assert worst < 0.01


def test_night_is_below_the_horizon():
    sun = SunModel(dt.datetime(2019, 9, 18, 16, 0, tzinfo=UTC))  # midnight in Beijing
    _, el = sun.az_el(0.0, 39.979 * DEG, 116.339 * DEG, 50.0)
    assert el < -0.5
