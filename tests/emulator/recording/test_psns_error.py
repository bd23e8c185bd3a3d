"""The solved solar vectors against truth (emulator.recording.psns_error): the truth against pvlib's SPA, the error
of a known rotation, the sign of a bi-direction solve, the statistics against numpy."""

from __future__ import annotations

import datetime as _dt
import math

import numpy as np
import pytest
from pvlib import spa
from scipy.spatial.transform import Rotation

from emulator.recording.psns_error import SolarVsTruth, azimuth_elevation_error, solar_error_stats
from emulator.world.sun import SunModel
from emulator.world.trajectory import StaticTrajectory
from firmware_model.registry import SolarSolve

EPOCH = _dt.datetime(2019, 9, 18, 8, 14, tzinfo=_dt.UTC)
LAT, LON, H, HEADING = 39.979, 116.339, 50.0, 30.0


def _cmp() -> SolarVsTruth:
    return SolarVsTruth(StaticTrajectory(LAT, LON, H, heading_deg=HEADING), SunModel(EPOCH))


def test_truth_is_the_spa_sun_turned_into_the_body_frame():
    """Level, heading 30 deg: s_b = (s_E cos h - s_N sin h, s_E sin h + s_N cos h, s_U) from pvlib's own SPA."""
    t = 7.3
    unix = np.array([EPOCH.timestamp() + t])
    pos = spa.solar_position(unix, LAT, LON, H, 1013.25, 12.0, float(spa.calculate_deltat(2019, 9)), 0.5667, 0)
    az, el = math.radians(float(pos[4][0])), math.radians(90.0 - float(pos[1][0]))  # azimuth, geometric zenith
    e, n, u = math.sin(az) * math.cos(el), math.cos(az) * math.cos(el), math.sin(el)
    h = math.radians(HEADING)
    want = np.array([e * math.cos(h) - n * math.sin(h), e * math.sin(h) + n * math.cos(h), u])
    got = _cmp().truth_s_b(t)
    assert math.degrees(math.acos(min(1.0, float(got @ want)))) < 1e-3


@pytest.mark.parametrize("angle_deg", [0.0, 0.05, 0.5, 3.0])
def test_a_solve_turned_by_a_known_angle_has_that_error_either_sign(angle_deg):
    cmp = _cmp()
    t = 4.0
    s = cmp.truth_s_b(t)
    axis = np.cross(s, [0.0, 0.0, 1.0])
    axis /= np.linalg.norm(axis)  # perpendicular to the sun: the solve turns by exactly angle_deg
    turned = Rotation.from_rotvec(math.radians(angle_deg) * axis).apply(s)
    cmp.add([SolarSolve(t, tuple(turned), 200, 1e-5, "camera", "accepted"),
             SolarSolve(t, tuple(-turned), 200, 1e-5, "camera", "refused")])  # the other sign of +-S
    cmp.drain()
    assert cmp.err_deg == pytest.approx([angle_deg, angle_deg], abs=1e-6)
    assert cmp.uses == {"accepted": 1, "refused": 1}
    header, *rows = "".join(cmp.rows).splitlines()
    assert header.split(",") == ["time_s", "s_b_x", "s_b_y", "s_b_z", "true_s_b_x", "true_s_b_y", "true_s_b_z",
                                 "err_deg", "err_az_deg", "err_el_deg", "n_used", "quality", "source", "use"]
    cells = rows[0].split(",")
    assert float(cells[7]) == pytest.approx(angle_deg, abs=1e-6)
    # turned about the horizontal axis perpendicular to the sun (the body is level): all of it is elevation, upwards
    assert cmp.err_el_deg == pytest.approx([angle_deg, angle_deg], abs=1e-6)
    assert cmp.err_az_deg == pytest.approx([0.0, 0.0], abs=1e-6)
    assert np.allclose([float(c) for c in cells[4:7]], s, atol=1e-12)
    assert cells[12:] == ["camera", "accepted"]


def test_statistics_are_numpys_and_a_zero_vector_is_not_a_number():
    rng = np.random.default_rng(5)
    errs = list(rng.gamma(2.0, 0.05, 101))
    st = solar_error_stats(errs)
    assert st == {"median": pytest.approx(np.median(errs)), "p95": pytest.approx(np.percentile(errs, 95)),
                  "max": pytest.approx(max(errs))}
    assert solar_error_stats([]) == {"median": None, "p95": None, "max": None}
    cmp = _cmp()
    cmp.add([SolarSolve(1.0, (0.0, 0.0, 0.0), 3, 0.4, "sensor", "refused")])
    summ = cmp.summary()
    assert summ is not None and summ["solves"] == 1
    assert math.isnan(summ["solar_vector_error_deg"]["max"])


def test_no_solve_no_section_and_windows_select_by_exposure_time():
    cmp = _cmp()
    assert cmp.summary() is None and cmp.rows == []
    cmp.add([SolarSolve(t, tuple(cmp.truth_s_b(t)), 10, 0.0, "camera", "accepted") for t in (1.0, 2.0, 3.0)])
    assert len(cmp.window(1.5, None)) == 2
    assert len(cmp.window(0.0, 2.0)) == 2
    assert max(cmp.window(0.0, None)) < 1e-6


def test_azimuth_elevation_error_against_a_known_rotation():
    # the true sun at azimuth 30 deg, elevation 40 deg; the solve 0.2 deg further in azimuth and 1.1 deg higher,
    # given with the opposite sign and not normalised
    def enu(az_deg, el_deg):
        a, e = np.radians(az_deg), np.radians(el_deg)
        return np.array([np.cos(e) * np.sin(a), np.cos(e) * np.cos(a), np.sin(e)])

    d_az, d_el = azimuth_elevation_error(-3.0 * enu(30.2, 41.1), enu(30.0, 40.0))
    assert d_az == pytest.approx(0.2, abs=1e-9) and d_el == pytest.approx(1.1, abs=1e-9)
    # across north the azimuth error wraps
    d_az, d_el = azimuth_elevation_error(enu(-0.3, 10.0), enu(359.9, 10.0))
    assert d_az == pytest.approx(-0.2, abs=1e-9) and d_el == pytest.approx(0.0, abs=1e-9)
