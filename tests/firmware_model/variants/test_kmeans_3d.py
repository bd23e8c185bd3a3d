"""K-means sun finding + 3-D attitude (Yang et al.): kernels against oracles, all-sky images, refusal (Done-when)."""

from __future__ import annotations

import datetime as dt
import math
import warnings

import numpy as np
import pytest
from scipy.cluster.vq import kmeans2

from emulator.world.sun import SunModel
from firmware_model import Firmware, FirmwareConfig
from firmware_model.attitude import a2mat, heading_from_yaw, yaw_from_heading
from firmware_model.psns_geometry import CameraGeometry
from firmware_model.variants.kmeans_3d import (
    find_sun,
    heading_from_mag,
    kmeans_1d,
    kmeans_attitude,
    pitch_roll_from_sun,
)
from firmware_model.variants.params import KmeansParams
from protocols.constants import DEG

from .streams import (
    CameraSpec,
    GnssSpec,
    ImuErrors,
    MagSpec,
    StreamSpec,
    camera_observation,
    field_enu,
    run,
    segment_trajectory,
)

TAIYUAN = (37.59, 112.24, 800.0)
EPOCH = dt.datetime(2019, 12, 1, 2, 0, tzinfo=dt.UTC)  # the paper's field test: 10:00 local
# all-sky fisheye (docs/reference/algorithms.md 2.4: f = 1.8 mm)
CAM = CameraGeometry(projection="fisheye", focal_m=1.8e-3)
MAG = MagSpec(declination_deg=-5.415, inclination_deg=56.938, intensity_nt=54121.0)  # IGRF-13 at the site


def _sun_n() -> np.ndarray:
    return SunModel(EPOCH, 69.0).sun_enu(0.0, TAIYUAN[0] * DEG, TAIYUAN[1] * DEG, TAIYUAN[2])


def test_kmeans_matches_scipy_kmeans2_from_the_same_start():
    rng = np.random.default_rng(4)
    x = np.concatenate([rng.normal(0.05, 0.02, 40), rng.normal(0.35, 0.05, 120), rng.normal(0.62, 0.04, 90)])
    centres, labels = kmeans_1d(x, 3, 20)
    lo, hi = x.min(), x.max()
    start = lo + (np.arange(3) + 0.5) * (hi - lo) / 3
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        c_ref, l_ref = kmeans2(x[:, None], start[:, None], iter=20, minit="matrix")
    assert np.allclose(centres, c_ref[:, 0], atol=1e-12) and np.array_equal(labels, l_ref)


@pytest.mark.parametrize("heading", [0.0, 144.9, 300.0])
def test_pitch_roll_and_heading_invert_the_papers_rotation_order_exactly(heading):
    s_n = _sun_n()
    b_n = field_enu(MAG)
    for pitch in (-20.0, -5.0, 10.0, 20.0):
        for roll in (-20.0, 5.0, 20.0):
            yaw = yaw_from_heading(heading * DEG)
            cbn = a2mat(pitch * DEG, roll * DEG, yaw)  # C_b^n; A->B = C_n^b = R_Y(roll) R_X(pitch) R_Z(yaw)
            th, ga = pitch_roll_from_sun(cbn.T @ s_n, s_n, yaw, 0.0)
            assert (th / DEG, ga / DEG) == pytest.approx((pitch, roll), abs=1e-9)
            assert heading_from_mag(cbn.T @ b_n, pitch * DEG, roll * DEG, MAG.declination_deg * DEG) == \
                pytest.approx(yaw, abs=1e-12)


def _tilt_grid():
    for heading in (0.0, 90.0, 144.9, 200.0, 300.0):
        for pitch in (-20.0, -10.0, 0.0, 10.0, 20.0):
            for roll in (-20.0, 5.0, 20.0):
                yield heading, pitch, roll


