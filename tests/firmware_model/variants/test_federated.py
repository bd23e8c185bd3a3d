"""Federated SINS/GNSS + MIMU/polarization filter (Ge et al.): master fusion, no-reset sharing, chi-square isolation
and readmission of a glitching GNSS, and the paper's three-configuration comparison (Done-when)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from firmware_model import Firmware, FirmwareConfig
from firmware_model.variants.federated import fuse_common_states
from firmware_model.variants.params import FederatedParams, VariantParams
from protocols.constants import DEG
from protocols.host import HostFormat, NavSolution
from protocols.stream import StreamDecoder

from .streams import GnssSpec, ImuErrors, StreamSpec, run, segment_trajectory

#: the paper's simulation conditions: gyro drift 25 deg/h, accelerometer bias 800 ug, GPS 2.5 m and 0.1 m/s,
#: polarization noise 0.01; gyro random noise 20 deg/h and accelerometer noise 600 ug read as densities per rt-Hz
PAPER_IMU = ImuErrors((25.0, 25.0, 25.0), 20.0 / 60.0, (800.0, 800.0, 800.0), 600.0)
MISALIGNMENT = (-0.9, 0.6, 0.7)


def test_master_fusion_is_the_information_weighted_mean():
    rng = np.random.default_rng(1)
    a = rng.normal(size=(6, 6))
    b = rng.normal(size=(6, 6))
    P1, P2 = a @ a.T + np.eye(6), b @ b.T + 2 * np.eye(6)
    x1, x2 = rng.normal(size=6), rng.normal(size=6)
    xg, Pg = fuse_common_states([(x1, P1), (x2, P2)])
    I1, I2 = np.linalg.inv(P1), np.linalg.inv(P2)
    assert np.allclose(Pg, np.linalg.inv(I1 + I2)) and np.allclose(xg, Pg @ (I1 @ x1 + I2 @ x2))
    # no-reset sharing P_i(0) = P0 / beta_i (beta = 1/2 each): the fused covariance is P0 again
    P0 = np.diag([1.0, 2.0, 3.0, 4.0, 5.0, 6.0])
    _, Pg0 = fuse_common_states([(np.zeros(6), P0 / 0.5), (np.zeros(6), P0 / 0.5)])
    assert np.allclose(Pg0, P0)


def _config(subfilters=("sins_gnss", "pol_mimu")) -> FirmwareConfig:
    vp = VariantParams(federated=FederatedParams(subfilters=tuple(subfilters), initial_attitude_sigma_deg=(1, 1, 1)))
    return FirmwareConfig(filter="federated", variants=vp, initial_misalignment_deg=MISALIGNMENT,
                          initial_heading_deg=30.0, gyro_arw_deg_rt_h=20.0 / 60.0, gyro_bias_sigma_deg_h=25.0,
                          accel_noise_ug_rt_hz=600.0,
                          accel_bias_sigma_mg=0.8, gnss_pos_sigma_h_m=2.5, gnss_pos_sigma_v_m=2.5,
                          # the stream's receiver error is white (streams.GnssSpec): the sheet says all of it is
                          gnss_pos_white_sigma_h_m=2.5, gnss_pos_white_sigma_v_m=2.5,
                          gnss_vel_sigma_h_mps=0.1, gnss_vel_sigma_v_mps=0.1,
                          # the sun sensor's figure on the team's sheet: 0.01 rad per component (the world's noise)
                          psns_sigma_deg=0.01 / DEG)


def _spec(t_static: float, t_turn: float, glitch_at: float | None) -> StreamSpec:
    traj = segment_trajectory([{"static": {"duration_s": t_static}},
                               {"accelerate": {"duration_s": 5, "to_speed_mps": 5}},
                               {"turn": {"angle_deg": 180.0, "rate_dps": 180.0 / t_turn}}],
                              heading_deg=30.0, duration=t_static + 5 + t_turn)
    glitches = ((glitch_at, 5.0, (60.0, -40.0, 10.0)),) if glitch_at is not None else ()
    return StreamSpec(traj, t_static + 5 + t_turn, imu=PAPER_IMU, gnss=GnssSpec(True, 2.5, 0.1, glitches=glitches),
                      psns="solar_vector", sun_sigma=0.01)


def _heading_rms(samples, after_s: float = 10.0) -> float:
    h = np.array([s.heading_err_deg for s in samples if s.t >= after_s])
    return float(np.sqrt(np.mean(h * h)))


def test_a_gnss_glitch_is_isolated_at_its_first_epoch_and_readmitted_when_it_passes():
    fw = Firmware(_config())
    navs: dict[float, NavSolution] = {}
    dec = StreamDecoder([HostFormat()])

    def on_tick(fw, r):
        for _, data, _ in r.outputs:
            for f in dec.feed(data):
                if isinstance(f, NavSolution):
                    navs[round(f.time_s, 3)] = f

    samples, events = run(fw, _spec(60.0, 30.0, glitch_at=40.0), on_tick=on_tick)
    iso = [e for e in events if e["event"] == "gnss_isolated"]
    back = [e for e in events if e["event"] == "gnss_readmitted"]
    assert len(iso) == 1 and iso[0]["t_meas_s"] == pytest.approx(40.0)  # the first glitched epoch (within 2)
    assert iso[0]["nis"] > iso[0]["threshold"] == pytest.approx(22.458) and iso[0]["dof"] == 6
    assert len(back) == 1 and back[0]["t_meas_s"] == pytest.approx(45.0) and back[0]["isolated_s"] == pytest.approx(5.0)
    modes = [(e["mode"], e["reason"]) for e in events if e["event"] == "federated_mode"]
    assert ("pol_mimu", "gnss_isolated") in modes and modes[-1] == ("three_way", "gnss_admitted")
    # the VARIANT block says which sub-filters are fused: 3 both, 2 MIMU/polarization only while isolated
    assert navs[30.0].variant_mode == 3 and navs[42.0].variant_mode == 2 and navs[50.0].variant_mode == 3
    # the glitch never reached the navigation solution
    pos = max(np.linalg.norm(s.pos_err_m[:2]) for s in samples if 38.0 <= s.t <= 50.0)
    assert pos < 10.0
    assert fw.counters["gnss_rejected"] == 5 and fw.counters["gnss_isolated"] == 1
    assert not navs[43.0].mode & 0x0004  # NavMode.GNSS_AIDED is off while the GNSS is isolated ...
    assert navs[47.0].mode & 0x0004  # ... and back after the readmission


def _compare(t_static: float, t_turn: float) -> dict[str, float]:
    spec = _spec(t_static, t_turn, glitch_at=None)
    out = {}
    for name, sub in (("three_way", ("sins_gnss", "pol_mimu")), ("pol_mimu", ("pol_mimu",)),
                      ("sins_gnss", ("sins_gnss",))):
        samples, _ = run(Firmware(_config(sub)), spec)
        out[name] = _heading_rms(samples)
    return out


def test_three_way_beats_polarization_mimu_beats_sins_gps_in_heading_fast():
    """Fast counterpart of the paper's comparison: 60 s static + 60 s half circle."""
    h = _compare(60.0, 60.0)
    assert h["three_way"] < h["pol_mimu"] < h["sins_gnss"], h
    assert h["three_way"] < 0.2 and h["sins_gnss"] > 0.3


