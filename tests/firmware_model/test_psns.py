"""PSNS solve: Stokes/AOP convention (docs/architecture.md "Conventions"), E-vectors, closed-form eigen solve, solar
vector accuracy."""

import math

import numpy as np
import pytest

from firmware_model import psns
from firmware_model.attitude import a2mat, yaw_from_heading
from firmware_model.psns_geometry import (
    CameraGeometry,
    compass_unit_mountings,
    compass_view_rays,
)
from protocols.constants import DEG

from .sky import observe_sky, rayleigh, render_mosaic

S_BEIJING = np.array([-0.876416, -0.282797, 0.389770])  # docs/reference/algorithms.md section 3 (ENU)


def _angle_deg(a, b) -> float:
    """Angle between two axes (sign-insensitive), robust near zero."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    return math.degrees(math.atan2(np.linalg.norm(np.cross(a, b)), abs(float(a @ b))))


def _sun_in_camera(heading_deg, pitch_deg, roll_deg, s_n=S_BEIJING):
    cbn = a2mat(pitch_deg * DEG, roll_deg * DEG, yaw_from_heading(heading_deg * DEG))
    s = cbn.T @ (s_n / np.linalg.norm(s_n))
    return s


# -- AOP convention ----------------------------------------------------------------------------------
def test_stokes_and_aop_follow_the_c1_convention():
    # an E-vector projecting on the image plane at psi = 30 deg from +x towards +y
    psi = 30 * DEG
    theta_p = np.deg2rad([0, 45, 90, 135])
    i = 0.5 * 1000 * (1 + 0.6 * np.cos(2 * (psi - theta_p)))
    s0, s1, s2 = psns.stokes(*i)
    dop, psi_m = psns.dop_psi(np.float64(s0), np.float64(s1), np.float64(s2))
    assert dop == pytest.approx(0.6, abs=1e-12) and psi_m == pytest.approx(psi, abs=1e-12)
    aop = psns.aop_from_psi(psi_m)
    assert aop == pytest.approx(60 * DEG)  # measured from +y towards +x
    # projection is proportional to (sin AOP, cos AOP) = (cos psi, sin psi)
    assert math.sin(aop) == pytest.approx(math.cos(psi)) and math.cos(aop) == pytest.approx(math.sin(psi))


@pytest.mark.parametrize("psi_deg, aop_deg", [(0, 90), (90, 0), (-90, 0), (100, -10), (-45, -45), (45, 45), (-89, -1)])
def test_aop_wraps_to_half_open_interval(psi_deg, aop_deg):
    a = float(psns.aop_from_psi(np.float64(psi_deg * DEG))) / DEG
    assert a == pytest.approx(aop_deg, abs=1e-9)
    assert -90 < a <= 90


# -- calibrated polarizer angles ---------------------------------------------------------------------
BIAS_DEG = (0.8, -0.5, 0.3, -0.6)
ANGLES_DEG = tuple(t + b for t, b in zip((0.0, 45.0, 90.0, 135.0), BIAS_DEG, strict=True))


def _wire_point(psi, dop, angles_deg, er):
    """One point as the camera sends it: Malus through polarizers at ``angles_deg`` (extinction ratio ``er``),
    Stokes with the nominal angles (independent of the firmware's formulas), AOP = 90 deg - psi wrapped."""
    th = np.radians(angles_deg)
    dia = (er - 1.0) / (er + 1.0)
    i0, i45, i90, i135 = 2000.0 * (1.0 + dia * dop * np.cos(2.0 * (psi - th)))
    s0, s1, s2 = 0.5 * (i0 + i45 + i90 + i135), i0 - i90, i45 - i135
    psi_w = 0.5 * math.atan2(s2, s1)
    aop_w = math.pi / 2 - psi_w
    return (aop_w - math.pi if aop_w > math.pi / 2 else aop_w), math.hypot(s1, s2) / s0


def _aop_err_deg(a, b):
    d = (float(a) - float(b)) / DEG
    return abs((d + 90.0) % 180.0 - 90.0)


@pytest.mark.parametrize("dtype, tol_deg", [(np.float64, 1e-9), (np.float32, 2e-4)])
def test_known_polarizer_biases_are_removed_closed_form(dtype, tol_deg):
    """Single points with channel biases in: corrected with the true angles, AOP and DOP equal the truth (a
    noise-free closed form); corrected with the nominal angles (an uncalibrated unit), the error stays."""
    cam = CameraGeometry(polarizer_deg=ANGLES_DEG, extinction_ratio=300.0)
    nominal = CameraGeometry(extinction_ratio=300.0)
    worst_nominal = 0.0
    for psi_deg in np.arange(-89.0, 91.0, 7.0):
        for dop in (0.05, 0.3, 0.8):
            psi = psi_deg * DEG
            aop_w, dop_w = _wire_point(psi, dop, ANGLES_DEG, 300.0)
            truth = psns.aop_from_psi(np.float64(psi))
            a, d = psns.correct_polarizer(np.array([aop_w]), np.array([dop_w]), cam, dtype=dtype)
            assert a.dtype == dtype and _aop_err_deg(a[0], truth) < tol_deg, (psi_deg, dop)
            assert float(d[0]) == pytest.approx(dop, rel=tol_deg)
            a, _ = psns.correct_polarizer(np.array([aop_w]), np.array([dop_w]), nominal, dtype=dtype)
            worst_nominal = max(worst_nominal, _aop_err_deg(a[0], truth))
    # first order: the shear of M moves the AOP by (d0+d90 + d45+d135)/4 cos 4 psi plus the common (sum d)/4
    assert worst_nominal > 0.3, worst_nominal


def test_nominal_polarizer_angles_are_the_identity_and_cheap():
    cam = CameraGeometry()
    aop = np.radians(np.array([-89.99, -30.0, 0.0, 45.0, 90.0]))
    dop = np.array([0.1, 0.2, 0.3, 0.4, 0.5])
    a, d = psns.correct_polarizer(aop, dop, cam, dtype=np.float64)
    assert np.array_equal(a, aop) and np.array_equal(d, dop)
    biased = CameraGeometry(polarizer_deg=ANGLES_DEG)
    # the docstring's figures: 1 MPYSP per point; 59 cycles of vector MATHLIB + 9 of arithmetic per point
    assert psns.polarizer_cycles(225, cam) == 225 + 40
    assert psns.polarizer_cycles(225, biased) == 225 * (59 + 9) + 3 * 40
    m, g = psns.polarizer_matrix((0.0, 45.0, 90.0, 135.0))
    assert np.allclose(m, 2 * np.eye(2)) and np.allclose(g, 0.0)


def test_evector_is_perpendicular_to_view_ray_both_projections():
    rng = np.random.default_rng(3)
    for cam in (CameraGeometry(), CameraGeometry(projection="fisheye", focal_m=3.7e-3)):
        x = rng.integers(1, cam.nx + 1, 500)
        y = rng.integers(1, cam.ny + 1, 500)
        aop = rng.uniform(-math.pi / 2, math.pi / 2, 500)
        e = psns.evectors_camera(x, y, aop, cam, dtype=np.float64)
        v = cam.view_rays(x, y)
        assert np.max(np.abs(np.sum(e * v, axis=1))) < 1e-12
        assert np.allclose(np.linalg.norm(e, axis=1), 1.0)
        # and its image-plane projection has the angle AOP from +y towards +x
        assert np.allclose(np.arctan2(e[:, 0], e[:, 1]) % np.pi, aop % np.pi)


# -- eigen solver ------------------------------------------------------------------------------------
def test_closed_form_eigen_matches_numpy_eigh():
    rng = np.random.default_rng(7)
    for _ in range(300):
        a = rng.normal(size=(3, 3))
        K = a @ a.T + rng.uniform(0, 1e-3) * np.eye(3)
        v, lam = psns.sym3_eigen_smallest(K)
        w, V = np.linalg.eigh(K)
        assert np.allclose(lam, w, rtol=1e-9, atol=1e-9 * w[2])
        if (w[1] - w[0]) > 1e-3 * w[2]:
            assert _angle_deg(v, V[:, 0]) < 1e-6
    # single precision, a realistic K (rank ~2, lambda_min ~ 0)
    cam = CameraGeometry()
    obs = observe_sky(_sun_in_camera(30, 2, -3), cam, stride_px=32)
    e = psns.evectors_camera(obs.x_px, obs.y_px, obs.aop_deg * DEG, cam)
    K32 = psns.scatter_matrix(e, obs.dop.astype(np.float32))
    v32, lam32 = psns.sym3_eigen_smallest(K32)
    w, V = np.linalg.eigh(K32.astype(np.float64))
    assert v32.dtype == np.float32
    assert _angle_deg(v32, V[:, 0]) < 1e-4
    assert lam32[2] == pytest.approx(w[2], rel=1e-5)


# -- solar vector accuracy ------------------------------------------------------------------------
ATTITUDES = [(30, 2, -3), (120, -5, 4), (250, 10, 0), (330, 0, 8)]


@pytest.mark.parametrize("cam", [CameraGeometry(), CameraGeometry(projection="fisheye", focal_m=3.7e-3)],
                         ids=["pinhole", "fisheye"])
def test_noise_free_camera_below_0p001_deg(cam):
    for att in ATTITUDES:
        s_c = _sun_in_camera(*att)
        obs = observe_sky(s_c, cam, stride_px=48)
        e = psns.evectors_camera(obs.x_px, obs.y_px, obs.aop_deg * DEG, cam)
        sol = psns.solve_solar_vector(e, obs.dop.astype(np.float32))
        assert sol.valid and sol.n_used > 1000
        assert _angle_deg(sol.s, s_c) < 0.001
        assert sol.quality < 1e-4


def test_reference_camera_noise_median_below_0p05_deg():
    """Full well 10 000 e-, 5 e- read noise, 12-bit, extinction ratio 300 (docs/reference/algorithms.md 2.2)."""
    rng = np.random.default_rng(29)
    cam = CameraGeometry()
    errs = []
    for heading in range(0, 360, 30):
        s_c = _sun_in_camera(heading, rng.uniform(-5, 5), rng.uniform(-5, 5))
        obs = observe_sky(s_c, cam, stride_px=16, rng=rng)  # ~19 600 points, 1/16 of the half-res grid
        e = psns.evectors_camera(obs.x_px, obs.y_px, obs.aop_deg * DEG, cam)
        sol = psns.solve_solar_vector(e, obs.dop.astype(np.float32))
        assert sol.valid
        errs.append(_angle_deg(sol.s, s_c))
    assert np.median(errs) < 0.05, errs
    assert max(errs) < 0.15


def test_wire_quantised_points_like_a_polarization_obs_frame():
    """0.01 deg AOP and 1/65535 DOP quantisation, ~200 points (what fits UART2 at 5 Hz)."""
    cam = CameraGeometry()
    s_c = _sun_in_camera(30, 2, -3)
    obs = observe_sky(s_c, cam, stride_px=160)
    aop = np.round(obs.aop_deg * 100) * (0.01 * DEG)
    dop = (np.round(obs.dop * 65535) / 65535).astype(np.float32)
    e = psns.evectors_camera(obs.x_px, obs.y_px, aop, cam)
    sol = psns.solve_solar_vector(e, dop)
    assert 150 < sol.n_used < 230
    assert _angle_deg(sol.s, s_c) < 0.01


def test_raw_mosaic_superpixel_path():
    cam = CameraGeometry(nx=612, ny=512, dx_m=4 * 3.45e-6, dy_m=4 * 3.45e-6)  # 1/4 resolution, same FOV
    s_c = _sun_in_camera(30, 2, -3)
    raw = render_mosaic(s_c, cam)
    x, y, aop, dop, s0 = psns.mosaic_observations(raw)
    assert x.shape == (306 * 256,) and np.all(s0 > 0)
    e = psns.evectors_camera(x, y, aop, cam)
    sol = psns.solve_solar_vector(e, dop)
    # the four pixels of a super-pixel see slightly different rays: a small systematic error remains
    assert _angle_deg(sol.s, s_c) < 0.05
    raw_n = render_mosaic(s_c, cam, rng=np.random.default_rng(5))
    x, y, aop, dop, _ = psns.mosaic_observations(raw_n)
    sol = psns.solve_solar_vector(psns.evectors_camera(x, y, aop, cam), dop)
    assert _angle_deg(sol.s, s_c) < 0.1


def test_too_few_points_or_isotropic_is_invalid():
    e = np.eye(3, dtype=np.float32)
    assert not psns.solve_solar_vector(e[:2], np.array([0.5, 0.5], dtype=np.float32)).valid
    sol = psns.solve_solar_vector(e, np.array([0.5, 0.5, 0.5], dtype=np.float32))
    assert not sol.valid and sol.quality == pytest.approx(1.0)
    assert not psns.solve_solar_vector(e, np.array([0.01, 0.01, 0.01], dtype=np.float32)).valid  # below DOP_min


# -- multi-unit compass geometry -------------------------------------------------------------------
def test_default_compass_geometry():
    m = compass_unit_mountings()
    assert m.shape == (9, 3, 3)
    assert np.allclose(m[0], np.eye(3))
    for c in m:
        assert np.allclose(c.T @ c, np.eye(3), atol=1e-12) and np.linalg.det(c) == pytest.approx(1.0)
    rays = compass_view_rays(m)
    zen = np.degrees(np.arccos(rays[1:, 2]))
    assert np.allclose(zen, 45.0)
    az = np.degrees(np.arctan2(rays[1:, 0], rays[1:, 1])) % 360
    assert np.allclose(az, np.arange(0, 360, 45))
    # each ring unit's +y points up the hemisphere: towards the zenith, in the ray's vertical plane
    y = m[1:, :, 1]
    assert np.all(y[:, 2] > 0.7)
    assert np.allclose(np.einsum("ij,ij->i", y, np.cross(rays[1:], [0, 0, 1.0])), 0.0, atol=1e-12)


def test_compass_units_recover_the_sun():
    m = compass_unit_mountings()
    s_b = _sun_in_camera(75, 3, -2)
    rays = compass_view_rays(m)
    dop, e_b = rayleigh(s_b, rays)
    # each unit measures the AOP of E in its own x-y plane, from its +y towards +x
    e_u = np.einsum("nji,nj->ni", m, e_b)
    aop = np.arctan2(e_u[:, 0], e_u[:, 1])
    e = psns.evectors_compass(aop, m, dtype=np.float64)
    sol = psns.solve_solar_vector(e, dop)
    assert _angle_deg(sol.s, s_b) < 1e-9


def test_exposure_time_tag_c1():
    # 36-byte SOLAR_VECTOR frame at 115200 8N1 (10 bits/byte), 30 ms latency
    t = psns.exposure_time_s(10.0, 36, 115200, 30000)
    assert t == pytest.approx(10.0 - 36 * 10 / 115200 - 0.030)


def test_calibrated_evectors_per_point_terms_cached_per_camera_and_point_set():
    # the lens terms of a point set are computed once and reused; another camera or point set gets its own
    from firmware_model.psns import _POINT_GEOMETRY, _point_geometry
    from firmware_model.psns_geometry import CameraGeometry as _Cam

    cam_a = _Cam(k1=-0.05, k2=0.01, exit_pupil_m=0.02, cx_px=1230.0)
    cam_b = _Cam(k1=0.03, exit_pupil_m=None)
    rng = np.random.default_rng(4)
    x = rng.uniform(1, 2448, 50).round()
    y = rng.uniform(1, 2048, 50).round()
    aop = rng.uniform(-1.5, 1.5, 50)
    for cam in (cam_a, cam_b):
        for dt in (np.float32, np.float64):
            first = psns.evectors_camera(x, y, aop, cam, dtype=dt)
            again = psns.evectors_camera(x.copy(), y.copy(), aop, cam, dtype=dt)
            assert np.array_equal(first, again)
            cached = _POINT_GEOMETRY.get(x, y, cam, dt)
            assert cached[0].dtype == dt and not cached[0].flags.writeable
            for c, f in zip(cached, _point_geometry(x, y, cam, dt)):
                assert np.array_equal(c, f)
            # a unit vector perpendicular to its ray, whatever the lens
            assert np.allclose(np.linalg.norm(first, axis=1), 1.0, atol=1e-6)
    e_a = psns.evectors_camera(x, y, aop, cam_a, dtype=np.float64)
    e_b = psns.evectors_camera(x, y, aop, cam_b, dtype=np.float64)
    assert np.abs(e_a - e_b).max() > 1e-3  # not the other camera's terms
    e_sub = psns.evectors_camera(x[:20], y[:20], aop[:20], cam_a, dtype=np.float64)
    assert np.array_equal(e_sub, e_a[:20])


def test_obs_points_array_is_the_array_of_the_point_objects():
    """``obs_points_array`` (from a frame's point bytes) is, byte for byte and in layout, the ``(n, 4)`` float64 array
    the loop built from the point objects, ``np.array([(p.x_px, p.y_px, p.aop_cdeg, p.dop) for p in points])``,
    every field over its whole range (performance.md 5.7, D-10.E9)."""
    from protocols.psns import PolarizationObs, PolarizationPoint, PsnsHeader

    rng = np.random.default_rng(4)
    for n in (1, 3, 225):
        pts = tuple(PolarizationPoint(int(rng.integers(0, 65536)), int(rng.integers(0, 65536)),
                                      int(rng.integers(-32768, 32768)), int(rng.integers(0, 65536)),
                                      int(rng.integers(0, 65536))) for _ in range(n))
        if n == 225:
            pts = (PolarizationPoint(0, 65535, -32768, 65535, 0), PolarizationPoint(65535, 0, 32767, 0, 65535),
                   *pts[2:])
        ref = np.array([(p.x_px, p.y_px, p.aop_cdeg, p.dop) for p in pts], dtype=np.float64)
        got = psns.obs_points_array(PolarizationObs(PsnsHeader(0, 0, 0, 1, n), pts).point_bytes)
        assert got.dtype == ref.dtype and got.shape == ref.shape == (n, 4)
        assert got.flags.c_contiguous and got.strides == ref.strides and got.tobytes() == ref.tobytes()