def test_all_sky_images_give_pitch_and_roll_within_a_tenth_of_a_degree_or_a_refusal():
    """Done-when: 75 simulated all-sky images (Rayleigh sky, ground below the horizon, AOP noise 0.1 deg at DOP
    0.5, magnetometer noise 15 nT / sqrt(5)): every answer within 0.1 deg in pitch and roll; a refusal exactly when
    the Sun is outside (or at the edge of) the lens's field; never a wrong answer."""
    rng = np.random.default_rng(11)
    p = KmeansParams(mag_declination_deg=MAG.declination_deg, mag_inclination_deg=MAG.inclination_deg)
    cs = CameraSpec(CAM, stride_px=64, aop_sigma_deg=0.1)
    s_n = _sun_n()
    b_n = field_enu(MAG)
    worst = 0.0
    answered = refused = 0
    for heading, pitch, roll in _tilt_grid():
        cbn = a2mat(pitch * DEG, roll * DEG, yaw_from_heading(heading * DEG))
        x, y, aop, dop = camera_observation(cs, cbn.T, s_n, rng)
        up_c = cbn.T[:, 2]  # the sky mask the firmware builds from its INS tilt (here: the truth)
        sky = CAM.view_rays(x, y) @ up_c > math.sin(2 * DEG)
        f = find_sun(x, y, aop.astype(np.float32), dop.astype(np.float32), CAM, sky, p, 0.05)
        sun_theta = math.degrees(math.acos((cbn.T @ s_n)[2]))
        if not f.ok:
            refused += 1
            assert f.reason == "sun_outside_fov" and sun_theta > 80.0, (heading, pitch, roll, f.reason, sun_theta)
            continue
        answered += 1
        m_b = cbn.T @ b_n + rng.normal(0.0, 15.0 / math.sqrt(5), 3)
        fix = kmeans_attitude(f, CAM.c_c_b, s_n, m_b, p.mag_declination_deg * DEG, (0.0, 0.0, 0.0),
                              p.attitude_iterations, p.mag_inclination_deg * DEG)
        err = max(abs(fix.pitch / DEG - pitch), abs(fix.roll / DEG - roll))
        worst = max(worst, err)
        assert abs((heading_from_yaw(fix.yaw) / DEG - heading + 180.0) % 360.0 - 180.0) < 0.3
        assert sun_theta < 84.8  # an answer only with the Sun inside the 85 deg field
    assert worst < 0.1 and answered >= 55 and refused >= 10


def test_firmware_tilt_series_fixes_within_a_tenth_of_a_degree_and_refuses_outside_the_field():
    traj = segment_trajectory([{"static": {"duration_s": 15}},
                               {"pitch": {"to_deg": -20, "rate_dps": 5, "duration_s": 15}},
                               {"roll": {"to_deg": 5, "rate_dps": 5, "duration_s": 15}},
                               {"pitch": {"to_deg": 15, "rate_dps": 5, "duration_s": 15}},
                               {"roll": {"to_deg": -40, "rate_dps": 5, "duration_s": 20}}],
                              heading_deg=144.9, duration=80.0, where=TAIYUAN)
    spec = StreamSpec(traj, 80.0, epoch=EPOCH, imu=ImuErrors((9, -7, 3), 0.15, (1500, -1000, 2000), 100),
                      gnss=GnssSpec(True, 3.0, 0.03), psns="camera", psns_rate_hz=2,
                      camera=CameraSpec(CAM, stride_px=64, aop_sigma_deg=0.1), mag=MAG)
    cfg = FirmwareConfig(filter="kmeans_3d", camera=CAM, initial_heading_deg=145.5)
    cfg.variants.kmeans_3d.mag_declination_deg = MAG.declination_deg
    cfg.variants.kmeans_3d.mag_inclination_deg = MAG.inclination_deg
    fw = Firmware(cfg)
    fixes = []

    def on_tick(fw, r):
        f = fw.filter
        if f.last_fix is not None and (not fixes or fixes[-1][0] != f.last_fix_t):
            st = traj.state(f.last_fix_t)
            fixes.append((f.last_fix_t, (f.last_fix.pitch - st.pitch) / DEG, (f.last_fix.roll - st.roll) / DEG))

    samples, events = run(fw, spec, on_tick=on_tick)
    fx = np.array(fixes)
    assert len(fx) >= 90 and np.abs(fx[:, 1:]).max() < 0.1
    refusals = [e for e in events if e["event"] == "kmeans_refused"]
    assert refusals and refusals[0]["reason"] == "sun_outside_fov"
    t_ref = refusals[0]["t_fpga_s"]
    st = traj.state(t_ref)
    s_b = st.c_bn.T @ SunModel(EPOCH, 69.0).sun_enu(t_ref, float(st.pos[0]), float(st.pos[1]), float(st.pos[2]))
    assert math.degrees(math.acos(s_b[2])) > 80.0  # refused because the Sun really left the (85 deg) field
    assert not [t for t, *_ in fixes if t > refusals[0]["t_fpga_s"]]  # no answer after the Sun left the field
    assert max(np.linalg.norm(s.att_err_deg) for s in samples if s.t > 5) < 0.15
    assert fw.filter.variant_status()[0] == 2  # VARIANT mode: refused
    # budget: the worst tick (K-means over ~400 points, eigen solve, attitude) stays far inside 200 Hz
    assert fw.meter.tasks["imu_tick"].cycles_max < 0.2 * fw.meter.tick_budget