@pytest.mark.slow
def test_three_way_beats_polarization_mimu_beats_sins_gps_in_heading_paper_trajectory(capsys):
    """Done-when: 400 s static + 300 s half circle, the paper's sensor figures and initial misalignment."""
    h = _compare(400.0, 300.0)
    with capsys.disabled():
        print(f"\nheading RMS after 10 s (deg): {h}")
    assert h["three_way"] < h["pol_mimu"] < h["sins_gnss"], h


# -- the sub-filters configured as the base filter is (docs/decisions/filter-consistency.md D-5.18) -----------------
def _field_cfg(**kw) -> FirmwareConfig:
    """The ``field`` spec sheet's figures (correlated GNSS error, sky figure, flicker, scale factor)."""
    from pathlib import Path

    import yaml

    from firmware_model.spec_sheet import SensorSpecSheet

    sheet = Path(__file__).resolve().parents[3] / "firmware_model" / "spec_sheets" / "field.yaml"
    fields = SensorSpecSheet.from_dict(yaml.safe_load(sheet.read_text())).config_fields()
    return FirmwareConfig(precision="float64", **{**fields, **kw})


def _pair(beta: float = 0.5, fed_kw=None, **cfg_kw):
    """A base filter and a federated filter on the same configuration and navigation state, both initialised."""
    from firmware_model import c674x
    from firmware_model.attitude import a2mat, mat2q, yaw_from_heading
    from firmware_model.filters.base import BaseFilter
    from firmware_model.nav_state import NavState
    from firmware_model.variants.federated import FederatedFilter

    # the base filter without the gyro flicker's middle-band states, which the sub-filters do not carry (D-5.28)
    cfg = _field_cfg(gyro_flicker_states=False, **cfg_kw)
    vp = VariantParams(federated=FederatedParams(beta_sins_gnss=beta, **(fed_kw or {})))
    fcfg = _field_cfg(filter="federated", variants=vp, **cfg_kw)
    cbn = a2mat(0.02, -0.01, yaw_from_heading(30 * DEG))
    nav = NavState(q=mat2q(cbn), v=np.zeros(3), pos=np.array([39.979 * DEG, 116.339 * DEG, 50.0]))
    base = BaseFilter(cfg, c674x.CycleMeter(cfg.clock_hz, cfg.imu_rate_hz), np.float64)
    fed = FederatedFilter(fcfg, c674x.CycleMeter(cfg.clock_hz, cfg.imu_rate_hz), np.float64)
    base.initialise(nav, 0.5 * DEG)
    fed.initialise(nav, 0.5 * DEG)
    return base, fed, nav, cbn


