"""Dual-vector switching (patent): discrimination factors, the two measurement models, the switch (Done-when)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from firmware_model import Firmware, FirmwareConfig
from firmware_model.attitude import a2mat, q2mat, rv2q, yaw_from_heading
from firmware_model.kf import N_STATES
from firmware_model.variants.common import compass_mountings, cross
from firmware_model.variants.dual_vector import (
    discrimination_factors,
    pair_bias_covariance,
    polarization_error,
    sun_error_vector,
    unit_error_figures,
    unit_evectors,
)
from firmware_model.variants.params import DualVectorParams, VariantParams
from protocols.constants import DEG
from protocols.host import HostFormat, NavSolution
from protocols.stream import StreamDecoder

from .streams import CompassSpec, GnssSpec, ImuErrors, StreamSpec, rayleigh, run, static_trajectory, wire_aop

S_N = np.array([-0.876416, -0.282797, 0.389770])  # Beijing case (docs/reference/algorithms.md 3)
THREE = compass_mountings([(0.0, 0.0), (45.0, 0.0), (45.0, 90.0)])


def _measured(cbn: np.ndarray, mounts: np.ndarray) -> np.ndarray:
    """Noise-free measured polarization vectors through the wire AOP (the tests' own Rayleigh sky)."""
    s_b = cbn.T @ S_N
    _, e_b = rayleigh(s_b, mounts[:, :, 2], 0.7)
    e_u = np.einsum("uji,uj->ui", mounts, e_b)
    return unit_evectors(wire_aop(e_u[:, 0], e_u[:, 1]), mounts, np.float64)


def test_discrimination_factor_is_the_sine_of_the_polarization_angle_error_and_sign_free():
    cbn = a2mat(2 * DEG, -3 * DEG, yaw_from_heading(30 * DEG))
    p = _measured(cbn, THREE)
    s_b = cbn.T @ S_N
    _, lam, _ = discrimination_factors(p, s_b, THREE[:, :, 2])
    assert np.all(lam < 1e-9)
    _, lam_flip, _ = discrimination_factors(-p, s_b, THREE[:, :, 2])
    assert np.all(lam_flip < 1e-9)
    # turn unit 1's measured vector about its ray by 4 deg: lambda_1 = sin 4 deg
    r = THREE[1, :, 2]
    p1 = q2mat(rv2q(4 * DEG * r)) @ p[1]
    p2 = np.array([p[0], p1, p[2]])
    _, lam2, _ = discrimination_factors(p2, s_b, THREE[:, :, 2])
    assert lam2[1] == pytest.approx(math.sin(4 * DEG), rel=1e-9) and lam2[0] < 1e-9


@pytest.mark.parametrize("phi_deg", [(0.3, -0.2, 0.5), (-0.4, 0.1, -0.2)])
def test_both_measurement_models_match_the_nonlinear_error_to_first_order(phi_deg):
    cbn = a2mat(2 * DEG, -3 * DEG, yaw_from_heading(30 * DEG))
    phi = np.array(phi_deg) * DEG
    computed = q2mat(rv2q(-phi)) @ cbn  # C_b^{n'}: the INS is off by phi
    p = _measured(cbn, THREE)
    # sun-error-vector: s~ from two measured polarization vectors, Z projected on u1, u2 == u_k . phi
    s_meas = cross(p[1], p[2])
    s_meas /= np.linalg.norm(s_meas)
    for sign in (1.0, -1.0):
        z, (u1, u2) = sun_error_vector(computed, sign * s_meas, S_N)
        for u in (u1, u2):
            assert float(u @ z) == pytest.approx(float(u @ phi), abs=2e-3 * np.linalg.norm(phi))
    # polarization-error-vector: z = (s x p)^T phi, invariant to the sign of p~
    for sign in (1.0, -1.0):
        z1, h = polarization_error(computed, sign * p[0], S_N)
        assert z1 == pytest.approx(float(h @ phi), abs=2e-3 * np.linalg.norm(phi) * np.linalg.norm(h))


def _run_blocked(duration_s: float = 115.0):
    spec = StreamSpec(static_trajectory(30.0, 2.0, -3.0), duration_s,
                      imu=ImuErrors((9.0, -7.0, 3.0), 0.15, (1500.0, -1000.0, 2000.0), 100.0),
                      gnss=GnssSpec(True, 3.0, 0.03), psns="compass",
                      compass=CompassSpec(THREE, blocked=(((1, 2), 60.0, 90.0), ((0, 1, 2), 100.0, 110.0))))
    fw = Firmware(FirmwareConfig(filter="dual_vector", compass_mountings=THREE, initial_heading_deg=30.5))
    navs: list[tuple[float, NavSolution]] = []
    dec = StreamDecoder([HostFormat()])

    def on_tick(fw, r):
        for _, data, _ in r.outputs:
            navs.extend((r.t_fpga_s, f) for f in dec.feed(data) if isinstance(f, NavSolution))

    samples, events = run(fw, spec, sample_every_s=0.2, on_tick=on_tick)
    return fw, samples, events, navs


def test_blocking_two_of_three_switches_within_one_update_and_attitude_stays_below_half_a_degree():
    fw, samples, events, navs = _run_blocked()
    modes = [e for e in events if e["event"] == "psns_mode"]
    assert [m["mode"] for m in modes] == ["sun_error_vector", "polarization_error_vector", "sun_error_vector",
                                          "none", "sun_error_vector"]
    to_pol, back, none, recovered = modes[1:]
    # the first frame exposed after the block (5 Hz: the one at 60.0 s) already switches
    assert 60.0 <= to_pol["t_meas_s"] < 60.0 + 0.2 and to_pol["q"] == [1, 0, 0]
    assert 90.0 <= back["t_meas_s"] < 90.2 and 100.0 <= none["t_meas_s"] < 100.2
    assert 110.0 <= recovered["t_meas_s"] < 110.2
    assert none["reason"] == "no_reliable_sensor"
    # every q_i is reported (event) with its discrimination factor
    q_reports = [e for e in events if e["event"] == "psns_quality"]
    assert q_reports[1]["mode"] == [1, 0, 0] and q_reports[1]["factors"][0] < 0.05
    rejected = {(e["channel"], e["reason"]) for e in events if e["event"] == "measurement_rejected"}
    assert {("compass_unit1", "low_dop"), ("compass_unit2", "low_dop"), ("compass_unit0", "low_dop")} <= rejected
    # attitude error against truth through the switch and the single-sensor phase
    att = np.array([np.linalg.norm(s.att_err_deg) for s in samples if 10.0 <= s.t <= 115.0])
    win = np.array([np.linalg.norm(s.att_err_deg) for s in samples if 55.0 <= s.t <= 95.0])
    assert att.max() < 0.5 and win.max() < 0.5
    # mode and every q_i in the navigation frame (VARIANT block), PSNS status "rejected" while all are blocked
    by_t = {round(t, 3): n for t, n in navs}
    assert by_t[50.0].variant_mode == 2 and by_t[50.0].psns_q_mask == 0b111 and by_t[50.0].psns_units == 3
    assert by_t[75.0].variant_mode == 1 and by_t[75.0].psns_q_mask == 0b001
    assert by_t[105.0].variant_mode == 0 and by_t[105.0].psns_q_mask == 0 and by_t[105.0].psns_status == 2
    # no polarization update while all are blocked
    assert fw.counters["compass_unit0_rejected"] >= 49
    assert fw.counters["polarization_vector_admitted"] >= 140 and fw.counters["sun_vector_admitted"] >= 350


def test_unit_sigmas_are_the_spec_sheets_compass_figures_and_the_filter_carries_its_states():
    """D-5.22: AOP noise at the reference DOP growing as 1/DOP from the configuration (the spec sheet), unless the
    scenario sets it; the calibration's residuals as the pair's bias states, after the base's GNSS states."""
    cfg = FirmwareConfig(filter="dual_vector", compass_mountings=THREE, compass_aop_sigma_deg=0.2,
                         compass_aop_dop_ref=0.4, compass_aop_residual_deg=0.18, compass_installation_residual_deg=0.13)
    aop_ref, res2, w2 = unit_error_figures(cfg)
    assert aop_ref == pytest.approx(0.2 * 0.4 * DEG, rel=1e-12)
    assert (res2, w2) == (pytest.approx((0.18 * DEG) ** 2), pytest.approx((0.13 * DEG) ** 2))
    flt = Firmware(cfg).filter
    dop = np.array([0.4, 0.2, 0.002])
    np.testing.assert_allclose(flt._unit_sigmas(dop), [0.2 * DEG, 0.4 * DEG, 40.0 * DEG], rtol=1e-6)
    np.testing.assert_allclose(flt._unit_sigmas(np.array([0.9])), [0.08 / 0.9 * DEG], rtol=1e-6)
    # the base filter's three GNSS position-error states, no solar-bias states, the gyro flicker's three (D-5.28),
    # the pair's three bias states
    assert (flt.n, flt.i_gnss, flt.i_sun, flt.i_flicker, flt.i_own) == (N_STATES + 9, N_STATES, None, N_STATES + 3,
                                                                        N_STATES + 6)
    # a scenario's own AOP figures replace the sheet's
    own = FirmwareConfig(filter="dual_vector", compass_mountings=THREE, compass_aop_sigma_deg=0.2,
                         variants=VariantParams(dual_vector=DualVectorParams(aop_sigma_deg=0.05, dop_ref=0.5)))
    assert unit_error_figures(own)[0] == pytest.approx(0.025 * DEG, rel=1e-12)


def test_pair_bias_covariance_matches_the_sample_of_turned_units():
    """pair_bias_covariance against Monte Carlo: turn the two units by random installation rotations and E-vector
    residuals, measure the pair's sun vector through the wire, and compare the bias rotations' covariance."""
    cbn = q2mat(rv2q(np.array([0.03, -0.05, 0.5])))  # a tilted, turned box
    s_b = cbn.T @ S_N
    rays = THREE[:, :, 2]
    _, e_b = rayleigh(s_b, rays, 0.7)
    sw, sr = 0.13 * DEG, 0.18 * DEG
    cov = pair_bias_covariance(s_b, e_b[1], e_b[2], rays[1], rays[2], sr * sr, sw * sw)
    rng = np.random.default_rng(5)
    mus = []
    for _ in range(4000):
        e = []
        for u in (1, 2):
            w = rng.normal(0.0, sw, 3)
            a = rng.normal(0.0, sr)
            eu = e_b[u] - np.cross(w, e_b[u])  # the unit's installation rotation
            eu = eu - a * np.cross(rays[u], eu)  # its E-vector residual about the ray
            e.append(eu / np.linalg.norm(eu))
        sm = np.cross(e[0], e[1])
        sm = sm / np.linalg.norm(sm) * np.sign(sm @ s_b)
        mus.append(np.cross(s_b, sm))  # mu = S x dS
    sample = np.cov(np.array(mus).T)
    np.testing.assert_allclose(cov, sample, atol=0.06 * np.abs(cov).max())
    assert np.abs(cov @ s_b).max() < 1e-12 * np.abs(cov).max() + 1e-20  # no rotation about S