def test_fix_measurement_is_the_first_order_error_of_the_fix():
    """D-5.23: the fix built from a sun turned by ``mu`` (ENU) and a yaw off by ``dyaw`` errs by
    ``phi_fix = G mu + s dpsi / (c . s)``, ``G = I - s c^T / (c . s)``, against the pitch/roll construction itself;
    ``c`` against a numerical derivative of the PSINS yaw; R and H are that map's covariance and columns."""
    from firmware_model.attitude import a2mat, m2att
    from firmware_model.variants.common import misalignment_between
    from firmware_model.variants.kmeans_3d import fix_measurement, pitch_roll_from_sun

    deg = math.pi / 180.0
    s_n = np.array([-0.876416, -0.282797, 0.389770])
    s_n = s_n / np.linalg.norm(s_n)
    pitch, roll, yaw = 12.0 * deg, -7.0 * deg, 40.0 * deg
    c_true = a2mat(pitch, roll, yaw)
    H, R = fix_measurement(s_n, pitch, yaw, 1e-6, 4e-6, 21, 18, None)
    g = -H[:, 18:21]
    c = np.array([math.tan(pitch) * math.sin(yaw), -math.tan(pitch) * math.cos(yaw), 1.0])
    for i in range(3):  # a misalignment phi turns the yaw by -c . phi
        e = np.zeros(3)
        e[i] = 1e-7
        turned = (np.eye(3) - np.array([[0, -e[2], e[1]], [e[2], 0, -e[0]], [-e[1], e[0], 0]])) @ c_true
        assert (m2att(turned)[2] - yaw) / 1e-7 == pytest.approx(-c[i], abs=1e-6)
    rng = np.random.default_rng(3)
    for _ in range(20):
        mu = rng.normal(0.0, 1e-4, 3)
        dyaw = float(rng.normal(0.0, 1e-4))
        s_meas_b = c_true.T @ (s_n + np.cross(mu, s_n))
        s_meas_b /= np.linalg.norm(s_meas_b)
        pr = pitch_roll_from_sun(s_meas_b, s_n, yaw + dyaw, pitch)
        assert pr is not None
        phi_fix = misalignment_between(a2mat(pr[0], pr[1], yaw + dyaw), c_true)
        np.testing.assert_allclose(phi_fix, g @ mu + s_n * (-dyaw) / (c @ s_n), atol=1e-6)  # ~1e-3 of it
    np.testing.assert_allclose(H[:, :3], np.eye(3))
    np.testing.assert_allclose(g @ s_n, 0.0, atol=1e-15)
    np.testing.assert_allclose(c @ g, 0.0, atol=1e-15)
    np.testing.assert_allclose(R, 1e-6 * g @ g.T + 4e-6 * np.outer(s_n, s_n) / (c @ s_n) ** 2, rtol=1e-12)
    # without a heading the INS's yaw stands: the attitude columns are G (rank 2, its left null vector c)
    H0, R0 = fix_measurement(s_n, pitch, yaw, 1e-6, None, 15, None, None)
    np.testing.assert_allclose(H0[:, :3], g, atol=1e-15)
    np.testing.assert_allclose(R0, 1e-6 * g @ g.T, rtol=1e-12)