def test_subfilters_take_the_base_filters_spec_sheet_q_p0_and_augmented_states():
    """Sub-filter 1 = the base filter's 15 states + its GNSS-error states, with the base's Q and P0 (GNSS block and
    the first fix's correlation included), the 15 shared states' times 1 / beta, the GNSS-error states' not (local to
    the sub-filter, D-5.32); sub-filter 2's attitude / gyro blocks are the base's times 1 / beta, and so is its
    accelerometer bias with the level's correlation with it (D-5.20), apart from the motion acceleration's stationary
    variance; its solar-bias states are the base's, unshared; the cycle meter charges the added states."""
    from firmware_model.filters.cycles import kf_predict_cycles, kf_scalar_update_cycles
    from firmware_model.kf import IDX_ACC, IDX_ATT, IDX_GYRO
    from firmware_model.variants.federated import (
        N2,
        X2_ACC,
        X2_ATT,
        X2_GYRO,
        X2_MOTION,
        pol_mimu_predict_cycles,
    )

    base, fed, _, _ = _pair(beta=0.5)
    b = 0.5
    assert base.i_gnss == 15 and fed.n1 == 18 and fed.gnss_states is not None and fed.gnss_states.i == 15
    assert fed.n2 == N2 + 3 and fed.sun_states is not None and fed.sun_states.i == N2
    g = base.i_gnss
    # Q: the same PSDs, the shared states' by 1 / beta, the receiver's local error states' whole (D-5.32)
    np.testing.assert_allclose(fed.q1[:15] * b, base.q[:15], rtol=1e-15)
    np.testing.assert_allclose(fed.q1[15:18], base.q[15:18], rtol=1e-15)
    np.testing.assert_allclose(fed._q2_att, base.q[IDX_ATT], rtol=1e-15)
    np.testing.assert_allclose(fed._q2_acc, base.q[IDX_ACC], rtol=1e-15)
    np.testing.assert_allclose(fed._q2_sun, base.q[base.i_sun:base.i_sun + 3], rtol=1e-15)
    assert fed.q1[g] == pytest.approx(2.0 * (fed.cfg.gnss_pos_sigma_h_m**2 - fed.cfg.gnss_pos_white_sigma_h_m**2)
                                          / fed.cfg.gnss_pos_corr_time_s, rel=1e-12)
    # P0: the shared block by 1 / beta; the GNSS-error block and its correlation with the first fix's position whole
    np.testing.assert_allclose(fed.P1[:15, :15] * b, base.P[:15, :15], rtol=1e-12, atol=1e-30)
    np.testing.assert_allclose(fed.P1[15:18, :], base.P[15:18, :18], rtol=1e-12, atol=1e-30)
    assert np.any(fed.P1[15:18, :15] != 0.0)
    P2 = fed.P2 * 0.5  # beta_pol_mimu
    np.testing.assert_allclose(P2[X2_ATT, X2_ATT], base.P[IDX_ATT, IDX_ATT], rtol=1e-12)
    np.testing.assert_allclose(P2[X2_GYRO, X2_GYRO], base.P[IDX_GYRO, IDX_GYRO], rtol=1e-12)
    np.testing.assert_allclose(P2[X2_ACC, X2_ACC], base.P[IDX_ACC, IDX_ACC], rtol=1e-12)
    np.testing.assert_allclose(P2[X2_ATT, X2_ACC], base.P[IDX_ATT, IDX_ACC], rtol=1e-12, atol=1e-30)
    assert np.any(P2[X2_ATT, X2_ACC] != 0.0)  # the level's correlation with the bias is there
    np.testing.assert_allclose(P2[X2_MOTION, X2_MOTION], np.eye(3) * fed.p.motion_accel_sigma_mps2**2, rtol=1e-12)
    assert not np.any(P2[X2_MOTION, :6]) and not np.any(P2[X2_MOTION, X2_ACC])
    i = base.i_sun
    np.testing.assert_allclose(fed.P2[N2:, N2:], base.P[i:i + 3, i:i + 3], rtol=1e-12)  # local: unshared
    np.linalg.cholesky(fed.P1)
    np.linalg.cholesky(fed.P2)
    c = fed.cost
    assert fed._cyc_predict1 == kf_predict_cycles(c, 18) > kf_predict_cycles(c, 15)
    assert fed._cyc_up1 == kf_scalar_update_cycles(c, 18) and fed._cyc_up2 == kf_scalar_update_cycles(c, 15)
    assert fed._cyc_predict2 == pol_mimu_predict_cycles(c, 15) > pol_mimu_predict_cycles(c, 12)


