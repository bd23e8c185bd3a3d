"""Federated SINS/GNSS + MIMU/polarization filter, no-reset, chi-square GNSS isolation (Ge, Gao, Wang, Zhang).

Ge Wenqiang et al., *bionic polarized-light / MIMU / GPS integrated navigation federated filter* (Beijing
Institute of Radio Metrology and Measurement). Federated structure after Carlson (1990); equations from
docs/reference/algorithms.md 5.2-5.3.

Sub-filter 1, **SINS/GNSS** (the base paper's 15-state error model, docs/reference/algorithms.md 1.3)::

    x1 = [phi | dv | dL dlambda dh | eps | nabla],   z = GNSS position and velocity (Eqs. 23-30 of the base paper)

Sub-filter 2, **MIMU/polarization** (the paper's second sub-filter, 9 states, + the accelerometer bias, 12)::

    x2 = [phi (3) | eps (3) | a^b (3) | nabla (3)]
    phi_dot = -[w_in x] phi - C_b^n eps,   eps_dot = 0,   a_k = c_a a_{k-1} + w_a  (first-order
    motion-acceleration model, the paper's Eq. 4: the next value stays in the neighbourhood of the
    current one, c_a = exp(-T / tau) sets the cut-off),   nabla_dot = w_nabla (the base model's bias rows)

with the paper's two measurements: the **accelerometer gravity measurement**
``z_a = f^n - g_up^n = [g_up x] phi + C_b^n (a^b + nabla)`` (``f^n = C_b^{n'} f^b`` the SINS's specific force
over the KF interval; at rest ``f^b = C_n^b g_up`` + interference; first order in phi) and the **sun-vector
measurement** ``z_s = S^n - C_b^{n'} (+-S^b) = -[S^n x] phi`` (sign by the smaller residual, base paper).

**No-reset information sharing** (docs/reference/algorithms.md 5.3): ``P_i(0) = P_0 / beta_i``, ``Q_i = Q / beta_i``
once, over the states whose errors both sub-filters see (the base model's; the sensor-error states that only one
sub-filter's measurements see keep their own P0 and Q, D-5.32),
``beta_1 = beta_2 = 0.5`` (the paper's choice), master share ``beta_m = 0``. The master fuses the common
states ``c = [phi, eps]``::

    P_g = (P_1c^-1 + P_2c^-1)^-1,   x_g = P_g (P_1c^-1 x_1c + P_2c^-1 x_2c)        (Eqs. 23-24 of the paper)

over the sub-filters that are admitted. The master never overwrites a local filter. The fused estimate
is fed back into the common reference (the SINS: attitude, gyro bias; and, while SINS/GNSS is admitted,
its velocity, position and accelerometer-bias estimates), and every local filter's state is shifted by
exactly the correction applied to the reference (``x_i <- x_i - x_applied``): each local filter keeps
its own information and its own estimate of the (corrected) reference, nothing of one sub-filter leaks
into the other, and the linearisation stays valid with a 25 deg/h gyro (docs/variants.md, D-6.3).

**Chi-square isolation** (docs/reference/algorithms.md 5.2): before a GNSS update, ``lambda = eps^T A^-1 eps`` with
``A = H P_1 H^T + R`` over the fix's m rows (5 with NMEA, 6 with UBX velD); ``lambda > chi2_{1-alpha}(m)``
isolates the GNSS: the epoch is not used, SINS/GNSS leaves the fusion (reconfiguration to MIMU/polarization,
event ``gnss_isolated``), its time update continues. When ``readmit_after`` consecutive epochs pass the
test, GNSS is readmitted (event ``gnss_readmitted``) and fused again.

``subfilters`` picks what the master fuses, which gives the paper's three configurations on one stream:
both (the three-way combination), ``pol_mimu`` (polarization/MIMU) and ``sins_gnss`` (SINS/GPS).

**What the box knows of its sensors** (docs/decisions/filter-consistency.md D-5.18, D-5.19): the sub-filters are
configured as the base filter is, by the same code (:mod:`firmware_model.filters`): Q and P0 of the common model
from the spec sheet (:func:`~firmware_model.filters.noise_model.spec_process_noise`,
:func:`~firmware_model.filters.noise_model.spec_initial_covariance`, the turns' rotation noise
:func:`~firmware_model.filters.noise_model.rotation_attitude_noise`); the SINS/GNSS sub-filter carries the three
Gauss-Markov GNSS-error states (:class:`~firmware_model.filters.gnss.GnssErrorStates`: ``x1 = [15 | b_E b_N b_U]``) when
``gnss_error_states``; the MIMU/polarization sub-filter takes the solar vector's noise from the solve's quality
(:func:`~firmware_model.filters.solar.solar_noise_variance`) unless ``sun_sigma`` fixes it, and carries the three
solar-bias states (:class:`~firmware_model.filters.solar.SolarBiasStates`: ``x2 = [phi | eps | a^b | nabla | mu]``) when
``psns_bias_states``. The augmented states are local to their sub-filter: the master fuses ``[phi, eps]`` only, and
they are never fed back. Sub-filter 2's accelerometer bias ``nabla`` is the base model's bias state (spec-sheet P0 with
the level's correlation, random-walk Q), apart from the 5 s motion acceleration, which would forget a turn-on bias
within seconds and let the averaged gravity measurement claim a level the accelerometers cannot give (D-5.20).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .. import c674x, earth
from ..arrays import FloatArray, FloatDtype
from ..attitude import q2mat_fast, qmul, qnormalize, rv2q
from ..filters.cycles import feedback_cycles, kf_predict_cycles, kf_scalar_update_cycles
from ..filters.gnss import GnssErrorStates, GnssMeasurement, gnss_fix_scale, gnss_measurement_rows
from ..filters.interface import NavFilter, UpdateReport, register_filter
from ..filters.noise_model import (
    ROTATION_NOISE_FLOPS,
    WARMUP_NOISE_CYCLES,
    rotation_attitude_noise,
    spec_initial_covariance,
    spec_process_noise,
    warmup_gyro_bias_variance,
)
from ..filters.solar import SolarBiasStates, SolarObservation, solar_noise_variance
from ..kf import (
    D_H,
    D_LAT,
    D_LON,
    IDX_ACC,
    IDX_ATT,
    IDX_GYRO,
    IDX_POS,
    IDX_VEL,
    N_STATES,
    PHI_E,
    PHI_N,
    error_transition_matrix,
    kf_predict,
    kf_update_scalar,
    solar_vector_residual,
    solar_vector_rows,
)
from ..nav_state import NavState
from ..units import DEG
from .common import spd_inverse, spd_inverse_cycles, spd_solve, spd_solve_cycles
from .mode_manager import ModeManager

__all__ = ["FederatedFilter", "fuse_common_states", "pol_mimu_predict_cycles"]

#: sub-filter 2's state layout ``x2 = [phi | eps | a^b | nabla]`` (+ the solar-bias states ``mu`` at ``N2`` when
#: carried; sub-filter 1 has the base filter's, :mod:`..kf`, + the GNSS-error states at ``N_STATES``)
N2 = 12
X2_ATT, X2_GYRO, X2_MOTION, X2_ACC = slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12)
#: the master's common states ``c = [phi | eps]``
G_ATT, G_GYRO = slice(0, 3), slice(3, 6)
#: where the common states sit in sub-filter 1 and in sub-filter 2
C1 = np.r_[IDX_ATT, IDX_GYRO]
C2 = np.r_[X2_ATT, X2_GYRO]
#: the base model's states that sub-filter 2 shares (P0 block, D-5.20): attitude, gyro bias, accelerometer bias
B2 = np.r_[IDX_ATT, IDX_GYRO, IDX_ACC]
S2 = np.r_[X2_ATT, X2_GYRO, X2_ACC]
SUB_SINS_GNSS, SUB_POL_MIMU = "sins_gnss", "pol_mimu"


def pol_mimu_predict_cycles(c: c674x.KernelCosts, n: int) -> int:
    """Time update of the MIMU/polarization sub-filter over ``n`` states [D]: ``Phi`` from F's attitude blocks
    (DSPF_sp_w_vec, n^2), ``Phi P Phi^T`` (2 x DSPF_sp_mat_mul n x n x n), a transpose, Q on the diagonal,
    symmetrise, and the motion model's ``exp(-T / tau)`` (one division, as the base charges it)."""
    return (c.w_vec(n * n) + 2 * c.mat_mul(n, n, n) + c.mat_trans(n, n) + c.flops(0, n)
            + c.flops(0, n * (n - 1) // 2) + c674x.mathlib("divdp"))


def fuse_common_states(parts: list[tuple[FloatArray, FloatArray]]) -> tuple[FloatArray, FloatArray]:
    """Master fusion ``P_g = (sum P_i^-1)^-1``, ``x_g = P_g sum P_i^-1 x_i`` over (x_i, P_i) pairs
    (docs/reference/algorithms.md 5.3)."""
    if len(parts) == 1:
        return parts[0][0].copy(), parts[0][1].copy()
    info = None
    vec = None
    for x, P in parts:
        Pi = spd_inverse(P)
        info = Pi if info is None else info + Pi
        vec = Pi @ x if vec is None else vec + Pi @ x
    assert info is not None and vec is not None
    Pg = spd_inverse(info)
    return (Pg @ vec).astype(parts[0][0].dtype), Pg


@register_filter("federated")
class FederatedFilter(NavFilter):
    """Two local filters and a master (module docstring)."""

    def __init__(self, cfg: Any, meter: c674x.CycleMeter, dtype: FloatDtype) -> None:
        super().__init__(cfg, meter, dtype)
        self.p = p = cfg.variants.federated
        for s in p.subfilters:
            if s not in (SUB_SINS_GNSS, SUB_POL_MIMU):
                raise ValueError(f"federated subfilters must be {SUB_SINS_GNSS!r} and/or {SUB_POL_MIMU!r}, got {s!r}")
        self.mm = ModeManager("federated", cfg.variants.mode_manager)
        self.counters = self.mm.counters
        # sub-filter 1: the base filter's 15 states (+ the GNSS-error states), its spec-sheet Q (D-5.18)
        n1 = N_STATES
        self.gnss_states: GnssErrorStates | None = None
        if cfg.gnss_error_states:
            self.gnss_states, n1 = GnssErrorStates(cfg, n1), n1 + 3
        # sub-filter 2: [phi | eps | a^b | nabla] (+ the solar-bias states, D-5.18, D-5.20)
        n2 = N2
        self.sun_states: SolarBiasStates | None = None
        if cfg.psns_bias_states and cfg.psns_enabled:
            self.sun_states, n2 = SolarBiasStates(cfg, n2), n2 + 3
        self.n1, self.n2 = n1, n2
        q15 = spec_process_noise(cfg)
        q1 = np.zeros(n1)
        q1[:N_STATES] = q15
        #: Gauss-Markov decay rates (1/s) of sub-filter 1's and sub-filter 2's augmented states (F's diagonal)
        self._rate1 = np.zeros(n1)
        self._rate2 = np.zeros(n2)
        if self.gnss_states is not None:
            g = self.gnss_states
            q1[g.i:g.i + 3] = g.psd
            self._rate1[g.i:g.i + 3] = g.rate
        # no-reset sharing over the shared states only: the GNSS-error states are local (D-5.32, :meth:`initialise`)
        q1[:N_STATES] /= p.beta_sins_gnss
        self.q1 = q1
        #: sub-filter 2's white PSDs of the shared states: the base model's attitude (ARW^2 + the gyro flicker's
        #: white equivalent), gyro-bias and accelerometer-bias rows
        self._q2_att = q15[IDX_ATT]
        self._q2_gyro = q15[IDX_GYRO]
        self._q2_acc = q15[IDX_ACC]
        self._q2_sun: FloatArray | None = None
        if self.sun_states is not None:
            sn = self.sun_states
            self._q2_sun = sn.psd
            self._rate2[sn.i:sn.i + 3] = sn.rate
        self._rot_var = (cfg.gyro_scale_factor_ppm * 1e-6) ** 2 + (cfg.gyro_misalignment_mrad * 1e-3) ** 2
        self.x1 = np.zeros(n1, dtype=dtype)
        self.P1 = np.zeros((n1, n1), dtype=dtype)
        self.x2 = np.zeros(n2, dtype=dtype)
        self.P2 = np.zeros((n2, n2), dtype=dtype)
        self.P = np.zeros((n1, n1), dtype=dtype)
        self._eye1 = np.eye(n1, dtype=dtype)
        self._eye2 = np.eye(n2, dtype=dtype)
        self.isolated = False
        self._passes = 0
        self._isolated_t: float | None = None
        self.gnss_seen = False
        self.fused_mask = 0
        c = self.cost
        self._cyc_predict1 = kf_predict_cycles(c, n1)
        self._cyc_predict2 = pol_mimu_predict_cycles(c, n2)
        self._cyc_up1 = kf_scalar_update_cycles(c, n1)
        self._cyc_up2 = kf_scalar_update_cycles(c, n2)
        self._cyc_fuse = 3 * spd_inverse_cycles(6, c) + c.flops(3 * 36, 3 * 36) + feedback_cycles(c)

    # -- introspection ------------------------------------------------------------------------------------
    @property
    def x(self) -> FloatArray:
        return self.x1

    def drain_events(self) -> list[dict[str, Any]]:
        return self.mm.drain() if self.mm.events else []

    def variant_status(self) -> tuple[int, int, int] | None:
        return self.fused_mask, 0, 0

    def _active(self) -> list[str]:
        out = []
        if SUB_SINS_GNSS in self.p.subfilters and not self.isolated and self.gnss_seen:
            out.append(SUB_SINS_GNSS)
        if SUB_POL_MIMU in self.p.subfilters:
            out.append(SUB_POL_MIMU)
        return out

    def _report_mode(self, t: float, reason: str) -> None:
        act = self._active()
        mask = (1 if SUB_SINS_GNSS in act else 0) | (2 if SUB_POL_MIMU in act else 0)
        self.fused_mask = mask
        name = {3: "three_way", 2: "pol_mimu", 1: "sins_gnss", 0: "none"}[mask]
        self.mm.set_mode(t, "federated_mode", name, reason, fused=act)

    # -- initialisation -----------------------------------------------------------------------------------
    def initialise(self, nav: NavState, heading_sigma_rad: float) -> None:
        """P0 of both sub-filters from the base filter's spec-sheet P0 (:func:`spec_initial_covariance`): sub-filter 1
        takes it whole (+ the GNSS-error states' prior correlated with the first fix), sub-filter 2 its attitude, gyro-
        and accelerometer-bias blocks with the level's correlation with that bias (D-5.14's ``cov(phi, nabla)``, D-5.20)
        and the motion acceleration's stationary variance;
        ``initial_attitude_sigma_deg`` (the sigma of a study's imposed misalignment, which the alignment task applies on
        top of the coarse alignment's frame: ``C_b^{n'} = rv2m(-phi_m) C_b^n``, D-6.8) adds its variance to the
        attitude block, ``P_phi = P_phi,align + diag(sigma_m^2)``: the two errors add, and the imposed one is
        independent of the sensors, so the level's correlation with the accelerometer bias stays ``A P_nabla``
        (D-5.29). Then the no-reset sharing, once: ``P_i(0) = P_0 / beta_i`` over the states whose errors both
        sub-filters see; the sensor-error states that only one sub-filter's measurements see (the receiver's correlated
        error in sub-filter 1, the solar vector's systematic error in sub-filter 2) keep the sheet's P0, and their Q
        (:meth:`predict`) stays undivided (D-5.32). Their errors and driving noise reach no estimate of the other
        sub-filter, so the joint covariance of the two local errors has no common part there and the upper bound
        ``diag(P_1 / beta_1, P_2 / beta_2)`` holds without inflating them (Carlson's bound is for the common part)."""
        cfg, p, dt = self.cfg, self.p, self.dtype
        p15 = spec_initial_covariance(cfg, nav, heading_sigma_rad)
        if p.initial_attitude_sigma_deg is not None:
            p15[IDX_ATT, IDX_ATT] += np.diag([(v * DEG) ** 2 for v in p.initial_attitude_sigma_deg])
        P1 = np.zeros((self.n1, self.n1))
        P1[:N_STATES, :N_STATES] = p15
        if self.gnss_states is not None:
            lat, h = float(nav.pos[0]), float(nav.pos[2])
            rm, rn = earth.radii(lat)
            self.gnss_states.set_prior(P1, rm + h, (rn + h) * math.cos(lat))
            self.gnss_states.t_last_fix = None
            self.q1[self.gnss_states.i:self.gnss_states.i + 3] = self.gnss_states.psd  # the sheet's level again
        P2 = np.zeros((self.n2, self.n2))
        P2[np.ix_(S2, S2)] = p15[np.ix_(B2, B2)]
        P2[X2_MOTION, X2_MOTION] = np.eye(3) * p.motion_accel_sigma_mps2**2
        if self.sun_states is not None:
            self.sun_states.reset(P2)
        # no-reset information sharing, once: P_i(0) = P0 / beta_i over the shared states (D-5.32)
        P1[:N_STATES, :N_STATES] /= p.beta_sins_gnss
        P2[:N2, :N2] /= p.beta_pol_mimu
        self.P1 = P1.astype(dt)
        self.P2 = P2.astype(dt)
        self.x1 = np.zeros(self.n1, dtype=dt)
        self.x2 = np.zeros(self.n2, dtype=dt)
        self.P = self.P1.copy()
        self.isolated = False
        self._passes = 0
        t = self.host.now_s() if self.host is not None else 0.0
        self._report_mode(t, "initialised")

    # -- time update (+ the accelerometer gravity measurement of sub-filter 2) -------------------------------
    def predict(self, nav: NavState, f_n: FloatArray, Tk: float) -> None:
        dt, p = self.dtype, self.p
        cbn = q2mat_fast(nav.q).astype(dt)
        F = error_transition_matrix(cbn, nav.v, nav.pos, f_n, dtype=dt)
        n1, n2 = self.n1, self.n2
        if n1 > N_STATES:  # the GNSS-error states: first-order Gauss-Markov, no coupling (as the base filter's)
            F1 = np.zeros((n1, n1), dtype=dt)
            F1[:N_STATES, :N_STATES] = F
            F1[np.diag_indices(n1)] -= self._rate1.astype(dt)
        else:
            F1 = F
        Phi1 = self._eye1 + F1 * dt(Tk)
        q1: FloatArray = self.q1 * Tk
        # the turns' attitude noise of gyro scale factor and misalignment (D-5.14), shared by both sub-filters
        rot = self.rotation_b_rad
        q_rot = None
        if self._rot_var > 0.0 and any(rot):
            q_rot = rotation_attitude_noise(self.cfg, cbn, rot)
            self.meter.charge("kf_rotation_noise", c674x.flops(*ROTATION_NOISE_FLOPS) + c674x.CALL_OVERHEAD)
            q1 = np.diag(q1)
            q1[IDX_ATT, IDX_ATT] += q_rot / p.beta_sins_gnss
        # the temperature-gradient gyro bias's in-run change while the box warms up (D-5.27), shared as Q is
        qw = warmup_gyro_bias_variance(self.cfg, float(nav.t) - Tk, Tk)
        if qw > 0.0:
            self.meter.charge("kf_warmup_noise", WARMUP_NOISE_CYCLES)
            if q1.ndim == 1:
                q1 = np.diag(q1)
            q1[IDX_GYRO, IDX_GYRO] += np.eye(3) * (qw / p.beta_sins_gnss)
        self.x1, self.P1 = kf_predict(self.x1, self.P1, Phi1, q1.astype(dt))
        self.meter.charge("fed_predict_sins_gnss", self._cyc_predict1)
        # sub-filter 2: attitude block and -C_b^n of F, first-order motion acceleration, the accelerometer bias's
        # random walk (identity in Phi), Gauss-Markov solar bias
        ca = math.exp(-Tk / p.motion_accel_tau_s)
        Phi2 = self._eye2.copy()
        Phi2[X2_ATT, X2_ATT] += F[IDX_ATT, IDX_ATT] * dt(Tk)
        Phi2[X2_ATT, X2_GYRO] = F[IDX_ATT, IDX_GYRO] * dt(Tk)
        Phi2[X2_MOTION, X2_MOTION] = self._eye2[X2_MOTION, X2_MOTION] * dt(ca)
        Phi2[np.diag_indices(n2)] -= (self._rate2 * Tk).astype(dt)
        sun = self.sun_states
        # the sky's error decorrelates over the heading turned (D-5.33)
        turn = 0.0 if sun is None else sun.decay_over_turn(Phi2, cbn, self.meter, self.cost)
        q2 = np.zeros((n2, n2))
        q2[X2_ATT, X2_ATT] = np.diag(self._q2_att * Tk)
        if q_rot is not None:
            q2[X2_ATT, X2_ATT] += q_rot
        q2[X2_GYRO, X2_GYRO] = np.diag(self._q2_gyro * Tk) + np.eye(3) * qw
        q2[X2_MOTION, X2_MOTION] = np.eye(3) * (p.motion_accel_sigma_mps2**2 * (1.0 - ca * ca))
        q2[X2_ACC, X2_ACC] = np.diag(self._q2_acc * Tk)
        if sun is not None and self._q2_sun is not None:
            i = sun.i
            if sun.shaped and sun.axis_n is not None:  # the sky's error across the solar meridian (D-5.16)
                q2[i:i + 3, i:i + 3] = sun.noise_block(Tk, turn)
                self.meter.charge("kf_sun_bias_noise", c674x.flops(9, 6) + c674x.CALL_OVERHEAD)
            else:
                q2[i:i + 3, i:i + 3] = np.diag(self._q2_sun * Tk)
        q2[:N2, :N2] /= p.beta_pol_mimu  # the solar-bias states' Q is local, not shared (D-5.32)
        self.x2, self.P2 = kf_predict(self.x2, self.P2, Phi2, q2.astype(dt))
        self.meter.charge("fed_predict_pol_mimu", self._cyc_predict2)
        self._gravity_update(nav, cbn, f_n)
        self.feedback(nav)

    def _gravity_update(self, nav: NavState, cbn: FloatArray, f_n: FloatArray) -> None:
        """``z_a = f^n - [0, 0, g] = [g x] phi + C_b^n (a^b + nabla)`` (3 rows, sub-filter 2)."""
        dt = self.dtype
        g = earth.gravity(float(nav.pos[0]), float(nav.pos[2]))
        z = np.array([f_n[0], f_n[1], f_n[2] - g], dtype=dt)
        H = np.zeros((3, self.n2), dtype=dt)
        H[0, PHI_N] = -g  # phi occupies the same indices in x2 as in the base layout
        H[1, PHI_E] = g
        H[:, X2_MOTION] = cbn
        H[:, X2_ACC] = cbn
        r = self.p.gravity_sigma_mps2**2
        A = H @ self.P2 @ H.T + np.eye(3, dtype=dt) * dt(r)
        innov = z - H @ self.x2
        nis = float(innov @ spd_solve(A, innov))
        # H P H^T over H's 8 non-zeros per row (2 level, 3 + 3 of C_b^n): 3 x 8 x n2 then 3 x 3 x 8
        n2 = self.n2
        self.meter.charge("fed_gravity_gate", self.cost.flops(24 * n2 + 72 + 3, 24 * n2 + 72)
                          + spd_solve_cycles(3, 1, self.cost))
        t = self.host.now_s() if self.host is not None else 0.0
        if not self.mm.gate(t, "gravity", nis, 3):
            return
        for i in range(3):
            self.x2, self.P2, _, _ = kf_update_scalar(self.x2, self.P2, H[i], float(z[i]), r)
        self.meter.charge("kf_update", 3 * self._cyc_up2)

    # -- GNSS: chi-square test, isolation, readmission (sub-filter 1) ---------------------------------------
    def update_gnss(self, nav: NavState, meas: GnssMeasurement, p_ins: FloatArray, v_ins: FloatArray) -> UpdateReport:
        dt = self.dtype
        rows = gnss_measurement_rows(self.cfg, self.meter, meas, p_ins, v_ins)
        m = len(rows)
        t = self.host.now_s() if self.host is not None else meas.t_fpga_s
        if m == 0:
            return UpdateReport("gnss", False, 0, 0.0, {"reason": "empty"})
        gs = self.gnss_states
        prior = None
        if meas.pos is not None and gs is not None and gs.t_last_fix is None:  # the first fix since the prior
            lat, h = float(p_ins[0]), float(p_ins[2])
            rm, rn = earth.radii(lat)
            prior = (rm + h, (rn + h) * math.cos(lat))
        if meas.pos is not None and gs is not None and gs.relock(self.x1, self.P1, meas.t_fpga_s):
            # a loss of lock: the receiver's correlated error is a fresh draw (D-5.17, as the base filter)
            self.counters["gnss_relock_redraws"] = self.counters.get("gnss_relock_redraws", 0) + 1
            self.meter.charge("gnss_relock", self.cost.flops(0, 6 * self.n1))
        if meas.pos is not None and gs is not None and gs.set_level(self.P1, gnss_fix_scale(self.cfg, meas) ** 2,
                                                                     prior):
            # the fix's geometry scales the receiver's error (D-5.42, as the base filter; the states are local)
            self.q1[gs.i:gs.i + 3] = gs.psd
            self.meter.charge("gnss_level", self.cost.flops(6, 6))
        # the rows as H (m, n1): position rows z = dp - b with R the white part when the GNSS error is a state
        H = np.zeros((m, self.n1))
        z = np.array([r[2] for r in rows])
        rr = np.array([r[3] for r in rows])
        for k, (i, hv, _zz, _r) in enumerate(rows):
            H[k, i] = hv
            if gs is not None and i in (D_LAT, D_LON, D_H):
                rr[k] = gs.position_row(H[k], i)
        nnz = 2 if gs is not None else 1  # non-zeros per position row
        eps = (z - H @ self.x1.astype(np.float64)).astype(dt)
        A = (H @ self.P1.astype(np.float64) @ H.T + np.diag(rr)).astype(dt)
        lam = float(eps @ spd_solve(A, eps))
        self.meter.charge("fed_chi2", spd_solve_cycles(m, 1, self.cost)
                          + self.cost.flops(nnz * nnz * m * m + nnz * m, nnz * nnz * m * m))
        passed = self.mm.gate(t, "gnss", lam, m, t_meas_s=meas.t_fpga_s)
        self.gnss_seen = True
        if not passed:
            self._passes = 0
            if not self.isolated:
                self.isolated = True
                self._isolated_t = meas.t_fpga_s
                self.mm.event(t, "gnss_isolated", "chi2_fail", nis=lam, threshold=self.mm.chi2_threshold(m), dof=m,
                              t_meas_s=meas.t_fpga_s)
                self._report_mode(t, "gnss_isolated")
            return UpdateReport("gnss", False, 0, math.sqrt(lam), {"reason": "chi2_fail", "nis": lam})
        if self.isolated:
            self._passes += 1
            if self._passes < self.p.readmit_after:
                return UpdateReport("gnss", False, 0, math.sqrt(lam), {"reason": "awaiting_readmission"})
            self.isolated = False
            iso_s = meas.t_fpga_s - (self._isolated_t or meas.t_fpga_s)
            self.mm.event(t, "gnss_readmitted", "chi2_pass", nis=lam, threshold=self.mm.chi2_threshold(m), dof=m,
                          isolated_s=iso_s, t_meas_s=meas.t_fpga_s)
        self._report_mode(t, "gnss_admitted")
        innov = []
        for k in range(m):
            self.x1, self.P1, nu, s = kf_update_scalar(self.x1, self.P1, H[k].astype(dt), float(z[k]), float(rr[k]))
            innov.append(nu / math.sqrt(s))
            self._count_nis("gnss_position" if rows[k][0] in (D_LAT, D_LON, D_H) else "gnss_velocity",
                            innov[-1])
        self.meter.charge("kf_update", m * self._cyc_up1)
        return UpdateReport("gnss", True, m, max(abs(v) for v in innov), {"nis": lam})

    # -- sun vector (sub-filter 2) ----------------------------------------------------------------------
    def update_solar(self, nav: NavState, obs: SolarObservation, s_n: FloatArray, cbn_exp: FloatArray) -> UpdateReport:
        dt = self.dtype
        s_n = s_n.astype(dt)
        z, sign = solar_vector_residual(s_n, cbn_exp.astype(dt), obs.s_b.astype(dt))
        Hs = solar_vector_rows(s_n, dt)[:, IDX_ATT]
        H = np.zeros((3, self.n2), dtype=dt)
        H[:, X2_ATT] = Hs
        sun = self.sun_states
        if sun is not None:
            # the solar-vector bias, as the base filter models it (D-5.13, D-5.16)
            # (its prior in the meridian's shape: local to this sub-filter, not shared by beta_2, D-5.32)
            if sun.shaped and sun.set_axis(s_n, self.P2):
                self.meter.charge("solar_bias_axis", self.cost.flops(4, 2) + self.cost.math("rsqrt"))
            sun.rows(H, Hs, cbn_exp.astype(dt))
        # the solve's own noise (D-5.13), or the study's fixed figure
        sig = self.p.sun_sigma
        r = sig * sig if sig is not None else solar_noise_variance(self.cfg, obs.quality, obs.n_used)
        A = H @ self.P2 @ H.T + np.eye(3, dtype=dt) * dt(r)
        innov = z - H @ self.x2
        lam = float(innov @ spd_solve(A, innov))
        self.meter.charge("solar_residual", self.cost.flops(18 + 9, 18 + 6))
        k = 2 if sun is not None else 1  # H's non-zero 3x3 blocks
        self.meter.charge("fed_solar_gate", self.cost.flops(54 * k * k, 45 * k * k) + spd_solve_cycles(3, 1, self.cost))
        t = self.host.now_s() if self.host is not None else obs.t_exposure_s
        resid = math.degrees(math.sqrt(float(z @ z)))
        if not self.mm.gate(t, "solar", lam, 3, residual_deg=resid):
            return UpdateReport("solar", False, 0, math.sqrt(lam), {"residual_deg": resid, "sign": sign})
        out = []
        for i in range(3):
            self.x2, self.P2, nu, s = kf_update_scalar(self.x2, self.P2, H[i], float(z[i]), r)
            out.append(nu / math.sqrt(s))
        self._count_solar_nis(out, z, s_n, r)
        self.meter.charge("kf_update", 3 * self._cyc_up2)
        return UpdateReport("solar", True, 3, max(abs(v) for v in out), {"residual_deg": resid, "sign": sign})

    # -- master fusion and feedback into the common reference -------------------------------------------
    def feedback(self, nav: NavState) -> None:
        dt = self.dtype
        act = self._active()
        parts = []
        if SUB_SINS_GNSS in act:
            parts.append((self.x1[C1], self.P1[np.ix_(C1, C1)]))
        if SUB_POL_MIMU in act:
            parts.append((self.x2[C2], self.P2[np.ix_(C2, C2)]))
        self.meter.charge("fed_fusion", self._cyc_fuse)
        if not parts:
            return
        xg, Pg = fuse_common_states(parts)
        xg = xg.astype(dt)
        # feed the fused common states into the reference and shift every local filter by the same amount
        nav.q = qnormalize(qmul(rv2q(xg[G_ATT]), nav.q)).astype(nav.q.dtype)
        self.gyro_bias = (self.gyro_bias + xg[G_GYRO]).astype(dt)
        self.x1[IDX_ATT] -= xg[G_ATT]
        self.x1[IDX_GYRO] -= xg[G_GYRO]
        self.x2[X2_ATT] -= xg[G_ATT]
        self.x2[X2_GYRO] -= xg[G_GYRO]
        if SUB_SINS_GNSS in act:
            x1 = self.x1
            nav.v = (nav.v - x1[IDX_VEL]).astype(nav.v.dtype)
            nav.pos = nav.pos - x1[IDX_POS].astype(np.float64)
            self.accel_bias = (self.accel_bias + x1[IDX_ACC]).astype(dt)
            self.x2[X2_ACC] -= x1[IDX_ACC]
            x1[IDX_VEL] = 0
            x1[IDX_POS] = 0
            x1[IDX_ACC] = 0
        # reported covariance: the fused attitude block with sub-filter 1's velocity/position
        P = self.P1.copy()
        P[IDX_ATT, IDX_ATT] = Pg[G_ATT, G_ATT]
        self.P = P
