"""Polarization camera: the conventions' geometry, the mosaic layout against polanalyser, exact inversion, noise."""

from __future__ import annotations

import asyncio
import datetime as dt
import math

import numpy as np
import pytest

from emulator.clock import EmulatorLoop
from emulator.devices.camera import (
    CHANNEL_OFFSETS,
    CameraConfig,
    CameraGeometry,
    PolarizationCamera,
    PolarizationCameraModel,
    mounting_matrix,
    stokes_superpixel,
    wire_aop_cdeg,
)
from emulator.links import LineConfig, MemHub
from emulator.world.sky import SkyModel
from emulator.world.sun import SunModel
from emulator.world.trajectory import StaticTrajectory
from protocols.constants import DEG
from protocols.psns import PolarizationObs, PsnsFormat, PsnsStatus, max_points
from protocols.stream import StreamDecoder

EPOCH = dt.datetime(2019, 9, 18, 8, 14, tzinfo=dt.UTC)  # sun az 252.1, el 22.9 in Beijing


def model(fidelity="binned", noise=True, seed=1, heading=30.0, pitch=0.0, roll=0.0, epoch=EPOCH, sky=None, **kw):
    traj = StaticTrajectory(39.979, 116.339, 50.0, heading, pitch, roll)
    cfg = CameraConfig(fidelity=fidelity, noise=noise, **kw)
    return PolarizationCameraModel(cfg, sky or SkyModel(), SunModel(epoch, 69.0), traj, np.random.default_rng(seed))


def inverted_e(geo_cfg, x, y, aop):
    """The firmware's inversion (the camera conventions): E^c from the wire AOP at pixel (x, y)."""
    X = geo_cfg.pixel_m * (x - (geo_cfg.nx + 1) / 2.0)
    Y = geo_cfg.pixel_m * (y - (geo_cfg.ny + 1) / 2.0)
    if geo_cfg.lens == "pinhole":
        e = np.stack([np.sin(aop), np.cos(aop), -(X * np.sin(aop) + Y * np.cos(aop)) / geo_cfg.focal_m], axis=1)
    else:
        r, al = np.hypot(X, Y), np.arctan2(Y, X)
        th = r / geo_cfg.focal_m
        vx, vy, vz = np.sin(th) * np.cos(al), np.sin(th) * np.sin(al), np.cos(th)
        e = np.stack([np.sin(aop), np.cos(aop), -(vx * np.sin(aop) + vy * np.cos(aop)) / vz], axis=1)
    return e / np.linalg.norm(e, axis=1, keepdims=True)


def residual_deg(m, obs, t=0.0):
    """Rotation about each view ray that would make the inverted E-vector perpendicular to the true sun."""
    _, s_c, _ = m.camera_attitude(t)
    aop = np.asarray(obs.aop)
    e = inverted_e(m.cfg, obs.x_px.astype(float), obs.y_px.astype(float), aop)
    v = np.stack(m.geo.rays(obs.x_px.astype(float), obs.y_px.astype(float))[:3], axis=1)
    s_perp = s_c[None, :] - (v @ s_c)[:, None] * v
    return np.degrees(np.abs(e @ s_c) / np.linalg.norm(s_perp, axis=1))


def test_pixel_rays_follow_c1():
    cfg = CameraConfig()
    geo = CameraGeometry(cfg)
    vx, vy, vz, _ = geo.rays(np.array([1.0, 2448.0, 1224.5]), np.array([1.0, 2048.0, 1024.5]))
    X = 3.45e-6 * (1 - 1224.5)
    Y = 3.45e-6 * (1 - 1024.5)
    n = math.sqrt(X * X + Y * Y + 16e-6)
    assert np.allclose([vx[0], vy[0], vz[0]], [X / n, Y / n, 4e-3 / n], atol=1e-15)
    assert vx[1] > 0 and vy[1] > 0 and np.allclose([vx[2], vy[2], vz[2]], [0, 0, 1])
    fe = CameraGeometry(CameraConfig(lens="fisheye", focal_m=1.8e-3))
    vx, vy, vz, ok = fe.rays(np.array([1224.5 + 400.0]), np.array([1024.5]))
    th = 400 * 3.45e-6 / 1.8e-3
    assert np.allclose([vx[0], vy[0], vz[0]], [math.sin(th), 0.0, math.cos(th)], atol=1e-15) and ok[0]
    # observation points sit at the weighted centroid of their windows (integer pixels)
    n = cfg.bin_superpixels
    sp_x = 2.0 * geo.win_cols + 1.5
    assert np.allclose((sp_x * geo.w_col).sum(axis=1) / geo.w_col.sum(), geo.x_px)
    sp_y = 2.0 * geo.win_rows + 1.5
    assert np.allclose((sp_y * geo.w_row).sum(axis=1) / geo.w_row.sum(), geo.y_px)
    assert geo.n_points == 225 and n == 8
    # every fisheye window lies inside the image circle
    assert np.all(np.arccos(fe.pt_v[:, 2]) < 90 * DEG)