def test_imposed_misalignment_sigma_adds_to_the_attitude_prior_and_keeps_the_level_bias_correlation():
    """D-5.29: a study's imposed misalignment (``initial_attitude_sigma_deg``, applied on top of the coarse
    alignment's frame) adds its variance to the attitude block of the spec-sheet P0 in both sub-filters; the level's
    correlation with the accelerometer bias (D-5.14) stays. Closed form at rest with ``P_nabla = s^2 I``:
    ``A P_nabla A^T = (s / g)^2 diag(1, 1, 0)`` (``A = [[0, -1, 0], [1, 0, 0], 0] C_b^n / g``, C_b^n orthonormal), so
    ``P_phi = diag((s/g)^2 + w^2 + m_E^2, (s/g)^2 + w^2 + m_N^2, h^2 + m_U^2)`` with ``w`` the levelling's averaged
    white noise, ``h`` the alignment's heading sigma, and ``cov(phi, nabla) = s^2 / g [[-C_21, -C_22, -C_23],
    [C_11, C_12, C_13], 0]``, all times ``1 / beta_i``."""
    from firmware_model.kf import IDX_ACC, IDX_ATT
    from firmware_model.units import G_STD
    from firmware_model.variants.federated import X2_ACC, X2_ATT

    sig_m = (1.0, 0.6, 0.8)  # deg, E N U
    _, ref, _, _ = _pair(beta=0.5)
    _, fed, _, cbn = _pair(beta=0.5, fed_kw={"initial_attitude_sigma_deg": sig_m})
    b1, b2 = fed.p.beta_sins_gnss, fed.p.beta_pol_mimu
    add = np.diag([(v * DEG) ** 2 for v in sig_m])
    # the difference is the imposed variance on the attitude diagonal, nothing else, in both sub-filters
    d1 = (fed.P1 - ref.P1) * b1
    np.testing.assert_allclose(d1[IDX_ATT, IDX_ATT], add, rtol=1e-12)
    d1[IDX_ATT, IDX_ATT] = 0.0
    assert np.abs(d1).max() == 0.0
    d2 = (fed.P2 - ref.P2) * b2
    np.testing.assert_allclose(d2[X2_ATT, X2_ATT], add, rtol=1e-12)
    d2[X2_ATT, X2_ATT] = 0.0
    assert np.abs(d2).max() == 0.0
    # closed form of the attitude block and the level-bias cross-covariance
    s = fed.cfg.accel_bias_sigma_mg * 1e-3 * G_STD
    w = ref.P1[0, 0] * b1 - (s / G_STD) ** 2  # the white part, read from the reference P0 ...
    assert 0.0 < w < 0.01 * (s / G_STD) ** 2  # ... which is small against the bias's part
    h2 = (0.5 * DEG) ** 2  # the heading sigma _pair aligns with
    want_att = np.diag([(s / G_STD) ** 2 + w + add[0, 0], (s / G_STD) ** 2 + w + add[1, 1], h2 + add[2, 2]])
    want_cross = s**2 / G_STD * np.array([-cbn[1], cbn[0], np.zeros(3)])
    for P, b, att, acc in ((fed.P1, b1, IDX_ATT, IDX_ACC), (fed.P2, b2, X2_ATT, X2_ACC)):
        np.testing.assert_allclose(P[att, att] * b, want_att, rtol=1e-9, atol=1e-18)
        np.testing.assert_allclose(P[att, acc] * b, want_cross, rtol=1e-12, atol=1e-20)
        np.linalg.cholesky(P)
    # the correlation is kept: the level's correlation with the bias is |rho| = (s/g) / sqrt((s/g)^2 + w + m^2)
    rho = fed.P1[0, IDX_ACC] @ cbn[1] * -1 / math.sqrt(fed.P1[0, 0] * s**2 / b1)
    assert rho == pytest.approx((s / G_STD) / math.sqrt((s / G_STD) ** 2 + w + add[0, 0]), rel=1e-9)


