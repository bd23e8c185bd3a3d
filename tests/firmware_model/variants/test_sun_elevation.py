"""Sun-elevation positioning (Zhang et al. 2021): alpha/beta reference values, the measurement model, Sage-Husa,
and GNSS-free static positioning against pure SINS (Done-when)."""

from __future__ import annotations

import datetime as dt
import math

import numpy as np
import pytest

from emulator.world.sun import SunModel
from firmware_model import Firmware, FirmwareConfig
from firmware_model.psns_geometry import compass_unit_mountings
from firmware_model.variants.sun_elevation import SageHusaR, sun_elevation_partials
from protocols.constants import DEG

from .streams import EPOCH, CompassSpec, GnssSpec, ImuErrors, StreamSpec, run, static_trajectory


@pytest.mark.parametrize("case, lat, dec, lha, alpha, beta", [
    ("Beijing", 39.979, 1.9344, 61.2708, -0.307084, -0.729255),
    ("Taiyuan", 37.59, -21.7287, 325.0532, -0.818405, 0.455344),
])
def test_alpha_beta_reproduce_the_reference_values(case, lat, dec, lha, alpha, beta):
    """docs/reference/algorithms.md 1.4: declination and local hour angle from SPA (section 3) -> alpha, beta."""
    _, a, b = sun_elevation_partials(lat * DEG, math.sin(dec * DEG), math.cos(dec * DEG), lha * DEG)
    assert a == pytest.approx(alpha, abs=2e-6) and b == pytest.approx(beta, abs=2e-6)


def test_partials_match_finite_differences_of_the_elevation():
    lat, sd, cd, lha = 39.979 * DEG, math.sin(1.9344 * DEG), math.cos(1.9344 * DEG), 61.2708 * DEG
    h = 1e-6
    s0, a, b = sun_elevation_partials(lat, sd, cd, lha)
    d_lat = (math.asin(sun_elevation_partials(lat + h, sd, cd, lha)[0])
             - math.asin(sun_elevation_partials(lat - h, sd, cd, lha)[0])) / (2 * h)
    d_lon = (math.asin(sun_elevation_partials(lat, sd, cd, lha + h)[0])
             - math.asin(sun_elevation_partials(lat, sd, cd, lha - h)[0])) / (2 * h)
    assert a == pytest.approx(d_lat, abs=1e-7) and b == pytest.approx(d_lon, abs=1e-7)
    # the H row of z = sin H_c - sin H_n is cos(h) (alpha, beta): d(sin h) = cos h dh
    d_sin = (sun_elevation_partials(lat + h, sd, cd, lha)[0]
             - sun_elevation_partials(lat - h, sd, cd, lha)[0]) / (2 * h)
    assert d_sin == pytest.approx(math.sqrt(1 - s0 * s0) * a, abs=1e-8)


def test_sage_husa_recovers_r_from_a_25_times_too_small_start():
    """docs/reference/algorithms.md 5.1 demo: R0 = 0.16 for a true R = 4 (b = 0.95)."""
    rng = np.random.default_rng(2)
    sh = SageHusaR(0.16, 0.95, 0.01, 1000.0)  # (PSINS' R_max = 100 R0 would be hit by 2-sigma innovations)
    rs = [sh.adapt(float(rng.normal(0.0, 2.0)), 0.0) for _ in range(2000)]
    assert np.mean(rs[-500:]) == pytest.approx(4.0, rel=0.15)
    assert sh.beta == pytest.approx(1 - 0.95, rel=1e-3)  # d_k = (1-b)/(1-b^(k+1)) -> 1-b