def test_binned_noise_free_inversion_is_exact():
    m = model("binned", noise=False)
    obs = m.observe(0.0)
    assert obs.status & PsnsStatus.VALID
    assert np.max(residual_deg(m, obs)) < 1e-9
    # through the wire's 0.01 deg quantization (+-0.005 deg in the image plane, a little more about an oblique ray)
    obs.aop = wire_aop_cdeg(obs.aop) * 0.01 * DEG
    assert np.max(residual_deg(m, obs)) < 0.01
    # a fisheye looking through a tilted body, too
    m = model("binned", noise=False, lens="fisheye", focal_m=1.8e-3, pitch=-20.0, roll=5.0, grid=(13, 13))
    obs = m.observe(0.0)
    good = obs.dop > 0.02
    assert good.sum() > 40  # the points inside the image circle that are not next to the sun
    assert np.max(residual_deg(m, obs)[good]) < 1e-9


def test_full_noise_free_inversion_is_exact_to_second_order():
    m = model("full", noise=False)
    obs = m.observe(0.0)
    good = obs.dop > 0.1
    assert good.sum() > 100
    assert np.max(residual_deg(m, obs)[good]) < 0.01
    b = model("binned", noise=False).observe(0.0)
    assert np.max(np.abs(b.dop - obs.dop)[good]) < 2e-4


def test_mosaic_layout_matches_polanalyser():
    pa = pytest.importorskip("polanalyser")
    m = model("full", noise=False)
    mosaic = m.render_mosaic(0.0)
    i0, i45, i90, i135 = pa.demosaicing(mosaic, pa.COLOR_PolarMono)
    stokes = pa.calcStokes([i0, i45, i90, i135], np.deg2rad([0, 45, 90, 135]))
    aolp = pa.cvtStokesToAoLP(stokes)  # [0, pi), from +x towards +y
    dolp = pa.cvtStokesToDoLP(stokes)
    obs = m.observe(0.0)
    psi = (math.pi / 2 - obs.aop) % math.pi
    x, y = obs.x_px - 1, obs.y_px - 1
    d = (aolp[y, x] - psi + math.pi / 2) % math.pi - math.pi / 2
    good = obs.dop > 0.1
    assert np.max(np.abs(np.degrees(d[good]))) < 0.05
    assert np.max(np.abs(dolp[y, x] - obs.dop)[good]) < 2e-3
    # and our own half-resolution super-pixel split agrees with the channel layout
    s0, dop, _psi_img = stokes_superpixel(mosaic)
    assert s0.shape == (1024, 1224) and np.nanmax(dop) < 0.75
    for _theta, (r, c) in CHANNEL_OFFSETS.items():
        assert mosaic[r::2, c::2].shape == (1024, 1224)


def sigma_aop_formula(m, obs):
    """sigma/(sqrt(2) S0 DOP) with sigma^2 the mean channel variance of the window mean (DN^2)."""
    cfg = m.cfg
    g = cfg.gain_dn_per_e
    a = obs.s0_dn / (2 * g)  # mean electrons per channel
    sig2 = m.geo.kappa * ((a + cfg.read_noise_e**2) * g * g + 1 / 12)
    return np.sqrt(sig2) / (math.sqrt(2) * obs.s0_dn * obs.dop)