@pytest.mark.parametrize(("pitch", "roll", "yaw"), [(12.0, -7.0, 40.0), (-20.0, 5.0, -145.0), (15.0, -35.0, 100.0)])
def test_mag_fix_heading_axis_is_the_tilt_compensations_jacobian(pitch, roll, yaw):
    """D-5.31: the tilt-compensated heading's partials on pitch and roll (finite differences of
    :func:`heading_from_mag` with the field the box sees) times the Euler errors of a misalignment (finite
    differences of ``m2att``), added to the INS yaw's ``c``, give ``c_m = (tan I sin D, tan I cos D, 1)`` at any
    attitude; the closed-form partials of the docstring match the differences."""
    from firmware_model.attitude import m2att
    from firmware_model.variants.kmeans_3d import mag_heading_axis

    p, r, y = pitch * DEG, roll * DEG, yaw * DEG
    dec, inc = MAG.declination_deg * DEG, MAG.inclination_deg * DEG
    c_true = a2mat(p, r, y)
    m_b = c_true.T @ field_enu(MAG)
    assert heading_from_mag(m_b, p, r, dec) == pytest.approx(y, abs=1e-9)
    h = 1e-6
    j_p = (heading_from_mag(m_b, p + h, r, dec) - heading_from_mag(m_b, p - h, r, dec)) / (2 * h)
    j_r = (heading_from_mag(m_b, p, r + h, dec) - heading_from_mag(m_b, p, r - h, dec)) / (2 * h)
    ti = math.tan(inc)
    assert j_p == pytest.approx(-ti * math.sin(y + dec), abs=1e-7)
    assert j_r == pytest.approx(-math.sin(p) - math.cos(p) * ti * math.cos(y + dec), abs=1e-7)
    euler = np.zeros((3, 3))  # d(pitch, roll, yaw) / d phi, numerically
    for i in range(3):
        e = np.zeros(3)
        e[i] = h
        turned = (np.eye(3) - np.array([[0, -e[2], e[1]], [e[2], 0, -e[0]], [-e[1], e[0], 0]])) @ c_true
        euler[:, i] = (np.array(m2att(turned)) - np.array([p, r, y])) / h
    c_m = -euler[2] + j_p * euler[0] + j_r * euler[1]  # -dyaw_fix + dyaw_mag(tilt) = c_m . phi
    np.testing.assert_allclose(c_m, mag_heading_axis(dec, inc), atol=1e-5)
    np.testing.assert_allclose(mag_heading_axis(dec, inc) @ field_enu(MAG), 0.0, atol=1e-12)


def test_mag_fix_measurement_is_the_first_order_error_of_the_self_consistent_fix():
    """D-5.31: the fix solved by :func:`kmeans_attitude` (heading from the magnetometer compensated with the fix's
    own tilt, iterated to self-consistency) from a sun turned by ``mu`` and a magnetometer heading off by ``w``
    errs by ``phi_fix = G_m mu + s (-w) / (c_m . s)``, ``G_m = I - s c_m^T / (c_m . s)``; the old axis ``c`` (the
    heading independent of the level) misses the sun's share of the heading by far more than the first order."""
    from firmware_model.attitude import m2att
    from firmware_model.variants.common import misalignment_between
    from firmware_model.variants.kmeans_3d import SunFinding, fix_measurement, mag_heading_axis

    s_n = _sun_n()
    dec, inc = MAG.declination_deg * DEG, MAG.inclination_deg * DEG
    pitch, roll, yaw = -20.0 * DEG, 5.0 * DEG, yaw_from_heading(144.9 * DEG)
    c_true = a2mat(pitch, roll, yaw)
    m_b = c_true.T @ field_enu(MAG)
    c_m = mag_heading_axis(dec, inc)
    H, R = fix_measurement(s_n, pitch, yaw, 1e-6, 4e-6, 22, 18, None, 21, c_m)
    g_m = -H[:, 18:21]
    cs = float(c_m @ s_n)
    np.testing.assert_allclose(g_m, np.eye(3) - np.outer(s_n, c_m) / cs, atol=1e-15)
    np.testing.assert_allclose(H[:, 21], -s_n / cs, atol=1e-15)
    np.testing.assert_allclose(R, 1e-6 * g_m @ g_m.T + 4e-6 * np.outer(s_n, s_n) / cs ** 2, rtol=1e-12)
    tp = math.tan(pitch)
    c = np.array([tp * math.sin(yaw), -tp * math.cos(yaw), 1.0])
    g_old = np.eye(3) - np.outer(s_n, c) / float(c @ s_n)
    rng = np.random.default_rng(5)
    worst_new = worst_old = 0.0
    for _ in range(10):
        mu = rng.normal(0.0, 1e-3, 3)
        w = float(rng.normal(0.0, 1e-3))
        s_meas_b = c_true.T @ (s_n + np.cross(mu, s_n))
        finding = SunFinding(True, "sun_in_fov", s_c=s_meas_b / np.linalg.norm(s_meas_b))
        fix = kmeans_attitude(finding, np.eye(3), s_n, m_b, dec - w, (pitch, roll, yaw), 4, inc)
        assert fix is not None and fix.heading_source == "magnetometer"
        assert heading_from_mag(m_b, fix.pitch, fix.roll, dec - w) == pytest.approx(fix.yaw, abs=1e-12)
        phi_fix = misalignment_between(a2mat(fix.pitch, fix.roll, fix.yaw), c_true)
        size = float(np.linalg.norm(phi_fix))
        worst_new = max(worst_new, float(np.linalg.norm(phi_fix - (g_m @ mu - s_n * w / cs))) / size)
        worst_old = max(worst_old, float(np.linalg.norm(phi_fix - (g_old @ mu - s_n * w / float(c @ s_n)))) / size)
        assert m2att(a2mat(fix.pitch, fix.roll, fix.yaw))[0] == pytest.approx(fix.pitch, abs=1e-12)
    assert worst_new < 0.01  # second order: a few 1e-3 of the error at 1e-3 rad
    assert worst_old > 0.3


