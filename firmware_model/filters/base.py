"""The base variant (Liang & Bai): the bi-direction solar-vector error-state KF with GNSS position/velocity and ``+-S``
updates, registered as ``firmware.filter: base``.

Its state is the 15-state model of :mod:`firmware_model.kf` (attitude error ``phi`` rad in the local-level ENU frame
n, velocity error ENU m/s, position error ``dL dlambda`` rad and ``dh`` m, gyro bias rad/s and accelerometer bias
m/s^2 in body axes), augmented when the configuration asks by the GNSS-error states (m, ENU;
:class:`~firmware_model.filters.gnss.GnssErrorStates`), the solar-vector bias states (rad;
:class:`~firmware_model.filters.solar.SolarBiasStates`) and the gyro flicker's middle band (rad/s, body;
:class:`~firmware_model.filters.noise_model.GyroFlickerStates`), then a variant's own states. Q and P0 come from the
spec sheet (:mod:`firmware_model.filters.noise_model`); cycles are charged per kernel
(:mod:`firmware_model.filters.cycles`). The variants of :mod:`firmware_model.variants` subclass it.
"""

from __future__ import annotations

import math

import numpy as np

from .. import c674x, earth
from ..arrays import F64Array, FloatArray, FloatDtype
from ..attitude import q2mat_fast, qmul, qnormalize, rv2q
from ..config import FirmwareConfig
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
    error_transition_matrix,
    kf_predict,
    kf_update_scalar,
    solar_vector_residual,
    solar_vector_rows,
)
from ..nav_state import NavState
from ..units import DEG
from .cycles import feedback_cycles, kf_predict_cycles, kf_scalar_update_cycles
from .gnss import GnssErrorStates, GnssMeasurement, gnss_fix_scale, gnss_measurement_rows
from .interface import NavFilter, UpdateReport, register_filter
from .noise_model import (
    ROTATION_NOISE_FLOPS,
    WARMUP_NOISE_CYCLES,
    GyroFlickerStates,
    gyro_flicker_band,
    rotation_attitude_noise,
    spec_initial_covariance,
    spec_process_noise,
    warmup_gyro_bias_variance,
)
from .solar import SolarBiasStates, SolarObservation, solar_noise_variance

__all__ = [
    "BaseFilter",
]


def _full_q(qk: FloatArray) -> F64Array:
    """``Q_k`` as a full float64 matrix that may be modified in place: the diagonal (n,) expanded, a full (n, n)
    copied (the predict's extra noise terms add blocks to it)."""
    return np.diag(qk.astype(np.float64)) if qk.ndim == 1 else qk.astype(np.float64, copy=True)