def aop_err(a, b):
    return (a - b + math.pi / 2) % math.pi - math.pi / 2


def test_binned_aop_noise_matches_formula_within_10_percent():
    truth = model("binned", noise=False, bin_superpixels=2).observe(0.0)
    m = model("binned", bin_superpixels=2, seed=4)
    errs = np.array([aop_err(m.observe(0.0).aop, truth.aop) for _ in range(600)])
    pred = sigma_aop_formula(m, truth)
    sel = truth.dop > 0.15
    ratio = errs.std(axis=0)[sel] / pred[sel]
    assert abs(np.median(ratio) - 1) < 0.05
    assert np.all(np.abs(ratio - 1) < 0.2)  # each point from 600 frames: +-3 sigma of the estimate
    pooled = (errs[:, sel] / pred[sel]).std()
    assert abs(pooled - 1) < 0.1


def test_full_aop_noise_matches_formula_and_binned():
    truth = model("full", noise=False, bin_superpixels=2).observe(0.0)
    mf = model("full", bin_superpixels=2, seed=5)
    mb = model("binned", bin_superpixels=2, seed=6)
    sel = truth.dop > 0.15
    pred = sigma_aop_formula(mf, truth)[sel]
    ef, eb, df, db = [], [], [], []
    for _ in range(25):
        of, ob = mf.observe(0.0), mb.observe(0.0)
        ef.append(aop_err(of.aop, truth.aop)[sel] / pred)
        eb.append(aop_err(ob.aop, truth.aop)[sel] / pred)
        df.append((of.dop - truth.dop)[sel])
        db.append((ob.dop - truth.dop)[sel])
    zf, zb = np.std(ef), np.std(eb)
    assert abs(zf - 1) < 0.1 and abs(zb - 1) < 0.1
    assert abs(zf / zb - 1) < 0.1
    assert abs(np.std(df) / np.std(db) - 1) < 0.1
    assert abs(np.mean(df)) < 3e-4 and abs(np.mean(db)) < 3e-4


def test_sun_below_horizon_reports_invalid():
    m = model("binned", epoch=dt.datetime(2019, 9, 18, 16, 0, tzinfo=dt.UTC))
    obs = m.observe(0.0)
    assert obs.status & PsnsStatus.SUN_BELOW_HORIZON and not obs.status & PsnsStatus.VALID
    assert len(obs.aop) == 0


def test_sun_in_view_saturates_and_is_dropped():
    # facing the sun's azimuth, nose down by 90 - 22.94 deg: the optical axis (body z) points at the sun
    for fid in ("full", "binned"):
        m = model(fid, heading=252.1164, pitch=-(90 - 22.9402), noise=False)
        obs = m.observe(0.0)
        assert obs.status & PsnsStatus.SATURATED
        assert len(obs.aop) < m.geo.n_points


def test_installation_error_rotates_the_pattern():
    m0 = model("binned", noise=False)
    m1 = model("binned", noise=False, mounting_c_b=mounting_matrix(installation_error_deg=(0.0, 0.0, 1.0)))
    a0, a1 = m0.observe(0.0), m1.observe(0.0)
    d = np.degrees(aop_err(a1.aop, a0.aop))
    assert abs(np.median(np.abs(d)) - 1.0) < 0.3  # a 1 deg roll about the optical axis


def test_camera_device_frames_latency_and_budget():
    loop = EmulatorLoop("fast")
    hub = MemHub()
    line = LineConfig(baud=115200)
    a, b = hub.pair("psns", line, loop)
    frames = []
    dec = StreamDecoder([PsnsFormat()])

    def rx(data):
        for f in dec.feed(data):
            frames.append((loop.time(), f))

    b.on_receive = rx
    m = model("binned")
    cam = PolarizationCamera(a, m, rate_hz=5.0, exposure_s=2e-3, processing_s=0.02)

    async def main():
        cam.start()
        await asyncio.sleep(2.05)

    loop.run_until_complete(main())
    loop.close()
    assert len(frames) == 10
    for k, (t_rx, f) in enumerate(frames):
        assert isinstance(f, PolarizationObs)
        assert f.header.seq == k and f.header.exposure_us == 2000
        assert len(f.points) == 225 <= max_points(115200, 5.0)
        n_bytes = 7 + 13 + 10 * len(f.points)
        t_exp = t_rx - n_bytes * 10 / 115200 - f.header.latency_us * 1e-6
        assert t_exp == pytest.approx(k * 0.2 + 1e-3, abs=1e-6)  # time tag (conventions): the middle of the exposure
    with pytest.raises(ValueError, match="max_points"):
        PolarizationCamera(a, model("binned", grid=(20, 20)), rate_hz=5.0)