def test_subfilters_share_the_warmup_gyro_bias_noise_by_beta():
    """D-5.27: the temperature-gradient bias's in-run change while the box warms up enters both sub-filters' gyro-bias
    rows as Q does, times 1 / beta_i; the ``field`` sheet carries the warm-up figure."""
    from firmware_model.filters.noise_model import warmup_gyro_bias_variance
    from firmware_model.kf import IDX_GYRO
    from firmware_model.variants.federated import X2_GYRO

    _, fed, nav, _ = _pair(beta=0.5)
    _, ref, _, _ = _pair(beta=0.5, gyro_temp_gradient_time_s=0.0)
    assert fed.cfg.gyro_temp_gradient_time_s == 600.0 and fed.cfg.gyro_temp_gradient_deg_h == 10.0
    nav.t = 30.0
    f_n = np.array([0.0, 0.0, 9.80])
    fed.predict(nav, f_n, 0.1)
    ref.predict(nav, f_n, 0.1)
    qw = warmup_gyro_bias_variance(fed.cfg, 29.9, 0.1)
    assert qw > 0.0
    d1 = fed.P1 - ref.P1
    np.testing.assert_allclose(d1[IDX_GYRO, IDX_GYRO], np.eye(3) * qw / 0.5, rtol=1e-9, atol=1e-24)
    d1[IDX_GYRO, IDX_GYRO] = 0.0
    assert np.abs(d1).max() == 0.0
    # sub-filter 2 (beta_pol_mimu 0.5); its gravity update follows the predict and barely touches the gyro rows
    d2 = np.diag(fed.P2 - ref.P2)[X2_GYRO]
    np.testing.assert_allclose(d2, qw / fed.p.beta_pol_mimu, rtol=1e-3)


