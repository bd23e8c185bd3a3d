"""Navigation-filter variants behind one interface, and the base variant (Liang & Bai).

The main loop (:mod:`firmware_model.firmware`) owns I/O, time keeping, alignment, the strapdown and
the task schedule; a :class:`NavFilter` owns the error state, its covariance and the measurement
models. The loop calls, per tick and only when there is something to do::

    predict(nav, f_n_mean, T_k)              every ``kf_predict_every`` IMU ticks
    update_gnss(nav, meas, p_ins, v_ins)      a GNSS fix is pending (1 Hz)
    update_solar(nav, obs, s_n, cbn_exp)      a PSNS solar vector is pending (frame rate)
    update_compass(nav, frame, t_exp)         a multi-unit compass frame is pending
    update_polarization_obs(nav, frame, t_exp)  a POLARIZATION_OBS frame, for variants that set
                                              ``raw_polarization_obs`` (instead of the firmware's solve)
    feedback(nav)                             closed-loop correction after updates

and, for every variant, once per tick (cheap: the base variant returns nothing)::

    drain_events()                            decisions to log (TickResult.events)
    variant_status()                          (variant_mode, psns_units, psns_q_mask) for the NAV_SOLUTION
                                              VARIANT block and STATUS, or None (base: no block)

Services of the main loop a variant may use (:class:`FilterHost`, handed over by :meth:`NavFilter.attach`):
UTC for the ephemeris, the INS state at a measurement's time, the mean of the MAG frames around a given
time, the current tick time.

Variants register themselves in :data:`FILTER_VARIANTS` with :func:`register_filter`; the
scenario's ``firmware.filter`` picks one by name. The variants of :mod:`firmware_model.variants` (dual-vector
switching, K-means
3-D attitude, federated filter with chi-square isolation, sun-elevation positioning with a
Sage-Husa adaptive KF) subclass :class:`NavFilter` (or :class:`BaseFilter`) and override the
updates they change; the loop stays as it is.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol, TypeVar

import numpy as np

from protocols.host import FILTER_VARIANT_NAMES

from . import c674x, earth
from .arrays import F64Array, FloatArray, FloatDtype
from .attitude import q2mat_fast, qmul, qnormalize, rv2q
from .config import FILTER_VARIANTS, FirmwareConfig
from .kf import (
    D_H,
    D_LAT,
    D_LON,
    DV_E,
    DV_N,
    DV_U,
    IDX_ACC,
    IDX_ATT,
    IDX_GYRO,
    IDX_POS,
    IDX_VEL,
    N_STATES,
    error_transition_matrix,
    kf_predict,
    kf_update_scalar,
    process_noise_psd,
    solar_vector_residual,
    solar_vector_rows,
)
from .nav_state import NavState
from .units import DEG, DPH, G_STD

#: reference angle of the rotation-dependent attitude noise (BaseFilter._rotation_noise), rad
_THETA_REF_RAD = math.pi / 2.0
#: Allan-deviation floor of flicker bias noise per unit bias instability B (IEEE Std 952: 0.664 B)
_ALLAN_FLOOR = math.sqrt(2.0 * math.log(2.0) / math.pi)
#: interval of the GNSS velocity aiding (s): 1 Hz fixes (for the flicker's matching time, BaseFilter._flicker_match_s)
_VEL_AID_INTERVAL_S = 1.0

__all__ = [
    "FILTER_VARIANTS",
    "BaseFilter",
    "FilterHost",
    "GnssMeasurement",
    "NavFilter",
    "SolarObservation",
    "UpdateReport",
    "feedback_cycles",
    "gnss_measurement_rows",
    "kf_predict_cycles",
    "kf_scalar_update_cycles",
    "register_filter",
]


def kf_scalar_update_cycles(c: c674x.KernelCosts, n: int = N_STATES) -> int:
    """One scalar Joseph update over ``n`` states [D, docs/reference/c674x-cycles.md section 6 fallback].

    ``a = P h`` and ``c = B h`` (2 x n^2 MAC), ``B = P - K a^T`` (n^2 MAC),
    ``P' = B - c K^T + r K K^T`` (2 n^2 MAC), symmetrise (n(n-1)/2 ADD), one reciprocal (MATHLIB [S]).
    """
    n2 = n * n
    return (2 * c.flops(n2, n2) + c.flops(n2, n2) + c.flops(2 * n2, 2 * n2) + c.flops(0, n * (n - 1) // 2)
            + c.math("recip") + c.flops(2 * n, 2 * n))


def kf_predict_cycles(c: c674x.KernelCosts, n: int = N_STATES) -> int:
    """Time update [S formulas, D sum]: F elements (~40 MUL/ADD, DP sin/cos and 4 divisions of the
    latitude terms), ``Phi = I + F T`` (DSPF_sp_w_vec, n^2), ``Phi P`` and ``(Phi P) Phi^T``
    (2 x DSPF_sp_mat_mul n x n x n), one transpose (DSPF_sp_mat_trans), Q on the diagonal, symmetrise."""
    return (c.flops(40, 40) + c674x.mathlib("divdp", 4) + c674x.mathlib("sindp") + c674x.mathlib("cosdp")
            + c.w_vec(n * n) + 2 * c.mat_mul(n, n, n) + c.mat_trans(n, n) + c.flops(0, n)
            + c.flops(0, n * (n - 1) // 2))


def solar_noise_variance(cfg: FirmwareConfig, quality: float, n_used: int) -> float:
    """Variance (rad^2 per axis) of a solved solar vector from the solve's own quality (docs/decisions/
    filter-consistency.md): with ``K = sum w E E^T`` and per-point misfit of variance ``sigma_e^2``,
    ``lambda_min ~ W sigma_e^2`` and ``lambda_j ~ W c_j``; first-order perturbation of the smallest eigenvector gives
    ``var_j = sigma_e^2 / (n c_j) = lambda_min / (n lambda_j)`` along the other eigenvectors. ``psns_noise_scale``
    absorbs the points' correlation (neighbouring pixels see the same sky); the spec sheet's floor bounds it below."""
    floor = (cfg.psns_sigma_deg * DEG) ** 2
    if n_used <= 0 or not math.isfinite(quality):
        return floor
    return max(floor, cfg.psns_noise_scale * max(quality, 0.0) / n_used)


def feedback_cycles(c: c674x.KernelCosts) -> int:
    """Closed-loop feedback: rv2q (sqrt, sin, cos, div), qmul (16 MUL, 12 ADD), normalise (rsqrt),
    3 DP position subtractions, 9 additions [S/D]."""
    return (c.math("sqrt") + c.math("sin") + c.math("cos") + c.math("div") + c.math("rsqrt")
            + c.flops(20, 24) + c674x.dp_flops(0, 3))


@dataclass
class GnssMeasurement:
    """A GNSS fix, time-tagged at its PPS edge (FPGA time base).

    ``pos`` = (lat rad, lon rad, h m) or None; ``vel`` = ENU m/s (3,) or None; ``vel_up`` tells
    whether ``vel[2]`` was measured (UBX NAV-PVT velD) or is absent (NMEA RMC).
    """

    t_fpga_s: float
    pos: tuple[float, float, float] | None = None
    vel: FloatArray | None = None
    vel_up: bool = False
    #: False: a 2-D fix (horizontal position only; ``pos[2]`` is no measurement)
    pos_up: bool = True
    quality: int = 1
    sigma_pos_h_m: float | None = None
    sigma_pos_v_m: float | None = None
    sigma_vel_mps: float | None = None


def gnss_measurement_rows(cfg: FirmwareConfig, meter: c674x.CycleMeter, meas: GnssMeasurement,
                          p_ins: FloatArray, v_ins: FloatArray) -> list[tuple[int, float, float, float]]:
    """The scalar rows of a GNSS update: ``(state index, H value, z, R)`` per measured component.

    Position (Eq. 23-24): ``Z_p = [R_Mh dL, R_Nh cosL dlambda, dh]`` (m), ``H_p = [0 diag(R_Mh, R_Nh cosL, 1) 0]``,
    charging the residual's cycles on ``meter``; velocity (Eq. 28-30): ``Z_v = v_INS - v_GNSS`` (ENU m/s),
    ``H_v = [0 I 0]``, the vertical only when measured (UBX velD). ``p_ins`` = (lat rad, lon rad, h m) and
    ``v_ins`` (ENU m/s) are the INS at the fix's time of validity. Shared by every filter with GNSS updates.
    """
    rows: list[tuple[int, float, float, float]] = []
    if meas.pos is not None:
        lat = float(p_ins[0])
        rm, rn = earth.radii(lat)
        rmh, rnh = rm + float(p_ins[2]), rn + float(p_ins[2])
        cl = math.cos(lat)
        sh = meas.sigma_pos_h_m or cfg.gnss_pos_sigma_h_m
        sv = meas.sigma_pos_v_m or cfg.gnss_pos_sigma_v_m
        rows += [
            (D_LAT, rmh, (float(p_ins[0]) - meas.pos[0]) * rmh, sh**2),
            (D_LON, rnh * cl, (float(p_ins[1]) - meas.pos[1]) * rnh * cl, sh**2),
        ]
        if meas.pos_up:
            rows.append((D_H, 1.0, float(p_ins[2]) - meas.pos[2], sv**2))
        meter.charge("gnss_residual", c674x.dp_flops(8, 6) + c674x.mathlib("cosdp") + c674x.mathlib("sqrtdp")
                     + c674x.mathlib("divdp"))
    if meas.vel is not None:
        svh = meas.sigma_vel_mps or cfg.gnss_vel_sigma_h_mps
        rows.append((DV_E, 1.0, float(v_ins[0]) - float(meas.vel[0]), svh**2))
        rows.append((DV_N, 1.0, float(v_ins[1]) - float(meas.vel[1]), svh**2))
        if meas.vel_up:
            rows.append((DV_U, 1.0, float(v_ins[2]) - float(meas.vel[2]), cfg.gnss_vel_sigma_v_mps**2))
    return rows


@dataclass
class SolarObservation:
    """A bi-direction solar vector in the body frame at its mid-exposure time."""

    t_exposure_s: float
    s_b: FloatArray
    quality: float
    n_used: int
    source: str  # "camera" (firmware solve) or "sensor" (on-sensor solve)


@dataclass
class UpdateReport:
    """What a measurement update did (for counters, events and the status byte)."""

    kind: str
    accepted: bool
    n_rows: int = 0
    max_norm_innov: float = 0.0
    detail: dict[str, Any] | None = None


class FilterHost(Protocol):
    """What the main loop offers a variant (:class:`firmware_model.Firmware` implements it)."""

    def utc_days(self, t_fpga_s: float) -> float | None:
        """Grena days (UT) at FPGA time ``t_fpga_s``, once GNSS gave date and time (else None)."""

    def ins_at(self, t_meas: float) -> tuple[F64Array, FloatArray, FloatArray]:
        """INS position (lat, lon rad, h m; float64), ENU velocity and attitude quaternion ``q_b^n`` at ``t_meas``.

        Fresh arrays built from the INS history (docs/decisions.md D-10.F2)."""

    def mag_mean_nt(self, t_center_s: float, half_window_s: float = 0.025) -> tuple[FloatArray, int] | None:
        """Mean magnetometer field (nT, body axes) of the MAG frames sampled within ``t_center_s +- half_window_s``."""

    def now_s(self) -> float:
        """FPGA time of the current tick, s."""


class NavFilter:
    """Interface of a navigation filter variant (see module docstring).

    Attributes the loop reads: ``P`` (n, n) covariance whose first 9 states are
    ``[phi, dv, dL dlambda dh]`` (for the reported sigmas), ``gyro_bias`` (rad/s, body) and
    ``accel_bias`` (m/s^2, body) used to compensate the IMU increments, ``counters`` (merged into the
    firmware's counters).
    """

    name = "abstract"
    #: Variant number in NAV_SOLUTION ``mode`` bits 8-11 and STATUS (``protocols.host.FilterVariant``,
    #: docs/architecture.md numbering of the firmware variants); set by :func:`register_filter` from the variant's name.
    variant_id = 0
    #: True: POLARIZATION_OBS frames go to :meth:`update_polarization_obs` instead of the firmware's solve.
    raw_polarization_obs = False
    #: the rotation the gyros measured over the coming predict's interval: the sum of the absolute angle
    #: increments per body axis (rad), set by the loop before each :meth:`predict` (rotation-dependent noise)
    rotation_b_rad: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __init__(self, cfg: FirmwareConfig, meter: c674x.CycleMeter, dtype: FloatDtype) -> None:
        self.cfg = cfg
        self.meter = meter
        self.dtype = dtype
        self.gyro_bias = np.zeros(3, dtype=dtype)
        self.accel_bias = np.zeros(3, dtype=dtype)
        self.P = np.zeros((N_STATES, N_STATES), dtype=dtype)
        self.cost = c674x.KernelCosts("float64" if np.dtype(dtype) == np.float64 else "float32")
        self.host: FilterHost | None = None
        self.counters: dict[str, int] = {}
        #: innovation statistics per measurement type: ``{"rows": n, "nis_sum": sum of nu^2 / s}`` of every scalar
        #: row processed (accepted), for the consistency check (emulator/distributed/campaign/consistency.py)
        self.innovation_stats: dict[str, dict[str, float]] = {}

    def _count_nis(self, kind: str, norm_innov: float) -> None:
        """Add one scalar row's normalised innovation ``nu / sqrt(s)`` to :attr:`innovation_stats`."""
        st = self.innovation_stats.get(kind)
        if st is None:
            st = self.innovation_stats[kind] = {"rows": 0, "nis_sum": 0.0}
        st["rows"] += 1
        st["nis_sum"] += norm_innov * norm_innov

    def attach(self, host: FilterHost) -> None:
        """Called by the main loop once the filter exists (and again after a variant switch)."""
        self.host = host

    def drain_events(self) -> list[dict[str, Any]]:
        """Decision events since the last call (``[]`` for variants without a mode manager)."""
        return []

    def variant_status(self) -> tuple[int, int, int] | None:
        """``(variant_mode, psns_units, psns_q_mask)`` for NAV_SOLUTION / STATUS; None: no VARIANT block."""
        return None

    def update_polarization_obs(self, nav: NavState, frame: Any, t_exposure_s: float) -> UpdateReport | None:
        """Raw POLARIZATION_OBS frames (only for variants with ``raw_polarization_obs``)."""
        return None

    def initialise(self, nav: NavState, heading_sigma_rad: float) -> None:
        raise NotImplementedError

    def predict(self, nav: NavState, f_n: FloatArray, Tk: float) -> None:
        """Time update over ``Tk`` s; ``f_n``: mean specific force (m/s^2, n). The loop sets
        :attr:`rotation_b_rad` before the call."""
        raise NotImplementedError

    def update_gnss(self, nav: NavState, meas: GnssMeasurement, p_ins: FloatArray, v_ins: FloatArray) -> UpdateReport:
        raise NotImplementedError

    def update_solar(self, nav: NavState, obs: SolarObservation, s_n: FloatArray, cbn_exp: FloatArray) -> UpdateReport:
        raise NotImplementedError

    def update_compass(self, nav: NavState, frame: Any, t_exposure_s: float) -> UpdateReport | None:
        """Multi-unit compass frames: not used by the base variant (the compass variants use them)."""
        return None

    def feedback(self, nav: NavState) -> None:
        raise NotImplementedError


_FilterClass = TypeVar("_FilterClass", bound=type[NavFilter])


def register_filter(name: str) -> Callable[[_FilterClass], _FilterClass]:
    """Class decorator: make a :class:`NavFilter` selectable as ``firmware.filter: name`` (enters it in the
    build's table :data:`firmware_model.config.FILTER_VARIANTS`)."""

    def deco(cls: _FilterClass) -> _FilterClass:
        cls.name = name
        if name in FILTER_VARIANT_NAMES:  # the host protocol's variant number (STATUS, SELECT_VARIANT)
            cls.variant_id = int(FILTER_VARIANT_NAMES[name])
        FILTER_VARIANTS[name] = cls
        return cls

    return deco


@register_filter("base")
class BaseFilter(NavFilter):
    """Bi-direction solar-vector 15-state KF (base paper): GNSS position/velocity + ``+-S`` updates."""

    #: augmented states this variant carries when the configuration asks for them (docs/decisions/
    #: filter-consistency.md): 3 GNSS position errors (E, N, U m, Gauss-Markov) and 3 solar-vector biases (body rad)
    augmentable = True

    def __init__(self, cfg: FirmwareConfig, meter: c674x.CycleMeter, dtype: FloatDtype) -> None:
        super().__init__(cfg, meter, dtype)
        n = N_STATES
        #: first index of the GNSS position-error states (E, N, U, m) and of the solar-vector bias states (body x, y,
        #: z, rad), or None when the variant or the configuration has none (layout: firmware_model/kf.py + these)
        self.i_gnss: int | None = None
        self.i_sun: int | None = None
        if self.augmentable and cfg.gnss_error_states:
            self.i_gnss, n = n, n + 3
        if self.augmentable and cfg.psns_bias_states and cfg.psns_enabled:
            self.i_sun, n = n, n + 3
        self.n = n
        self.x = np.zeros(n, dtype=dtype)
        self.P = np.zeros((n, n), dtype=dtype)
        arw = cfg.gyro_arw_deg_rt_h * DEG / 60.0
        vrw = cfg.accel_noise_ug_rt_hz * 1e-6 * G_STD
        qg = 2.0 * (cfg.gyro_bias_instability_deg_h * DPH) ** 2 / cfg.bias_corr_time_s
        qa = 2.0 * (cfg.accel_bias_instability_mg * 1e-3 * G_STD) ** 2 / cfg.accel_bias_corr_time_s
        q = np.zeros(n)
        q[:N_STATES] = process_noise_psd(arw, vrw, qg, qa)
        # the bias instability is flicker noise (Allan floor 0.664 B from ~1 s up to the correlation time): over the
        # seconds the GNSS velocity needs to see a bias, it moves as much as over minutes, which the random walk above
        # (matched at tau) does not; its white-noise equivalent whose Allan deviation touches the floor at the
        # velocity-aiding time constant (sigma_A^2 = N^2 / T) is added to the attitude and velocity rows (D-5.15)
        self._t_flicker = self._flicker_match_s()
        q[IDX_ATT] += self._flicker_white_psd(self._flicker_b_gyro())
        q[IDX_VEL] += self._flicker_white_psd(self._flicker_b_accel())
        #: Gauss-Markov decay rates (1/s) of the augmented states, on F's diagonal
        self._aug_rate = np.zeros(n)
        if self.i_gnss is not None:
            sc_h, sc_v = self._gnss_corr_sigmas()
            tau = cfg.gnss_pos_corr_time_s
            q[self.i_gnss:self.i_gnss + 3] = (2.0 * sc_h**2 / tau, 2.0 * sc_h**2 / tau, 2.0 * sc_v**2 / tau)
            self._aug_rate[self.i_gnss:self.i_gnss + 3] = 1.0 / tau
        if self.i_sun is not None:
            tau = cfg.psns_bias_corr_time_s
            q[self.i_sun:self.i_sun + 3] = 2.0 * (cfg.psns_bias_sigma_deg * DEG) ** 2 / tau
            self._aug_rate[self.i_sun:self.i_sun + 3] = 1.0 / tau
        self.q = q
        #: rotation-dependent attitude noise (see _rotation_noise): variances per radian, scale factor, misalignment
        self._rot_var_sf = (cfg.gyro_scale_factor_ppm * 1e-6) ** 2
        self._rot_var_mis = (cfg.gyro_misalignment_mrad * 1e-3) ** 2
        self._rot_var = self._rot_var_sf + self._rot_var_mis
        #: solar-vector bias (D-5.16): isotropic camera-mount variance, the sky's variance (rad^2 per axis across the
        #: sun, put into the elevation axis), and the horizontal n-frame axis across the solar meridian (z x s_n,
        #: from the last solar update; None until the first)
        sky2 = (cfg.psns_sky_bias_deg * DEG) ** 2
        self._mu_sky2 = sky2 if self.i_sun is not None else 0.0
        self._mu_iso2 = max((cfg.psns_bias_sigma_deg * DEG) ** 2 - sky2, 0.0)
        self._sun_axis_n: F64Array | None = None
        #: FPGA time of the last GNSS position fix (s), for the loss-of-lock re-draw of the GNSS error states
        self._t_last_fix: float | None = None
        self._eye = np.eye(n, dtype=dtype)
        self._qk_interval, self._qk = math.nan, self.q  # Q_k of the last KF interval (predict)
        self._cyc_update = kf_scalar_update_cycles(self.cost, n)
        self._cyc_predict = kf_predict_cycles(self.cost, n)
        self._cyc_feedback = feedback_cycles(self.cost)

    def _flicker_b_gyro(self) -> float:
        """Gyro bias instability B (rad/s) for the flicker term: at most the gyro bias's total sigma (the in-run part
        of a bias cannot move more than the bias itself; a configuration that says otherwise is read as the smaller)."""
        return min(self.cfg.gyro_bias_instability_deg_h, self.cfg.gyro_bias_sigma_deg_h) * DPH

    def _flicker_b_accel(self) -> float:
        """Accelerometer bias instability B (m/s^2) for the flicker term, at most the bias's total sigma."""
        return min(self.cfg.accel_bias_instability_mg, self.cfg.accel_bias_sigma_mg) * 1e-3 * G_STD

    def _flicker_match_s(self) -> float:
        """The time (s) over which the filter's velocity estimate averages the GNSS velocity when its process noise
        is the flicker's white equivalent matched at that same time: a random walk of PSD ``q`` seen through
        measurements of variance ``r`` every ``D`` s is averaged over ``T = sqrt(r D / q)``; with
        ``q = (0.664 B_a)^2 T`` this gives ``T = (r D / (0.664 B_a)^2)^(1/3)`` (paper accelerometers: 3.3 s; field:
        32 s), bounded to [D, accelerometer correlation time]. D-5.15."""
        cfg = self.cfg
        floor = _ALLAN_FLOOR * max(self._flicker_b_accel(), 1e-8)
        t = (cfg.gnss_vel_sigma_h_mps**2 * _VEL_AID_INTERVAL_S / floor**2) ** (1.0 / 3.0)
        return float(min(max(t, _VEL_AID_INTERVAL_S), cfg.accel_bias_corr_time_s))

    def _flicker_white_psd(self, b: float) -> float:
        """White-noise PSD (unit^2 s) whose Allan variance ``N^2 / T`` equals the flicker floor ``(0.664 B)^2`` at
        the matching time ``T`` (:meth:`_flicker_match_s`): ``N^2 = (0.664 B)^2 T`` (B in rad/s or m/s^2)."""
        return (_ALLAN_FLOOR * b) ** 2 * self._t_flicker

    def _gnss_corr_sigmas(self) -> tuple[float, float]:
        """Sigmas (m, horizontal per axis and vertical) of the time-correlated GNSS position error: the spec's
        total less its white part, in quadrature."""
        cfg = self.cfg
        h = math.sqrt(max(cfg.gnss_pos_sigma_h_m**2 - cfg.gnss_pos_white_sigma_h_m**2, 0.0))
        v = math.sqrt(max(cfg.gnss_pos_sigma_v_m**2 - cfg.gnss_pos_white_sigma_v_m**2, 0.0))
        return h, v

    # -- initialisation -------------------------------------------------------------------------
    def initialise(self, nav: NavState, heading_sigma_rad: float) -> None:
        """P0 from the spec sheet (:mod:`firmware_model.spec_sheet`): level from the accelerometer bias (correlated
        with the bias states), heading from the alignment, position from the first fix (its correlated error shared
        with the GNSS-error states)."""
        cfg = self.cfg
        n = self.n
        lat, h = float(nav.pos[0]), float(nav.pos[2])
        rm, rn = earth.radii(lat)
        rmh, rnh_cl = rm + h, (rn + h) * math.cos(lat)
        P = np.zeros((n, n))
        p0 = np.zeros(n)
        sig_acc = cfg.accel_bias_sigma_mg * 1e-3 * G_STD  # m/s^2, per body axis
        # the level comes from the accelerometers averaged over the coarse alignment: its error is the bias (below)
        # plus the averaged white noise (VRW / sqrt(T_align)), rad
        # (the accelerometer white noise and the white equivalent of its flicker bias, D-5.15)
        vrw2 = (cfg.accel_noise_ug_rt_hz * 1e-6 * G_STD) ** 2
        vrw2 += self._flicker_white_psd(self._flicker_b_accel())
        lvl_noise = math.sqrt(vrw2 / max(cfg.align_time_s, 0.1)) / G_STD
        p0[IDX_ATT] = (lvl_noise**2, lvl_noise**2, heading_sigma_rad**2)
        p0[IDX_VEL] = 0.1**2
        p0[IDX_POS] = ((cfg.gnss_pos_sigma_h_m / rmh) ** 2, (cfg.gnss_pos_sigma_h_m / rnh_cl) ** 2,
                       cfg.gnss_pos_sigma_v_m**2)
        p0[IDX_GYRO] = (cfg.gyro_bias_sigma_deg_h * DPH) ** 2
        p0[IDX_ACC] = sig_acc**2
        if self.i_gnss is not None:
            # the position comes from a fix: dp = b + w, so cov(dp, b) = var(b) (per axis, in the states' units)
            sc_h, sc_v = self._gnss_corr_sigmas()
            i = self.i_gnss
            p0[i:i + 3] = (sc_h**2, sc_h**2, sc_v**2)
            for pos_idx, b_idx, scale in ((D_LON, i, 1.0 / rnh_cl), (D_LAT, i + 1, 1.0 / rmh), (D_H, i + 2, 1.0)):
                P[pos_idx, b_idx] = P[b_idx, pos_idx] = p0[b_idx] * scale
        if self.i_sun is not None:
            p0[self.i_sun:self.i_sun + 3] = (cfg.psns_bias_sigma_deg * DEG) ** 2
        P[np.diag_indices(n)] = p0
        # Levelling leaves the tilt error that cancels the accelerometer bias in the horizontal specific force
        # (velocity error equation dv' = f^n x phi + C_b^n nabla with f^n = (0, 0, g)): phi_E = -nabla^n_N / g,
        # phi_N = nabla^n_E / g. The two are one error, so P0 carries it once, as phi_level = A nabla^b with
        # A = [[0, -1, 0], [1, 0, 0]] C_b^n[:, :] / g: cov(phi, phi) += A P_nabla A^T, cov(phi, nabla) = A P_nabla.
        # Independent priors would count the bias twice and halve the level variance after the first fixes
        # (Groves, Principles of GNSS, Inertial, and Multisensor Integrated Navigation Systems, 2nd ed., 14.2.1).
        cbn = q2mat_fast(nav.q).astype(np.float64)
        a = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 0.0]]) @ cbn / G_STD
        p_acc = sig_acc**2 * a
        P[IDX_ATT, IDX_ATT] += p_acc @ a.T
        P[IDX_ATT, IDX_ACC] = p_acc
        P[IDX_ACC, IDX_ATT] = p_acc.T
        self.P = P.astype(self.dtype)
        self.x = np.zeros(n, dtype=self.dtype)
        self._sun_axis_n = None
        self._t_last_fix = None

    # -- time update --------------------------------------------------------------------------
    def predict(self, nav: NavState, f_n: FloatArray, Tk: float) -> None:
        dt = self.dtype
        F15 = error_transition_matrix(q2mat_fast(nav.q), nav.v, nav.pos, f_n, dtype=dt)
        if self.n > N_STATES:  # augmented states: first-order Gauss-Markov, no coupling into the navigation errors
            F = np.zeros((self.n, self.n), dtype=dt)
            F[:N_STATES, :N_STATES] = F15
            F[np.diag_indices(self.n)] -= self._aug_rate.astype(dt)
        else:
            F = F15
        Phi = self._eye + F * dt(Tk)
        if Tk != self._qk_interval:  # Q_k = q T_k: the same every interval but the first after alignment
            self._qk_interval, self._qk = Tk, (self.q * Tk).astype(dt)
        rot_b = self.rotation_b_rad
        qk: FloatArray = self._qk
        if self._rot_var > 0.0 and any(rot_b):
            qk = self._rotation_noise(nav, rot_b, qk)
        if self._sun_axis_n is not None and self._mu_sky2 > 0.0:
            qk = self._sun_bias_noise(nav, qk, Tk)
        self.x, self.P = kf_predict(self.x, self.P, Phi, qk)
        self.meter.charge("kf_predict", self._cyc_predict)

    def _mu_cov(self) -> F64Array:
        """Covariance (rad^2, local-level frame) of the solar-vector bias: the spec sheet's isotropic figure (mount
        and sky, ``m^2 + s^2`` per axis) plus the sky's again on the axis across the solar meridian, along which the
        turbid sky's departure from the Rayleigh pattern shifts the solved sun (D-5.16):
        ``(m^2 + s^2) I + s^2 u u^T``, ``u = z x S^n / |z x S^n|``."""
        u = self._sun_axis_n
        assert u is not None
        return (self._mu_iso2 + self._mu_sky2) * np.eye(3) + self._mu_sky2 * np.outer(u, u)

    def _sun_bias_noise(self, nav: NavState, qk: FloatArray, Tk: float) -> FloatArray:
        """Q_k of the solar-vector bias states, ``2 T_k / tau`` times :meth:`_mu_cov` (the Gauss-Markov's stationary
        covariance, its direction following the body's turns), in place of the isotropic diagonal."""
        assert self.i_sun is not None
        i = self.i_sun
        q = np.diag(qk.astype(np.float64)) if qk.ndim == 1 else qk.astype(np.float64, copy=True)
        q[i:i + 3, i:i + 3] = (2.0 * Tk / self.cfg.psns_bias_corr_time_s) * self._mu_cov()
        self.meter.charge("kf_sun_bias_noise", c674x.flops(9, 6) + c674x.CALL_OVERHEAD)
        return q.astype(self.dtype)

    def _rotation_noise(self, nav: NavState, rot_b: tuple[float, float, float], qk_in: FloatArray) -> FloatArray:
        """Q_k with the attitude noise the gyros' scale-factor error s and misalignment m add while the body turns.

        A rotation ``theta_i`` about body axis i leaves ``s theta_i`` about that axis and ``m theta_i`` about each of
        the other two; the filter has no states for them (a consider approach: Groves 2013, section 14.2.7). The
        error of one manoeuvre is coherent (a 90 deg turn with m = 0.33 mrad tilts the level by 0.03 deg), while the
        white noise of Q adds in quadrature; the variance added per interval is therefore ``sigma^2 theta_i
        THETA_REF`` (``THETA_REF`` = 90 deg): over one turn of 90 deg it sums to ``(sigma * 90 deg)^2``, the turn's
        coherent error, and over several turns it grows with the total angle, as errors of alternating turns do.
        Body variances ``s^2 t_i + m^2 (t_j + t_k)`` (times ``THETA_REF``), rotated to n: ``C_b^n diag C_b^n^T``.
        """
        s2, m2 = self._rot_var_sf, self._rot_var_mis
        tx, ty, tz = (abs(float(v)) for v in rot_b)
        var_b = np.array([s2 * tx + m2 * (ty + tz), s2 * ty + m2 * (tx + tz), s2 * tz + m2 * (tx + ty)])
        var_b *= _THETA_REF_RAD
        cbn = q2mat_fast(nav.q).astype(np.float64)
        qk_att = (cbn * var_b) @ cbn.T
        qk = np.diag(qk_in.astype(np.float64)) if qk_in.ndim == 1 else qk_in.astype(np.float64, copy=True)
        qk[IDX_ATT, IDX_ATT] += qk_att
        self.meter.charge("kf_rotation_noise", c674x.flops(45, 36) + c674x.CALL_OVERHEAD)
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
        """After a loss of lock (no position fix for more than ``gnss_relock_gap_s``) the receiver's correlated error is
        a fresh draw (D-5.17): the GNSS error states restart from zero with their stationary variance and no
        correlation with the navigation errors. Without this, the Gauss-Markov keeps ``exp(-gap / tau)`` of its
        pre-outage estimate and correlation, and the filter puts the re-acquisition jump into position and vertical
        velocity."""
        gap, last = self.cfg.gnss_relock_gap_s, self._t_last_fix
        self._t_last_fix = t_fix
        if self.i_gnss is None or gap <= 0.0 or last is None or t_fix - last <= gap:
            return
        i = self.i_gnss
        sc_h, sc_v = self._gnss_corr_sigmas()
        self.x[i:i + 3] = 0.0
        self.P[i:i + 3, :] = 0.0
        self.P[:, i:i + 3] = 0.0
        self.P[i:i + 3, i:i + 3] = np.diag([sc_h**2, sc_h**2, sc_v**2]).astype(self.dtype)
        self.counters["gnss_relock_redraws"] = self.counters.get("gnss_relock_redraws", 0) + 1
        self.meter.charge("gnss_relock", self.cost.flops(0, 6 * self.n))

    def update_gnss(self, nav: NavState, meas: GnssMeasurement, p_ins: FloatArray, v_ins: FloatArray) -> UpdateReport:
        dt = self.dtype
        if meas.pos is not None:
            self._gnss_relock(meas.t_fpga_s)
        rows = gnss_measurement_rows(self.cfg, self.meter, meas, p_ins, v_ins)
        innov = []
        h = np.zeros(self.n, dtype=dt)
        gated = 0
        cfg = self.cfg
        for idx, hval, z, r in rows:
            h[:] = 0
            h[idx] = hval
            kind = "gnss_position" if idx in (D_LAT, D_LON, D_H) else "gnss_velocity"
            if self.i_gnss is not None and kind == "gnss_position":
                # z = p_INS - p_GNSS = dp - b: the correlated error is a state, R only its white part
                h[self.i_gnss + {D_LON: 0, D_LAT: 1, D_H: 2}[idx]] = -1.0
                r = (cfg.gnss_pos_white_sigma_v_m if idx == D_H else cfg.gnss_pos_white_sigma_h_m) ** 2
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
        if self._mu_sky2 > 0.0:
            self._set_sun_axis(s_n)
        H = solar_vector_rows(s_n, dt, self.n)
        if self.i_sun is not None:
            if self._mu_sky2 > 0.0:
                # the bias in the local-level frame, where the sky's error stays in the solar meridian whatever the
                # body does (D-5.16): S^n measured = (I + [mu x]) S^n, Z = -[S^n x] phi + [S^n x] mu
                H[:, self.i_sun:self.i_sun + 3] = -H[:, IDX_ATT]
            else:
                # s_b measured = (I + [mu x]) s_b: Z = -[S^n x] phi + [S^n x] C_b^n mu
                # (docs/decisions/filter-consistency.md)
                H[:, self.i_sun:self.i_sun + 3] = -H[:, IDX_ATT] @ cbn_exp.astype(dt)
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
        for nu in innov:
            self._count_nis("solar_vector", nu)
        self.meter.charge("kf_update", 3 * self._cyc_update)
        return UpdateReport("solar", True, 3, max(abs(v) for v in innov),
                            {"residual_deg": math.sqrt(z2) / DEG, "sign": sign})

    def _set_sun_axis(self, s_n: FloatArray) -> None:
        """Keep the n-frame axis across the solar meridian (D-5.16); at the first solar update, give the bias states
        their prior in that shape (until then they are uncorrelated with every other state, so this is the P0 the
        filter would have set knowing the sun)."""
        e, nn = float(s_n[0]), float(s_n[1])
        norm = math.hypot(e, nn)
        if norm < 1e-3:  # sun at the zenith: no meridian
            return
        first = self._sun_axis_n is None
        self._sun_axis_n = np.array([-nn / norm, e / norm, 0.0])
        if first and self.i_sun is not None:
            i = self.i_sun
            self.P[i:i + 3, i:i + 3] = self._mu_cov().astype(self.dtype)
        self.meter.charge("solar_bias_axis", self.cost.flops(4, 2) + self.cost.math("rsqrt"))

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