def _gnss_free(filter_name: str, duration_s: float, gyro_bias_dph: tuple[float, float, float], gnss_until_s: float,
               seed: int = 1, epoch=EPOCH):
    spec = StreamSpec(static_trajectory(30.0, 1.0, -2.0), duration_s, epoch=epoch,
                      imu=ImuErrors(gyro_bias_dph, 0.15, (50.0, -50.0, 50.0), 25.0),
                      gnss=GnssSpec(True, 2.5, 0.05, outages=((gnss_until_s, 1e9),), time_during_outage=True),
                      psns="compass", psns_rate_hz=1, compass=CompassSpec(compass_unit_mountings(), aop_sigma_deg=0.1))
    b = max(abs(v) for v in gyro_bias_dph)
    # the synthetic stream hands each NAV-PVT over whole, 0.05 s after its epoch: a line that fast (2 Mbaud) and that
    # latency are what the firmware must be told to date fixes without PPS from their own UTC
    cfg = FirmwareConfig(filter=filter_name, initial_heading_deg=30.2, gyro_bias_sigma_deg_h=b,
                         gyro_bias_instability_deg_h=0.5, accel_bias_sigma_mg=0.05, accel_noise_ug_rt_hz=25.0,
                         gnss_baud=2_000_000, gnss_latency_s=0.05)
    fw = Firmware(cfg)
    samples, events = run(fw, spec, seed=seed, sample_every_s=10.0)
    sun = SunModel(epoch, 69.0)
    out = []
    for s in samples:
        if s.t < gnss_until_s:
            continue
        az, _ = sun.az_el(s.t, 39.979 * DEG, 116.339 * DEG, 50.0)
        n, e = s.pos_err_m[0], s.pos_err_m[1]
        along = e * math.sin(az) + n * math.cos(az)  # along the Sun's azimuth: what the elevation observes
        across = e * math.cos(az) - n * math.sin(az)
        out.append((s.t, n, e, along, across))
    return fw, np.array(out), events


def _report(a: np.ndarray) -> dict[str, float]:
    return {"mae_n_km": float(np.mean(np.abs(a[:, 1]))) / 1e3, "mae_e_km": float(np.mean(np.abs(a[:, 2]))) / 1e3,
            "mae_hor_km": float(np.mean(np.hypot(a[:, 1], a[:, 2]))) / 1e3,
            "max_along_km": float(np.max(np.abs(a[:, 3]))) / 1e3, "final_along_km": float(a[-1, 3]) / 1e3,
            "final_across_km": float(a[-1, 4]) / 1e3}


def test_gnss_free_sun_elevation_bounds_the_along_azimuth_error_fast():
    """Fast counterpart (6 min; near local noon, so the static drift's main, northern, direction is the Sun's
    azimuth, and a 20 deg/h gyro so that it shows within minutes)."""
    bias = (20.0, -20.0, 10.0)
    noon = dt.datetime(2019, 9, 18, 4, 0, tzinfo=dt.UTC)
    fw, se, _ev = _gnss_free("sun_elevation", 360.0, bias, 60.0, epoch=noon)
    _, sins, _ = _gnss_free("base", 360.0, bias, 60.0, epoch=noon)
    r_se, r_sins = _report(se), _report(sins)
    assert r_sins["final_along_km"] > 0.3  # pure SINS runs away along the Sun's azimuth ...
    assert r_se["max_along_km"] < 0.4 * r_sins["max_along_km"] and abs(r_se["final_along_km"]) < 0.15  # ... held
    assert r_se["mae_hor_km"] < 0.6 * r_sins["mae_hor_km"]
    assert fw.counters["sun_elevation_admitted"] > 280
    # the receiver kept sending its time without a fix or PPS: tagged by its own UTC, the clock stays right
    # (before the receiver rework these epochs were refused as stale-PPS, counted in utc_stale_pps)
    from firmware_model import sun as fw_sun

    t_end = 360.0
    expected_days = fw_sun.grena_days(2019, 9, 18, 4.0 + t_end / 3600.0)
    assert abs(fw.clock.utc_days(t_end) - expected_days) * 86400.0 < 0.01
    assert fw.filter.variant_status()[0] == 1