def test_sins_gnss_subfilter_predicts_and_updates_gnss_as_the_base_filter():
    """With beta = 1 and no solar-bias states the SINS/GNSS sub-filter is the base filter's 18-state model: the same
    predict (GNSS-error Gauss-Markov, turns' rotation noise) and the same GNSS update (position rows ``dp - b`` with
    the white R) give the same covariance and estimate."""
    from firmware_model.filters.gnss import GnssMeasurement

    # the master fuses SINS/GNSS only, and not before its first fix: nothing of sub-filter 2 reaches the reference
    base, fed, nav, _ = _pair(beta=1.0, fed_kw={"subfilters": ("sins_gnss",)}, psns_bias_states=False)
    assert base.n == fed.n1 == 18
    f_n = np.array([0.01, -0.02, 9.80])
    for flt in (base, fed):
        flt.rotation_b_rad = (0.001, 0.002, 0.05)
        for _ in range(10):
            flt.predict(nav, f_n, 0.1)
    np.testing.assert_allclose(fed.P1, base.P, rtol=1e-9, atol=1e-30)
    p = nav.pos.copy()
    meas = GnssMeasurement(t_fpga_s=1.0, pos=(p[0] + 2e-7, p[1] - 3e-7, p[2] + 1.5), vel=np.array([0.02, -0.01, 0.0]),
                           vel_up=True)
    rb = base.update_gnss(nav, meas, p, np.zeros(3))
    fed.gnss_seen = True
    rf = fed.update_gnss(nav, meas, p, np.zeros(3))
    assert rb.accepted and rf.accepted and rb.n_rows == rf.n_rows == 6
    np.testing.assert_allclose(fed.P1, base.P, rtol=1e-9, atol=1e-30)
    np.testing.assert_allclose(fed.x1, base.x, rtol=1e-9, atol=1e-15)
    assert fed.x1[fed.gnss_states.i + 2] != 0.0  # the vertical receiver error is estimated
    assert fed.innovation_stats["gnss_position"]["rows"] == 3


@pytest.mark.parametrize("sun_sigma", [None, 0.01])
def test_pol_mimu_solar_update_uses_the_solve_quality_noise_and_the_bias_states(sun_sigma):
    """The MIMU/polarization sub-filter's sun-vector update by closed form: ``P+ = P - P H^T (H P H^T + r I)^-1 H P``
    with ``H = [-[S^n x] | 0 | 0 | [S^n x] C_b^n]`` (body-frame solar bias, no sky figure) and ``r`` from the solve
    (:func:`solar_noise_variance`) or, when the study fixes it, ``sun_sigma^2``."""
    from firmware_model.filters.solar import SolarObservation, solar_noise_variance
    from firmware_model.variants.federated import N2, X2_ATT

    _, fed, nav, cbn = _pair(fed_kw={"sun_sigma": sun_sigma}, psns_sky_bias_deg=0.0)
    assert fed.sun_states is not None and not fed.sun_states.shaped
    el, az = 35 * DEG, 220 * DEG
    s_n = np.array([math.cos(el) * math.sin(az), math.cos(el) * math.cos(az), math.sin(el)])
    obs = SolarObservation(t_exposure_s=2.0, s_b=cbn.T @ s_n, quality=0.004, n_used=150, source="camera")
    r = sun_sigma**2 if sun_sigma is not None else solar_noise_variance(fed.cfg, 0.004, 150)
    assert sun_sigma is not None or r == pytest.approx(fed.cfg.psns_noise_scale * 0.004 / 150)
    sx = np.array([[0.0, -s_n[2], s_n[1]], [s_n[2], 0.0, -s_n[0]], [-s_n[1], s_n[0], 0.0]])
    H = np.zeros((3, fed.n2))
    H[:, X2_ATT] = -sx
    H[:, N2:] = sx @ cbn
    P = fed.P2.copy()
    want = P - P @ H.T @ np.linalg.solve(H @ P @ H.T + r * np.eye(3), H @ P)
    rep = fed.update_solar(nav, obs, s_n, cbn)
    assert rep.accepted
    np.testing.assert_allclose(fed.P2, want, rtol=1e-6, atol=1e-16)
    # the fix counts its two dof across the sun (D-5.32, filters.solar.solar_fix_nis); a perfect solve here: NIS 0
    assert fed.innovation_stats["solar_vector"]["rows"] == 2
    assert fed.innovation_stats["solar_vector"]["nis_sum"] == pytest.approx(0.0, abs=1e-9)


