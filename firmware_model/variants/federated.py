"""Federated SINS/GNSS + MIMU/polarization filter, no-reset, chi-square GNSS isolation (Ge, Gao, Wang, Zhang).

Ge Wenqiang et al., *bionic polarized-light / MIMU / GPS integrated navigation federated filter* (Beijing
Institute of Radio Metrology and Measurement). Federated structure after Carlson (1990); equations from
docs/reference/algorithms.md 5.2-5.3.

Sub-filter 1, **SINS/GNSS** (the base paper's 15-state error model, docs/reference/algorithms.md 1.3)::

    x1 = [phi | dv | dL dlambda dh | eps | nabla],   z = GNSS position and velocity (Eqs. 23-30 of the base paper)

Sub-filter 2, **MIMU/polarization** (the paper's second sub-filter, 9 states)::

    x2 = [phi (3) | eps (3) | a^b (3)]
    phi_dot = -[w_in x] phi - C_b^n eps,   eps_dot = 0,   a_k = c_a a_{k-1} + w_a  (first-order
    motion-acceleration model, the paper's Eq. 4: the next value stays in the neighbourhood of the
    current one, c_a = exp(-T / tau) sets the cut-off)

with the paper's two measurements: the **accelerometer gravity measurement**
``z_a = f^n - g_up^n = [g_up x] phi + C_b^n a^b`` (``f^n = C_b^{n'} f^b`` the SINS's specific force over
the KF interval; at rest ``f^b = C_n^b g_up`` + interference; first order in phi) and the **sun-vector
measurement** ``z_s = S^n - C_b^{n'} (+-S^b) = -[S^n x] phi`` (sign by the smaller residual, base paper).

**No-reset information sharing** (docs/reference/algorithms.md 5.3): ``P_i(0) = P_0 / beta_i``, ``Q_i = Q / beta_i``
once,
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
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .. import c674x, earth
from ..arrays import FloatArray, FloatDtype
from ..attitude import q2mat_fast, qmul, qnormalize, rv2q
from ..filters import (
    GnssMeasurement,
    NavFilter,
    SolarObservation,
    UpdateReport,
    feedback_cycles,
    gnss_measurement_rows,
    kf_predict_cycles,
    register_filter,
)
from ..kf import (
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
    process_noise_psd,
    solar_vector_residual,
    solar_vector_rows,
)
from ..nav_state import NavState
from ..units import DEG, DPH, G_STD
from .common import spd_inverse, spd_inverse_cycles, spd_solve, spd_solve_cycles
from .mode_manager import ModeManager

__all__ = ["FederatedFilter", "fuse_common_states", "scalar_update_cycles"]

#: sub-filter 2's state layout ``x2 = [phi | eps | a^b]`` (sub-filter 1 has the base filter's, :mod:`..kf`)
N2 = 9
X2_ATT, X2_GYRO, X2_MOTION = slice(0, 3), slice(3, 6), slice(6, 9)
#: the master's common states ``c = [phi | eps]``
G_ATT, G_GYRO = slice(0, 3), slice(3, 6)
#: where the common states sit in sub-filter 1 and in sub-filter 2
C1 = np.r_[IDX_ATT, IDX_GYRO]
C2 = np.r_[X2_ATT, X2_GYRO]
SUB_SINS_GNSS, SUB_POL_MIMU = "sins_gnss", "pol_mimu"


def scalar_update_cycles(n: int, c: c674x.KernelCosts) -> int:
    """One scalar Joseph update over ``n`` states (the base filter's 15-state figure generalised) [D]."""
    n2 = n * n
    return (2 * c.flops(n2, n2) + c.flops(n2, n2) + c.flops(2 * n2, 2 * n2) + c.flops(0, n * (n - 1) // 2)
            + c.math("recip") + c.flops(2 * n, 2 * n))


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
        arw = cfg.gyro_arw_deg_rt_h * DEG / 60.0
        vrw = cfg.accel_noise_ug_rt_hz * 1e-6 * G_STD
        tau = cfg.bias_corr_time_s
        self._qg = 2.0 * (cfg.gyro_bias_instability_deg_h * DPH) ** 2 / tau
        qa = 2.0 * (cfg.accel_bias_instability_mg * 1e-3 * G_STD) ** 2 / tau
        self.q1 = process_noise_psd(arw, vrw, self._qg, qa) / p.beta_sins_gnss
        self._arw2 = arw * arw
        self.x1 = np.zeros(N_STATES, dtype=dtype)
        self.P1 = np.zeros((N_STATES, N_STATES), dtype=dtype)
        self.x2 = np.zeros(N2, dtype=dtype)
        self.P2 = np.zeros((N2, N2), dtype=dtype)
        self._eye1 = np.eye(N_STATES, dtype=dtype)
        self._eye2 = np.eye(N2, dtype=dtype)
        self.isolated = False
        self._passes = 0
        self._isolated_t: float | None = None
        self.gnss_seen = False
        self.fused_mask = 0
        c = self.cost
        self._cyc_predict1 = kf_predict_cycles(c)
        self._cyc_predict2 = (c.w_vec(N2 * N2) + 2 * c.mat_mul(N2, N2, N2) + c.mat_trans(N2, N2) + c.flops(0, N2)
                              + c.flops(0, N2 * (N2 - 1) // 2) + c674x.mathlib("divdp"))
        self._cyc_up1 = scalar_update_cycles(N_STATES, c)
        self._cyc_up2 = scalar_update_cycles(N2, c)
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
        cfg, p, dt = self.cfg, self.p, self.dtype
        lat, h = float(nav.pos[0]), float(nav.pos[2])
        rm, rn = earth.radii(lat)
        lvl = cfg.accel_bias_sigma_mg * 1e-3
        att = [lvl**2, lvl**2, heading_sigma_rad**2]
        if p.initial_attitude_sigma_deg is not None:
            att = [(v * DEG) ** 2 for v in p.initial_attitude_sigma_deg]
        gyro = [(cfg.gyro_bias_sigma_deg_h * DPH) ** 2] * 3
        p01 = np.zeros(N_STATES)
        p01[IDX_ATT] = att
        p01[IDX_VEL] = 0.1**2
        p01[IDX_POS] = ((cfg.gnss_pos_sigma_h_m / (rm + h)) ** 2,
                        (cfg.gnss_pos_sigma_h_m / ((rn + h) * math.cos(lat))) ** 2, cfg.gnss_pos_sigma_v_m**2)
        p01[IDX_GYRO] = gyro
        p01[IDX_ACC] = (cfg.accel_bias_sigma_mg * 1e-3 * G_STD) ** 2
        p02 = np.zeros(N2)
        p02[X2_ATT] = att
        p02[X2_GYRO] = gyro
        p02[X2_MOTION] = p.motion_accel_sigma_mps2**2 + (cfg.accel_bias_sigma_mg * 1e-3 * G_STD) ** 2
        # no-reset information sharing, once: P_i(0) = P0 / beta_i
        self.P1 = np.diag(p01 / p.beta_sins_gnss).astype(dt)
        self.P2 = np.diag(p02 / p.beta_pol_mimu).astype(dt)
        self.x1 = np.zeros(N_STATES, dtype=dt)
        self.x2 = np.zeros(N2, dtype=dt)
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
        Phi1 = self._eye1 + F * dt(Tk)
        self.x1, self.P1 = kf_predict(self.x1, self.P1, Phi1, (self.q1 * Tk).astype(dt))
        self.meter.charge("fed_predict_sins_gnss", self._cyc_predict1)
        # sub-filter 2: attitude block and -C_b^n of F, first-order motion acceleration
        ca = math.exp(-Tk / p.motion_accel_tau_s)
        Phi2 = self._eye2.copy()
        Phi2[X2_ATT, X2_ATT] += F[IDX_ATT, IDX_ATT] * dt(Tk)
        Phi2[X2_ATT, X2_GYRO] = F[IDX_ATT, IDX_GYRO] * dt(Tk)
        Phi2[X2_MOTION, X2_MOTION] = self._eye2[X2_MOTION, X2_MOTION] * dt(ca)
        q2 = np.zeros(N2)
        q2[X2_ATT] = self._arw2 * Tk
        q2[X2_GYRO] = self._qg * Tk
        q2[X2_MOTION] = p.motion_accel_sigma_mps2**2 * (1.0 - ca * ca)
        q2 = q2 / p.beta_pol_mimu
        self.x2, self.P2 = kf_predict(self.x2, self.P2, Phi2, q2.astype(dt))
        self.meter.charge("fed_predict_pol_mimu", self._cyc_predict2)
        self._gravity_update(nav, cbn, f_n)
        self.feedback(nav)

    def _gravity_update(self, nav: NavState, cbn: FloatArray, f_n: FloatArray) -> None:
        """``z_a = f^n - [0, 0, g] = [g x] phi + C_b^n a^b`` (3 rows, sub-filter 2)."""
        dt = self.dtype
        g = earth.gravity(float(nav.pos[0]), float(nav.pos[2]))
        z = np.array([f_n[0], f_n[1], f_n[2] - g], dtype=dt)
        H = np.zeros((3, N2), dtype=dt)
        H[0, PHI_N] = -g  # phi occupies the same indices in x2 as in the base layout
        H[1, PHI_E] = g
        H[:, X2_MOTION] = cbn
        r = self.p.gravity_sigma_mps2**2
        A = H @ self.P2 @ H.T + np.eye(3, dtype=dt) * dt(r)
        innov = z - H @ self.x2
        nis = float(innov @ spd_solve(A, innov))
        self.meter.charge("fed_gravity_gate", self.cost.flops(27 * 9 + 27, 27 * 9) + spd_solve_cycles(3, 1, self.cost))
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
        idx = np.array([r[0] for r in rows])
        d = np.array([r[1] for r in rows])
        z = np.array([r[2] for r in rows])
        rr = np.array([r[3] for r in rows])
        eps = (z - d * self.x1[idx].astype(np.float64)).astype(dt)
        A = (self.P1[np.ix_(idx, idx)] * np.outer(d, d) + np.diag(rr)).astype(dt)
        lam = float(eps @ spd_solve(A, eps))
        self.meter.charge("fed_chi2", spd_solve_cycles(m, 1, self.cost) + self.cost.flops(2 * m * m, m * m))
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
        h = np.zeros(N_STATES, dtype=dt)
        innov = []
        for (i, hv, zz, r) in rows:
            h[:] = 0
            h[i] = hv
            self.x1, self.P1, nu, s = kf_update_scalar(self.x1, self.P1, h, zz, r)
            innov.append(nu / math.sqrt(s))
        self.meter.charge("kf_update", m * self._cyc_up1)
        return UpdateReport("gnss", True, m, max(abs(v) for v in innov), {"nis": lam})

    # -- sun vector (sub-filter 2) ----------------------------------------------------------------------
    def update_solar(self, nav: NavState, obs: SolarObservation, s_n: FloatArray, cbn_exp: FloatArray) -> UpdateReport:
        dt = self.dtype
        s_n = s_n.astype(dt)
        z, sign = solar_vector_residual(s_n, cbn_exp.astype(dt), obs.s_b.astype(dt))
        Hs = solar_vector_rows(s_n, dt)[:, IDX_ATT]
        H = np.zeros((3, N2), dtype=dt)
        H[:, X2_ATT] = Hs
        r = self.p.sun_sigma**2
        A = Hs @ self.P2[X2_ATT, X2_ATT] @ Hs.T + np.eye(3, dtype=dt) * dt(r)
        innov = z - H @ self.x2
        lam = float(innov @ spd_solve(A, innov))
        self.meter.charge("solar_residual", self.cost.flops(18 + 9, 18 + 6))
        self.meter.charge("fed_solar_gate", self.cost.flops(54, 45) + spd_solve_cycles(3, 1, self.cost))
        t = self.host.now_s() if self.host is not None else obs.t_exposure_s
        resid = math.degrees(math.sqrt(float(z @ z)))
        if not self.mm.gate(t, "solar", lam, 3, residual_deg=resid):
            return UpdateReport("solar", False, 0, math.sqrt(lam), {"residual_deg": resid, "sign": sign})
        out = []
        for i in range(3):
            self.x2, self.P2, nu, s = kf_update_scalar(self.x2, self.P2, H[i], float(z[i]), r)
            out.append(nu / math.sqrt(s))
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
            self.x2[X2_MOTION] -= x1[IDX_ACC]
            x1[IDX_VEL] = 0
            x1[IDX_POS] = 0
            x1[IDX_ACC] = 0
        # reported covariance: the fused attitude block with sub-filter 1's velocity/position
        P = self.P1.copy()
        P[IDX_ATT, IDX_ATT] = Pg[G_ATT, G_ATT]
        self.P = P
