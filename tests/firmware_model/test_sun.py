"""Grena (2012) Algorithm 5 ephemeris against SPA (pvlib) and the reference numbers of docs/reference/algorithms.md
3."""

import datetime as dt
import math

import numpy as np
import pytest

from firmware_model import c674x, sun
from protocols.constants import DEG


def _angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return math.degrees(math.atan2(np.linalg.norm(np.cross(a, b)), float(a @ b)))


def _enu(az_deg, el_deg):
    az, el = np.radians(az_deg), np.radians(el_deg)
    return np.stack([np.sin(az) * np.cos(el), np.cos(az) * np.cos(el), np.sin(el)], axis=-1)


def test_time_scale_origin_and_gregorian_rule():
    assert sun.grena_days(2060, 1, 1, 0.0) == 0.0
    assert sun.grena_days(2060, 1, 2, 12.0) == 1.5
    # 2100 is not a leap year: 28 Feb -> 1 Mar is one day
    assert sun.grena_days(2100, 3, 1, 0.0) - sun.grena_days(2100, 2, 28, 0.0) == 1.0
    # and 2000-2099 leap years are: 2040-02-29 exists
    assert sun.grena_days(2040, 3, 1, 0.0) - sun.grena_days(2040, 2, 28, 0.0) == 2.0
    t = dt.datetime(2019, 9, 18, 8, 14, 0, tzinfo=dt.UTC)
    assert sun.grena_days_from_datetime(t) == pytest.approx(sun.grena_days(2019, 9, 18, 8 + 14 / 60), abs=1e-9)


@pytest.mark.parametrize(
    "lat, lon, when, s_ref",
    [
        # docs/reference/algorithms.md section 3: SPA (pvlib 0.16.1) ENU sun vectors
        (39.979, 116.339, dt.datetime(2019, 9, 18, 8, 14, tzinfo=dt.UTC), [-0.876416, -0.282797, 0.389770]),
        (37.59, 112.24, dt.datetime(2019, 12, 1, 2, 0, tzinfo=dt.UTC), [0.532125, -0.757852, 0.377496]),
    ],
)
def test_reference_cases_within_0p005_deg(lat, lon, when, s_ref):
    td = sun.grena_days_from_datetime(when)
    s = sun.sun_vector_enu(td, lat * DEG, lon * DEG)
    assert s.dtype == np.float32
    assert abs(float(np.linalg.norm(s.astype(float))) - 1.0) < 1e-6
    assert _angle_deg(s, s_ref) < 0.005


def test_against_pvlib_spa_2010_2110_below_0p01_deg():
    pd = pytest.importorskip("pandas")
    pvlib = pytest.importorskip("pvlib")
    rng = np.random.default_rng(2012)
    t0 = pd.Timestamp("2010-01-01", tz="UTC").value // 10**9
    t1 = pd.Timestamp("2110-01-01", tz="UTC").value // 10**9
    worst = 0.0
    errs = []
    for lat, lon in [(39.979, 116.339), (-33.9, 18.4), (64.1, -21.9), (0.5, -78.5), (-45.0, 170.0)]:
        secs = np.sort(rng.integers(t0, t1, 200))
        times = pd.to_datetime(secs, unit="s", utc=True)
        spa = pvlib.solarposition.spa_python(times, lat, lon, altitude=0.0, delta_t=None)
        ref = _enu(spa["azimuth"].to_numpy(), spa["elevation"].to_numpy())
        for i, t in enumerate(times):
            td = sun.grena_days_from_datetime(t.to_pydatetime())
            e = _angle_deg(sun.sun_vector_enu(td, lat * DEG, lon * DEG), ref[i])
            errs.append(e)
            worst = max(worst, e)
    assert worst < 0.01, worst
    assert np.median(errs) < 0.003


def test_az_el_convention_matches_vector():
    td = sun.grena_days(2019, 9, 18, 8 + 14 / 60)
    az, el = sun.sun_az_el(td, 39.979 * DEG, 116.339 * DEG)
    assert az / DEG == pytest.approx(252.1164, abs=0.005)  # SPA, docs/reference/algorithms.md section 3
    assert el / DEG == pytest.approx(22.9402, abs=0.005)


def test_ephemeris_is_charged_with_double_precision_where_needed():
    cyc = sun.ephemeris_cycles()
    # the DP phases and their reductions dominate: more than 13 divdp + DP flops, far below a tick
    assert cyc > 13 * c674x.MATHLIB_DP_INLINE["divdp"]
    assert cyc < 0.01 * 1.5e6