def _fisheye_realistic(**kw):
    """A zenith-looking fisheye under the realistic sky (turbid, aureole): the Sun 23 deg high is inside its field."""
    return model("binned", noise=False, sky=SkyModel("realistic"), lens="fisheye", focal_m=1.8e-3,
                 fisheye_max_theta=85.0 * DEG, grid=(25, 25), **kw)


def _glare(m, t):
    _, s_c, _ = m.camera_attitude(t)
    half = (m.cfg.bin_superpixels + 1) * m.cfg.pixel_m / m.cfg.focal_m
    return m.geo.pt_v @ s_c > math.cos(m.cfg.sun_glare + half)


def test_auto_exposure_puts_the_metered_percentile_at_its_share_of_the_full_well():
    """The realistic sky near the horizon on the Sun's side is many times the radiance the fixed exposure was set
    for: at the fixed signal most of the field saturates; auto exposure brings the 98th percentile of the points'
    brightest channel to the target share of the full well (between cos(45 deg) of the aligned value and the
    aligned value itself: the four polarizers are 45 deg apart) and leaves saturated the Sun's glare alone."""
    fixed = _fisheye_realistic()
    _, _, _, _, sat_fixed = fixed.binned_channels(0.0)
    glare = _glare(fixed, 0.0)
    assert np.count_nonzero(sat_fixed & ~glare) > 0.3 * fixed.geo.n_points
    m = _fisheye_realistic(auto_exposure_target=0.5)
    i0, i45, i90, i135, sat = m.binned_channels(0.0)
    e_max = np.max(np.stack([i0, i45, i90, i135]), axis=0) / m.cfg.gain_dn_per_e  # noise-free: DN / gain
    p98 = float(np.percentile(e_max[~glare], 98.0))
    assert 0.5 * m.cfg.full_well_e * 0.85 < p98 <= 0.5 * m.cfg.full_well_e * (1 + 1e-9)
    assert np.count_nonzero(sat & ~glare) <= 0.02 * m.geo.n_points + 1
    assert m.exposure_scale < 0.3  # the realistic sky is brighter than the configured exposure assumed


def test_auto_exposure_uses_the_last_frames_metering():
    """A frame is exposed as the one before it metered (the camera's loop lags one frame); the first meters
    itself; without auto exposure every frame is at the configured signal."""
    m = _fisheye_realistic(auto_exposure_target=0.5)
    m.observe(0.0)
    first = m.exposure_scale
    metered_at_0 = m._ae_signal_e
    m.observe(-2 * 3600.0)  # two hours earlier, the Sun higher: the sky changed, the exposure is still the last frame's
    assert m.exposure_scale == pytest.approx(metered_at_0 / m.cfg.signal_e, rel=1e-15) == first
    metered_later = m._ae_signal_e
    assert metered_later != pytest.approx(metered_at_0, rel=1e-3)
    m.observe(-2 * 3600.0 + 0.5)
    assert m.exposure_scale == pytest.approx(metered_later / m.cfg.signal_e, rel=1e-15)
    off = _fisheye_realistic()
    off.observe(0.0)
    assert off.exposure_scale == 1.0 and off._ae_signal_e is None


def test_camera_frame_header_reports_the_auto_exposure():
    loop = EmulatorLoop("fast")
    hub = MemHub()
    a, b = hub.pair("psns", LineConfig(baud=115200), loop)
    frames = []
    dec = StreamDecoder([PsnsFormat()])
    b.on_receive = lambda data: frames.extend(dec.feed(data))
    m = model("binned", sky=SkyModel("realistic"), auto_exposure_target=0.5)
    cam = PolarizationCamera(a, m, rate_hz=5.0, exposure_s=2e-3, processing_s=0.02)

    async def main():
        cam.start()
        await asyncio.sleep(0.45)

    loop.run_until_complete(main())
    loop.close()
    assert len(frames) == 2
    assert frames[-1].header.exposure_us == round(2e-3 * m.exposure_scale * 1e6) != 2000