def test_pol_mimu_solar_bias_states_are_local_not_shared_by_beta():
    """D-5.32: the solar-bias states model the solar sensor's (and the sky's) error, which only sub-filter 2's
    measurements see: at the first sun they take the base filter's meridian-shaped prior whole (not / beta_2), and
    their Q stays the Gauss-Markov's own, so a stationary prior stays stationary through a predict:
    ``P_mu' = (1 - T / tau)^2 P_mu + (2 T / tau) P_mu`` (with the old ``/ beta_2`` on both it grew by ``1 / beta_2``
    at the first sun and its Q was twice the sheet's)."""
    from firmware_model.filters.solar import SolarObservation

    _, fed, nav, cbn = _pair()
    sun = fed.sun_states
    assert sun is not None and sun.shaped
    el, az = 35 * DEG, 220 * DEG
    s_n = np.array([math.cos(el) * math.sin(az), math.cos(el) * math.cos(az), math.sin(el)])
    u = np.array([-math.cos(az), math.sin(az), 0.0])
    want = (sun.iso2 + sun.sky2) * np.eye(3) + (sun.sky_el2 - sun.sky2) * np.outer(u, u)
    P = fed.P2.copy()
    assert sun.set_axis(s_n, P)
    np.testing.assert_allclose(P[sun.i:, sun.i:], want, rtol=1e-12)
    # through the filter: the first sun's update (a perfect solve) leaves the prior's shape, then one predict
    obs = SolarObservation(t_exposure_s=1.0, s_b=cbn.T @ s_n, quality=0.004, n_used=150, source="camera")
    fed2 = _pair()[1]
    P0 = fed2.P2.copy()
    sun2 = fed2.sun_states
    assert sun2 is not None
    sun2.set_axis(s_n, P0)
    fed2.P2 = P0
    fed2.x2[:] = 0.0
    Tk = 0.1
    pm = P0[sun2.i:, sun2.i:].copy()
    fed2.predict(nav, np.array([0.0, 0.0, 9.80]), Tk)
    a = 1.0 - Tk / sun2.tau
    np.testing.assert_allclose(fed2.P2[sun2.i:, sun2.i:], a * a * pm + (2.0 * Tk / sun2.tau) * want, rtol=1e-9)
    assert fed.update_solar(nav, obs, s_n, cbn).accepted


def test_pol_mimu_static_gravity_keeps_the_accelerometer_bias_in_the_level():
    """At rest the gravity measurement sees the level and the accelerometer bias only as ``[g x] phi + C_b^n nabla``:
    however long it is averaged, the bias's horizontal components keep their prior (``sigma_nabla^2 / beta_2``) and the
    level keeps at least the part of its prior that the bias explains, ``A P_nabla A^T`` (``sigma_nabla / g`` per
    axis, shared by ``1 / beta_2``; D-5.14, D-5.20). A bias folded into the 5 s motion acceleration was forgotten:
    300 s of gravity shrank the level sigma to about half of that (0.127 deg against 0.286, field sheet)."""
    from firmware_model import earth
    from firmware_model.kf import PHI_E, PHI_N
    from firmware_model.units import G_STD
    from firmware_model.variants.federated import X2_ACC

    _, fed, nav, cbn = _pair(fed_kw={"subfilters": ("pol_mimu",)})
    g = earth.gravity(float(nav.pos[0]), float(nav.pos[2]))
    f_n = np.array([0.0, 0.0, g])
    for _ in range(3000):  # 300 s at the 10 Hz KF rate
        fed.predict(nav, f_n, 0.1)
    assert fed.mm.counters.get("gravity_admitted") == 3000 and "gravity_rejected" not in fed.mm.counters
    b2 = fed.p.beta_pol_mimu
    sig_nabla = fed.cfg.accel_bias_sigma_mg * 1e-3 * G_STD
    p_nabla_n = cbn @ fed.P2[X2_ACC, X2_ACC] @ cbn.T
    np.testing.assert_allclose(np.sqrt(np.diag(p_nabla_n)[:2]), sig_nabla / math.sqrt(b2), rtol=0.01)
    floor = sig_nabla / g / math.sqrt(b2)
    for i in (PHI_E, PHI_N):
        assert floor <= math.sqrt(fed.P2[i, i]) < 1.15 * floor