@pytest.mark.slow
def test_gnss_free_20_min_static_sun_elevation_against_pure_sins(capsys):
    """Done-when: the paper's 20 min static test (Beijing, 16:14 local): report the MAE; the along-azimuth error
    stays bounded while pure SINS diverges (the cross-azimuth direction is not observable: it drifts like SINS)."""
    bias = (5.0, -5.0, 2.5)
    _, se, _ = _gnss_free("sun_elevation", 1260.0, bias, 60.0)
    _, sins, _ = _gnss_free("base", 1260.0, bias, 60.0)
    r_se, r_sins = _report(se), _report(sins)
    with capsys.disabled():
        print(f"\nsun-elevation: {r_se}\npure SINS:     {r_sins}")
    assert r_se["max_along_km"] < 3.0 and r_sins["max_along_km"] > 10.0
    assert r_se["mae_e_km"] < 0.6 * r_sins["mae_e_km"] and r_se["mae_hor_km"] < r_sins["mae_hor_km"]


def test_elevation_update_off_is_the_same_filter_navigating_as_pure_sins():
    """``elevation_update: false`` (the paper's pure-SINS baseline of sun_elevation_paper_like_for_like): every frame is
    measured and logged as not used, nothing reaches the state, so the solution drifts as free inertial; the same
    stream with the update holds the along-azimuth error."""
    import dataclasses

    bias = (20.0, -20.0, 10.0)
    noon = dt.datetime(2019, 9, 18, 4, 0, tzinfo=dt.UTC)
    spec = StreamSpec(static_trajectory(30.0, 1.0, -2.0), 240.0, epoch=noon,
                      imu=ImuErrors(bias, 0.15, (50.0, -50.0, 50.0), 25.0),
                      gnss=GnssSpec(True, 2.5, 0.05, outages=((10.0, 1e9),), time_during_outage=True),
                      psns="compass", psns_rate_hz=1, compass=CompassSpec(compass_unit_mountings(), aop_sigma_deg=0.1))
    out = {}
    for on in (True, False):
        cfg = FirmwareConfig(filter="sun_elevation", initial_heading_deg=30.2, gyro_bias_sigma_deg_h=20.0,
                             gyro_bias_instability_deg_h=0.5, accel_bias_sigma_mg=0.05, accel_noise_ug_rt_hz=25.0,
                             gnss_baud=2_000_000, gnss_latency_s=0.05)
        cfg.variants.sun_elevation = dataclasses.replace(cfg.variants.sun_elevation, elevation_update=on)
        fw = Firmware(cfg)
        samples, events = run(fw, spec, seed=3, sample_every_s=10.0)
        out[on] = (fw, samples, [e for e in events if e.get("channel") == "sun_elevation"])
    fw_off, _s_off, ev_off = out[False]
    assert fw_off.counters.get("sun_elevation_admitted", 0) == 0
    assert fw_off.counters["sun_elevation_rejected"] > 200  # one per 1 Hz frame after the alignment
    assert {e["reason"] for e in ev_off} == {"elevation_update_off"}
    assert out[True][0].counters["sun_elevation_admitted"] > 200
    # along the Sun's azimuth (what one elevation observes): free inertial runs away, the update holds it
    sun = SunModel(noon, 69.0)
    az, _ = sun.az_el(240.0, 39.979 * DEG, 116.339 * DEG, 50.0)
    along = {on: abs(s[-1].pos_err_m[1] * math.sin(az) + s[-1].pos_err_m[0] * math.cos(az))
             for on, (_fw, s, _e) in out.items()}
    assert along[False] > 10.0 * along[True]  # 2.2 km against 18 m (seed 3)


# -- Sage-Husa's R0 from the spec sheet's compass figures (docs/decisions/filter-consistency.md D-5.19) --------------
def _rayleigh_units(s_b: np.ndarray, mountings: np.ndarray, p_max: float = 0.7):
    """AOP (rad, unit frame) and DOP of each unit under a Rayleigh sky with the sun at ``s_b`` (body)."""
    aops, dops = [], []
    for m in mountings:
        ray = m[:, 2]
        e = np.cross(ray, s_b)
        e_u = m.T @ e  # (sin A, cos A, 0) up to scale
        aops.append(math.atan2(e_u[0], e_u[1]))
        cg = float(ray @ s_b)
        dops.append(p_max * (1 - cg * cg) / (1 + cg * cg))
    return np.array(aops), np.array(dops)