@register_filter("base")
class BaseFilter(NavFilter):
    """Bi-direction solar-vector 15-state KF (base paper): GNSS position/velocity + ``+-S`` updates."""

    #: augmented states this variant carries when the configuration asks for them (docs/decisions/
    #: filter-consistency.md): 3 GNSS position errors (E, N, U m, Gauss-Markov) and 3 solar-vector biases (body rad)
    augmentable = True
    #: whether the solar-vector bias states are among them (a variant whose PSNS measurement is not the base
    #: filter's solar vector, e.g. the dual-vector compass update, carries the GNSS states only)
    solar_bias_augmentable = True
    #: further states a variant declares for its own measurements, after the augmented ones (index ``i_own``;
    #: the variant gives them their prior and process noise; zero rows of F: random constants unless it sets a rate)
    own_states = 0

    def __init__(self, cfg: FirmwareConfig, meter: c674x.CycleMeter, dtype: FloatDtype) -> None:
        super().__init__(cfg, meter, dtype)
        n = N_STATES
        #: first index of the GNSS position-error states (E, N, U, m) and of the solar-vector bias states (body x, y,
        #: z, rad), or None when the variant or the configuration has none (layout: firmware_model/kf.py + these)
        self.i_gnss: int | None = None
        self.i_sun: int | None = None
        if self.augmentable and cfg.gnss_error_states:
            self.i_gnss, n = n, n + 3
        if self.augmentable and self.solar_bias_augmentable and cfg.psns_bias_states and cfg.psns_enabled:
            self.i_sun, n = n, n + 3
        #: first index of the gyro flicker's middle-band states (body x, y, z, rad/s; D-5.28), or None
        self.i_flicker: int | None = None
        if self.augmentable and cfg.gyro_flicker_states and gyro_flicker_band(cfg)[1] > 0.0:
            self.i_flicker, n = n, n + 3
        self.i_own: int | None = None
        if self.own_states:
            self.i_own, n = n, n + self.own_states
        self.n = n
        self.x = np.zeros(n, dtype=dtype)
        self.P = np.zeros((n, n), dtype=dtype)
        #: the augmented states' models (shared with the federated sub-filters: one declaration)
        self.gnss_states = GnssErrorStates(cfg, self.i_gnss) if self.i_gnss is not None else None
        self.sun_states = SolarBiasStates(cfg, self.i_sun) if self.i_sun is not None else None
        self.flicker_states = GyroFlickerStates(cfg, self.i_flicker) if self.i_flicker is not None else None
        q = np.zeros(n)
        q[:N_STATES] = spec_process_noise(cfg)
        #: Gauss-Markov decay rates (1/s) of the augmented states, on F's diagonal
        self._aug_rate = np.zeros(n)
        for st in (self.gnss_states, self.sun_states, self.flicker_states):
            if st is not None:
                q[st.i:st.i + 3] = st.psd
                self._aug_rate[st.i:st.i + 3] = st.rate
        self.q = q
        #: rotation-dependent attitude noise (D-5.14) only with a scale-factor or misalignment figure
        self._rot_var = (cfg.gyro_scale_factor_ppm * 1e-6) ** 2 + (cfg.gyro_misalignment_mrad * 1e-3) ** 2
        self._eye = np.eye(n, dtype=dtype)
        self._qk_interval, self._qk = math.nan, self.q  # Q_k of the last KF interval (predict)
        self._cyc_update = kf_scalar_update_cycles(self.cost, n)
        self._cyc_predict = kf_predict_cycles(self.cost, n)
        self._cyc_feedback = feedback_cycles(self.cost)

    # -- initialisation -------------------------------------------------------------------------
    def initialise(self, nav: NavState, heading_sigma_rad: float) -> None:
        """P0 from the spec sheet (:func:`spec_initial_covariance`): level from the accelerometer bias (correlated
        with the bias states), heading from the alignment, position from the first fix (its correlated error shared
        with the GNSS-error states, :meth:`GnssErrorStates.set_prior`), the solar-bias states' stationary variance."""
        n = self.n
        P = np.zeros((n, n))
        P[:N_STATES, :N_STATES] = spec_initial_covariance(self.cfg, nav, heading_sigma_rad)
        if self.gnss_states is not None:
            lat, h = float(nav.pos[0]), float(nav.pos[2])
            rm, rn = earth.radii(lat)
            self.gnss_states.set_prior(P, rm + h, (rn + h) * math.cos(lat))
            self.gnss_states.t_last_fix = None
            self.q[self.gnss_states.i:self.gnss_states.i + 3] = self.gnss_states.psd  # the sheet's level again
            self._qk_interval = math.nan
        if self.sun_states is not None:
            self.sun_states.reset(P)
        if self.flicker_states is not None:
            i = self.flicker_states.i
            P[i:i + 3, i:i + 3] = np.eye(3) * self.flicker_states.var
        self.P = P.astype(self.dtype)
        self.x = np.zeros(n, dtype=self.dtype)

    # -- time update --------------------------------------------------------------------------
    def predict(self, nav: NavState, f_n: FloatArray, Tk: float) -> None:
        dt = self.dtype
        cbn = q2mat_fast(nav.q)
        F15 = error_transition_matrix(cbn, nav.v, nav.pos, f_n, dtype=dt)
        if self.n > N_STATES:  # augmented states: first-order Gauss-Markov, no coupling into the navigation errors
            F = np.zeros((self.n, self.n), dtype=dt)
            F[:N_STATES, :N_STATES] = F15
            F[np.diag_indices(self.n)] -= self._aug_rate.astype(dt)
            if self.flicker_states is not None:  # the flicker drives the attitude as the bias does (D-5.28)
                i = self.flicker_states.i
                F[IDX_ATT, i:i + 3] = F15[IDX_ATT, IDX_GYRO]
        else:
            F = F15
        Phi = self._eye + F * dt(Tk)
        sun = self.sun_states
        # the sky's error decorrelates over the heading turned (D-5.33)
        turn = 0.0 if sun is None else sun.decay_over_turn(Phi, cbn, self.meter, self.cost)
        if Tk != self._qk_interval:  # Q_k = q T_k: the same every interval but the first after alignment
            self._qk_interval, self._qk = Tk, (self.q * Tk).astype(dt)
        rot_b = self.rotation_b_rad
        qk: FloatArray = self._qk
        if self._rot_var > 0.0 and any(rot_b):
            qk = self._rotation_noise(nav, rot_b, qk)
        if sun is not None and sun.shaped and sun.axis_n is not None:
            qk = self._sun_bias_noise(qk, Tk, turn)
        qw = warmup_gyro_bias_variance(self.cfg, float(nav.t) - Tk, Tk)
        if qw > 0.0:  # the temperature-gradient bias's in-run change while the box warms up (D-5.27)
            qk = _full_q(qk)
            qk[IDX_GYRO, IDX_GYRO] += np.eye(3) * qw
            qk = qk.astype(dt)
            self.meter.charge("kf_warmup_noise", WARMUP_NOISE_CYCLES)
        self.x, self.P = kf_predict(self.x, self.P, Phi, qk)
        self.meter.charge("kf_predict", self._cyc_predict)

    def _sun_bias_noise(self, qk: FloatArray, Tk: float, turn_rad: float = 0.0) -> FloatArray:
        """Q_k with the solar-vector bias block :meth:`SolarBiasStates.noise_block` (the Gauss-Markov's stationary
        covariance, its direction following the sun) in place of the isotropic diagonal."""
        sun = self.sun_states
        assert sun is not None
        i = sun.i
        q = _full_q(qk)
        q[i:i + 3, i:i + 3] = sun.noise_block(Tk, turn_rad)
        self.meter.charge("kf_sun_bias_noise", c674x.flops(9, 6) + c674x.CALL_OVERHEAD)
        return q.astype(self.dtype)

    def _rotation_noise(self, nav: NavState, rot_b: tuple[float, float, float], qk_in: FloatArray) -> FloatArray:
        """Q_k with the attitude noise of the gyros' scale factor and misalignment over the interval's turns
        (:func:`rotation_attitude_noise`, D-5.14) added to the attitude block."""
        qk_att = rotation_attitude_noise(self.cfg, q2mat_fast(nav.q), rot_b)
        qk = _full_q(qk_in)
        qk[IDX_ATT, IDX_ATT] += qk_att
        self.meter.charge("kf_rotation_noise", c674x.flops(*ROTATION_NOISE_FLOPS) + c674x.CALL_OVERHEAD)
        return qk.astype(self.dtype)

    # -- measurement updates --------------------------------------------------------------------
    def _scalar(self, h: FloatArray, z: float, r: float) -> float:
        x, P, nu, s = kf_update_scalar(self.x, self.P, h, z, r)
        if not (s > 0.0 and math.isfinite(s) and math.isfinite(nu)):
            # a covariance that lost positive definiteness, or a non-finite measurement that got this far:
            # the update is refused and the state kept (counted; the loop's divergence check re-aligns)
            self.counters["kf_update_refused"] = self.counters.get("kf_update_refused", 0) + 1
            return 0.0
        self.x, self.P = x, P
        return nu / math.sqrt(s)

    def _gnss_row_gated(self, h: FloatArray, z: float, r: float) -> bool:
        """Innovation gate of one GNSS row: ``nu^2 / (h P h^T + r) > gnss_gate_chi2`` (or not finite) refuses it."""
        s = float(h @ (self.P @ h)) + r
        nu = float(z - h @ self.x)
        nis = nu * nu / s if s > 0.0 else math.inf
        if not nis <= self.cfg.gnss_gate_chi2:
            self.counters["gnss_rows_gated"] = self.counters.get("gnss_rows_gated", 0) + 1
            return True
        return False

    def _gnss_relock(self, t_fix: float) -> None:
        """A loss of lock re-draws the GNSS error states (:meth:`GnssErrorStates.relock`, D-5.17): counted, charged."""
        if self.gnss_states is not None and self.gnss_states.relock(self.x, self.P, t_fix):
            self.counters["gnss_relock_redraws"] = self.counters.get("gnss_relock_redraws", 0) + 1
            self.meter.charge("gnss_relock", self.cost.flops(0, 6 * self.n))

    def _gnss_level(self, meas: GnssMeasurement, p_first: FloatArray | None = None) -> None:
        """The GNSS error states follow the fix's reported geometry (:meth:`GnssErrorStates.set_level`, D-5.42):
        their process noise is re-read when the level changes (charged). ``p_first`` (lat rad, lon rad, h m): the
        first fix since the prior, whose position variance rises with the level too."""
        gs = self.gnss_states
        prior = None
        if p_first is not None:
            lat, h = float(p_first[0]), float(p_first[2])
            rm, rn = earth.radii(lat)
            prior = (rm + h, (rn + h) * math.cos(lat))
        if gs is not None and gs.set_level(self.P, gnss_fix_scale(self.cfg, meas) ** 2, prior):
            self.q[gs.i:gs.i + 3] = gs.psd
            self._qk_interval = math.nan  # Q_k = q T_k is recomputed at the next predict
            self.counters["gnss_level_changes"] = self.counters.get("gnss_level_changes", 0) + 1
            self.meter.charge("gnss_level", self.cost.flops(6, 6))

    def update_gnss(self, nav: NavState, meas: GnssMeasurement, p_ins: FloatArray, v_ins: FloatArray) -> UpdateReport:
        dt = self.dtype
        if meas.pos is not None:
            first = self.gnss_states is not None and self.gnss_states.t_last_fix is None
            self._gnss_relock(meas.t_fpga_s)
            self._gnss_level(meas, p_ins if first else None)
        rows = gnss_measurement_rows(self.cfg, self.meter, meas, p_ins, v_ins)
        innov = []
        h = np.zeros(self.n, dtype=dt)
        gated = 0
        for idx, hval, z, r in rows:
            h[:] = 0
            h[idx] = hval
            kind = "gnss_position" if idx in (D_LAT, D_LON, D_H) else "gnss_velocity"
            if self.gnss_states is not None and kind == "gnss_position":
                # z = p_INS - p_GNSS = dp - b: the correlated error is a state, R only its white part
                r = self.gnss_states.position_row(h, idx)
            if self._gnss_row_gated(h, z, r):
                gated += 1
                continue
            nu = self._scalar(h, z, r)
            self._count_nis(kind, nu)
            innov.append(nu)
        self.meter.charge("kf_update", len(rows) * self._cyc_update)
        n = len(rows) - gated
        return UpdateReport("gnss", n > 0 or not rows, n, max((abs(v) for v in innov), default=0.0),
                            {"gated_rows": gated} if gated else None)

    def update_solar(self, nav: NavState, obs: SolarObservation, s_n: FloatArray, cbn_exp: FloatArray) -> UpdateReport:
        """Eqs. 31-42: ``Z = S^n - C_b^{n'} (+-S^b)``, sign by the smaller ``|Z|``, ``H = -[S^n x]``."""
        cfg = self.cfg
        dt = self.dtype
        s_n = s_n.astype(dt)
        z, sign = solar_vector_residual(s_n, cbn_exp.astype(dt), obs.s_b.astype(dt))
        sun = self.sun_states
        if sun is not None and sun.shaped and sun.set_axis(s_n, self.P):
            self.meter.charge("solar_bias_axis", self.cost.flops(4, 2) + self.cost.math("rsqrt"))
        H = solar_vector_rows(s_n, dt, self.n)
        if sun is not None:
            # the bias in the local-level frame, where the sky's error stays in the solar meridian whatever the body
            # does (D-5.16): Z = -[S^n x] phi + [S^n x] mu; or in the body: Z = -[S^n x] phi + [S^n x] C_b^n mu
            sun.rows(H, H[:, IDX_ATT], cbn_exp.astype(dt))
        r = solar_noise_variance(cfg, obs.quality, obs.n_used)
        self.meter.charge("solar_residual", self.cost.flops(18 + 9, 18 + 6))
        # innovation gate: |Z|^2 against its predicted variance tr(H P H^T) + 3 r (no 3x3 inverse)
        var = float(np.einsum("ij,jk,ik->", H, self.P, H)) + 3.0 * r
        nu3 = z - H @ self.x  # the augmented solar-bias states carry an estimate between feedbacks
        z2 = float(nu3 @ nu3)
        self.meter.charge("solar_gate", self.cost.flops(45, 40))
        nis = z2 / var
        if nis > cfg.psns_gate_chi2:
            return UpdateReport("solar", False, 0, math.sqrt(nis), {"residual_deg": math.sqrt(z2) / DEG, "sign": sign})
        innov = [self._scalar(H[i], float(z[i]), r) for i in range(3)]
        self._count_solar_nis(innov, z, s_n, r)
        self.meter.charge("kf_update", 3 * self._cyc_update)
        return UpdateReport("solar", True, 3, max(abs(v) for v in innov),
                            {"residual_deg": math.sqrt(z2) / DEG, "sign": sign})

    # -- closed loop ----------------------------------------------------------------------------
    def feedback(self, nav: NavState) -> None:
        """Correct the navigation state with the estimate and zero the error state."""
        dt = self.dtype
        x = self.x
        # attitude: C_b^n = (I + [phi x]) C_b^{n'}  ->  q <- rv2q(phi) (x) q
        nav.q = qnormalize(qmul(rv2q(x[IDX_ATT]), nav.q)).astype(nav.q.dtype)
        nav.v = (nav.v - x[IDX_VEL]).astype(nav.v.dtype)
        nav.pos = nav.pos - x[IDX_POS].astype(np.float64)
        self.gyro_bias = (self.gyro_bias + x[IDX_GYRO]).astype(dt)
        self.accel_bias = (self.accel_bias + x[IDX_ACC]).astype(dt)
        x_new = np.zeros(self.n, dtype=dt)
        x_new[N_STATES:] = x[N_STATES:]  # the augmented states are estimates of sensor errors, not fed back
        self.x = x_new
        self.meter.charge("kf_feedback", self._cyc_feedback)