def _camera_bytes(traj, seconds: float) -> bytes:
    """Every byte a binned camera on ``traj`` sends in ``seconds`` (mem link, fast loop)."""
    loop = EmulatorLoop("fast")
    a, b = MemHub().pair("psns", LineConfig(baud=115200), loop)
    got = bytearray()
    b.on_receive = got.extend
    cfg = CameraConfig(fidelity="binned")
    m = PolarizationCameraModel(cfg, SkyModel(), SunModel(EPOCH, 69.0), traj, np.random.default_rng(3))
    cam = PolarizationCamera(a, m, rate_hz=5.0, exposure_s=1e-3, processing_s=0.02)

    async def main():
        cam.start()
        await asyncio.sleep(seconds)

    loop.run_until_complete(main())
    loop.close()
    assert cam.frames_sent == round(seconds * 5.0)
    return bytes(got)


def test_truth_ahead_gives_the_frames_of_the_per_frame_truth(monkeypatch):
    """The camera's truth evaluated for 25 frames in one vectorised call (``PolarizationCameraModel.truth_ahead``,
    performance) gives every byte of the frames that one ``Trajectory.state`` per frame gives, on the reference
    scenario's moving trajectory (static, acceleration, cruise and the first 90 deg turn in 55 s)."""
    from emulator.scenario import load_scenario
    from emulator.world.build import build_trajectory
    from tests.conftest import SCENARIOS

    traj = build_trajectory(load_scenario(SCENARIOS / "bench_vehicle_loop_10min.yaml"))
    calls = {"state": 0, "states": 0}

    class Counting:
        def state(self, t):
            calls["state"] += 1
            return traj.state(t)

        def states(self, ts):
            calls["states"] += 1
            return traj.states(ts)

    ahead = _camera_bytes(Counting(), 55.0)
    assert calls == {"state": 0, "states": 11}  # 275 frames, 25 per evaluation
    monkeypatch.setattr(PolarizationCameraModel, "truth_ahead", lambda self, ts: None)  # one state() per frame
    calls.update(state=0, states=0)
    one_by_one = _camera_bytes(Counting(), 55.0)
    assert calls == {"state": 275, "states": 0}
    assert len(ahead) > 275 * 2000
    assert ahead == one_by_one


def test_truth_ahead_states_are_bit_for_bit_the_single_states():
    """What the look-ahead keeps is exactly what ``state`` gives at each of the camera's instants, to the last bit
    (the frame bytes above cannot resolve that), over the whole reference trajectory: every phase, every turn."""
    from emulator.scenario import load_scenario
    from emulator.world.build import build_trajectory
    from tests.conftest import SCENARIOS

    traj = build_trajectory(load_scenario(SCENARIOS / "bench_vehicle_loop_10min.yaml"))
    m = PolarizationCameraModel(CameraConfig(fidelity="binned"), SkyModel(), SunModel(EPOCH, 69.0), traj,
                                np.random.default_rng(3))
    cam = PolarizationCamera(MemHub().pair("psns", LineConfig(baud=115200), EmulatorLoop("fast"))[0], m)
    ts = [cam._t_mid(cam._t_start(k)) for k in range(3000)]  # 600 s at 5 Hz
    for i in range(0, len(ts), PolarizationCamera.TRUTH_AHEAD):
        chunk = ts[i:i + PolarizationCamera.TRUTH_AHEAD]
        m.truth_ahead(chunk)
        for t in chunk:
            assert m.has_truth(t)
            a, b = m._truth[t], traj.state(t)
            assert (a.t, a.pitch, a.roll, a.heading) == (b.t, b.pitch, b.roll, b.heading)
            for x, y in ((a.pos, b.pos), (a.v_enu, b.v_enu), (a.c_bn, b.c_bn)):
                assert x.tobytes() == y.tobytes()