def _rot(w: np.ndarray) -> np.ndarray:
    """Rotation matrix of the rotation vector ``w`` (Rodrigues)."""
    th = float(np.linalg.norm(w))
    if th == 0.0:
        return np.eye(3)
    k = w / th
    kx = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(th) * kx + (1 - math.cos(th)) * kx @ kx


def test_elevation_noise_variance_matches_finite_differences_of_the_two_unit_solve():
    """The closed form against a numerical Jacobian of the firmware's own path (E-vectors -> Eq. 6 -> up . S) with
    respect to both units' AOP errors and installation rotations: var = sum_k J_k^2 sigma_k^2."""
    from firmware_model.variants.dual_vector import unit_evectors
    from firmware_model.variants.sun_elevation import elevation_noise_variance, sun_vector_from_two_evectors

    cfg = FirmwareConfig(compass_aop_sigma_deg=0.1, compass_aop_dop_ref=0.5, compass_aop_residual_deg=0.18,
                         compass_installation_residual_deg=0.13)
    mnt = compass_unit_mountings()
    el, az = 25 * DEG, 250 * DEG
    s_n = np.array([math.cos(el) * math.sin(az), math.cos(el) * math.cos(az), math.sin(el)])
    cbn = _rot(np.array([0.02, -0.035, 0.0])) @ _rot(np.array([0.0, 0.0, -0.5]))
    s_b = cbn.T @ s_n
    aop, dop = _rayleigh_units(s_b, mnt)
    i, j = (int(k) for k in np.argsort(-dop)[:2])
    up_b = cbn[2, :]

    def sin_h(x: np.ndarray) -> float:
        a = np.array([aop[i] + x[0], aop[j] + x[1]])
        e = unit_evectors(a, mnt[[i, j]], np.float64)
        ei, ej = _rot(-x[2:5]) @ e[0], _rot(-x[5:8]) @ e[1]
        s, _ = sun_vector_from_two_evectors(ei, ej)
        return float(up_b @ (s if s @ s_b > 0 else -s))

    h = 1e-7
    jac = np.array([(sin_h(h * np.eye(8)[k]) - sin_h(-h * np.eye(8)[k])) / (2 * h) for k in range(8)])
    sig_a = [math.hypot(0.1 * 0.5 / dop[i], 0.18) * DEG, math.hypot(0.1 * 0.5 / dop[j], 0.18) * DEG]
    sig = np.array(sig_a + [0.13 * DEG] * 6)
    want = float(np.sum((jac * sig) ** 2))
    e = unit_evectors(aop[[i, j]], mnt[[i, j]], np.float64)
    s, _ = sun_vector_from_two_evectors(e[0], e[1])
    got = elevation_noise_variance(cfg, e[0], e[1], s, mnt[i][:, 2], mnt[j][:, 2], dop[i], dop[j], up_b)
    assert got == pytest.approx(want, rel=1e-5)
    assert got == pytest.approx(elevation_noise_variance(cfg, e[0], e[1], -s, mnt[i][:, 2], mnt[j][:, 2], dop[i],
                                                         dop[j], up_b), rel=1e-12)  # sign-free
    # a perfectly calibrated, noise-free compass measures the elevation exactly
    zero = FirmwareConfig(compass_aop_sigma_deg=0.001, compass_aop_residual_deg=0.0,
                          compass_installation_residual_deg=0.0)
    assert elevation_noise_variance(zero, e[0], e[1], s, mnt[i][:, 2], mnt[j][:, 2], dop[i], dop[j], up_b) < 1e-3 * got


class _Host:
    """The main loop's services (firmware_model.filters.interface.FilterHost) for one static epoch."""

    def __init__(self, days: float, nav) -> None:
        self.days, self.nav = days, nav

    def utc_days(self, t_fpga_s: float) -> float:
        return self.days

    def ins_at(self, t_meas: float):
        return self.nav.pos.copy(), self.nav.v.copy(), self.nav.q.copy()

    def mag_mean_nt(self, t_center_s: float, half_window_s: float = 0.025):
        return None

    def now_s(self) -> float:
        return 10.0