def test_fix_events_report_every_single_fix_and_change_nothing_else():
    """``fix_events`` (the single fixes of Yang et al.'s field table, benchmarks/paper_reproductions.py yang): one
    ``kmeans_fix`` event per solved frame, carrying the fix the filter weighed at its exposure time; the navigation
    output and every other event are the same with it off, and off there is no such event."""
    traj = segment_trajectory([{"static": {"duration_s": 8}},
                               {"pitch": {"to_deg": -10, "rate_dps": 5, "duration_s": 8}}],
                              heading_deg=144.9, duration=16.0, where=TAIYUAN)
    spec = StreamSpec(traj, 16.0, epoch=EPOCH, imu=ImuErrors((9, -7, 3), 0.15, (1500, -1000, 2000), 100),
                      gnss=GnssSpec(True, 3.0, 0.03), psns="camera", psns_rate_hz=2,
                      camera=CameraSpec(CAM, stride_px=64, aop_sigma_deg=0.1), mag=MAG)
    out = {}
    for on in (False, True):
        cfg = FirmwareConfig(filter="kmeans_3d", camera=CAM, initial_heading_deg=145.5)
        cfg.variants.kmeans_3d.mag_declination_deg = MAG.declination_deg
        cfg.variants.kmeans_3d.mag_inclination_deg = MAG.inclination_deg
        cfg.variants.kmeans_3d.fix_events = on
        fw = Firmware(cfg)
        fixes = []

        def on_tick(fw, r, fixes=fixes):
            f = fw.filter
            if f.last_fix is not None and (not fixes or fixes[-1][0] != f.last_fix_t):
                fixes.append((f.last_fix_t, f.last_fix.pitch / DEG, f.last_fix.roll / DEG,
                              heading_from_yaw(f.last_fix.yaw) / DEG))

        samples, events = run(fw, spec, on_tick=on_tick)
        out[on] = (samples, events, fixes)
    (s_off, ev_off, fx_off), (s_on, ev_on, fx_on) = out[False], out[True]
    assert not [e for e in ev_off if e["event"] == "kmeans_fix"]
    logged = [e for e in ev_on if e["event"] == "kmeans_fix"]
    assert len(fx_on) >= 20 and len(logged) == len(fx_on)
    for e, (t, p, r, h) in zip(logged, fx_on):
        assert e["t_meas_us"] == round(t * 1e6) and e["reason"] == "magnetometer"
        # event floats keep 6 significant digits (mode_manager._clean)
        assert (e["t_meas_s"], e["pitch_deg"], e["roll_deg"], e["heading_deg"]) == pytest.approx((t, p, r, h),
                                                                                                  rel=6e-6)
    assert fx_on == fx_off
    assert [e for e in ev_on if e["event"] != "kmeans_fix"] == ev_off
    assert [(s.t, s.pitch_err_deg, s.roll_err_deg) for s in s_on] == [(s.t, s.pitch_err_deg, s.roll_err_deg)
                                                                       for s in s_off]