@pytest.mark.parametrize("fixed_deg", [None, 0.2])
def test_sage_husa_starts_from_the_spec_derived_r0(fixed_deg):
    """One compass frame through SunElevationFilter.update_compass: the nominal R the Sage-Husa filter adapts from is
    elevation_noise_variance of the two highest-DOP units (the spec sheet's compass figures), or (cos H_c sigma)^2
    when the scenario fixes ``elevation_sigma_deg``."""
    from firmware_model import c674x, sun
    from firmware_model.attitude import a2mat, mat2q, yaw_from_heading
    from firmware_model.nav_state import NavState
    from firmware_model.variants.dual_vector import unit_evectors
    from firmware_model.variants.params import SunElevationParams, VariantParams
    from firmware_model.variants.sun_elevation import (
        SunElevationFilter,
        elevation_noise_cycles,
        elevation_noise_variance,
        sun_vector_from_two_evectors,
    )
    from protocols.psns import CompassFrame, CompassUnit, PsnsHeader

    cfg = FirmwareConfig(filter="sun_elevation", precision="float64", compass_aop_residual_deg=0.18,
                         variants=VariantParams(sun_elevation=SunElevationParams(elevation_sigma_deg=fixed_deg)))
    flt = SunElevationFilter(cfg, c674x.CycleMeter(cfg.clock_hz, cfg.imu_rate_hz), np.float64)
    cbn = a2mat(0.01, -0.02, yaw_from_heading(30 * DEG))
    nav = NavState(q=mat2q(cbn), v=np.zeros(3), pos=np.array([39.979 * DEG, 116.339 * DEG, 50.0]))
    flt.initialise(nav, 1.0 * DEG)
    days = sun.grena_days_from_datetime(dt.datetime(2019, 9, 18, 8, 14, tzinfo=dt.UTC))
    flt.attach(_Host(days, nav))
    s_n = sun.sun_vector_enu(days, float(nav.pos[0]), float(nav.pos[1]), dtype=np.float64)
    s_b = cbn.T @ s_n
    mnt = compass_unit_mountings()
    aop, dop = _rayleigh_units(s_b, mnt)
    units = tuple(CompassUnit(k, round(math.degrees(aop[k]) * 100) % 36000, round(dop[k] * 65535))
                  for k in range(len(mnt)))
    frame = CompassFrame(PsnsHeader(1, 1000, 0, 0, len(units)), units)
    flt.meter.begin("psns")
    rep = flt.update_compass(nav, frame, 9.5)
    flt.meter.end()
    assert rep is not None and rep.accepted
    # the pair the filter chose (the two highest-DOP units, well conditioned here) on the wire's quantisation
    i, j = sorted(range(len(mnt)), key=lambda k: -units[k].dop)[:2]
    assert flt.pair_mask == (1 << i) | (1 << j)
    if fixed_deg is None:
        a = np.array([units[i].aop_cdeg, units[j].aop_cdeg]) * 0.01 * DEG
        e = unit_evectors(a, mnt[[i, j]], np.float64)
        s, _ = sun_vector_from_two_evectors(e[0], e[1])
        want = elevation_noise_variance(cfg, e[0], e[1], s, mnt[i][:, 2], mnt[j][:, 2], units[i].dop / 65535.0,
                                        units[j].dop / 65535.0, cbn[2, :])
        assert flt.adaptive.r0 == pytest.approx(want, rel=1e-9)
        assert flt.meter.tasks["psns"].kernels["se_elevation_noise"] == elevation_noise_cycles(flt.cost)
    else:
        cos_hc = math.sqrt(1.0 - flt.last["sin_hc"] ** 2)
        assert flt.adaptive.r0 == pytest.approx((cos_hc * 0.2 * DEG) ** 2, rel=1e-12)
