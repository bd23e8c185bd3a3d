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
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, ClassVar, Protocol, TypeVar

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
#: a first-order Gauss-Markov of sigma s and correlation time c has the Allan variance
#: ``s^2 (c / T)^2 (2 x - 3 + 4 exp(-x) - exp(-2 x))``, ``x = T / c`` (from its autocorrelation ``s^2 exp(-|t| / c)``);
#: its Allan deviation peaks at ``T = GM_ALLAN_PEAK_X c`` with the value ``GM_ALLAN_PEAK s`` (the root of its
#: derivative, to 5 digits; tests/firmware_model/test_spec_sheet.py checks both against the formula)
GM_ALLAN_PEAK_X = 1.8928
GM_ALLAN_PEAK = 0.61736

__all__ = [
    "FILTER_VARIANTS",
    "SOLAR_VECTOR_DOF",
    "BaseFilter",
    "FilterHost",
    "GnssMeasurement",
    "GyroFlickerStates",
    "NavFilter",
    "SolarObservation",
    "UpdateReport",
    "feedback_cycles",
    "gnss_dop_scale",
    "gnss_fix_scale",
    "gnss_measurement_rows",
    "gyro_bias_walk_psd",
    "gyro_flicker_band",
    "kf_predict_cycles",
    "kf_scalar_update_cycles",
    "register_filter",
    "solar_fix_nis",
    "warmup_gyro_bias_variance",
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


#: degrees of freedom of one solar-vector fix: the residual of two unit vectors ``Z = S^n - C_b^{n'} S^b`` has no
#: first-order part along ``S^n`` (``(S^n)^T [S^n x] = 0``), so its three rows carry two (D-5.32)
SOLAR_VECTOR_DOF = 2


def solar_fix_nis(norm_innovs: Sequence[float], z_along_sun: float, r: float) -> float:
    """NIS of one solar-vector fix in the plane across the sun (``SOLAR_VECTOR_DOF`` = 2 dof; D-5.32) from its three
    sequential scalar rows of noise ``r`` (rad^2 each, ``R = r I``).

    The rows' normalised innovations ``nu_i / sqrt(s_i)`` sum in squares to ``nu^T S^-1 nu`` with
    ``S = H P H^T + r I`` (sequential scalar updates with a diagonal R). Every row of ``H`` is orthogonal to ``S^n``
    (the attitude columns ``-[S^n x]``, the solar-bias columns ``[S^n x]`` or ``[S^n x] C_b^n``), so ``S S^n = r S^n``
    and the NIS splits into the part along the sun, ``(nu . S^n)^2 / r = (Z . S^n)^2 / r``, and the part across it,
    chi-square with 2 dof for a consistent filter. The part along the sun is no noise: for unit vectors
    ``Z . S^n = 1 - cos(err)`` is second order in the angle ``err`` between them (1 deg between the two vectors gives
    a NIS of 3 along the sun at ``r`` = (0.005 deg)^2, the ``field`` sheet's floor), and it changes no state
    (``H^T S^n = 0``). Returns ``sum (nu_i^2 / s_i) - (Z . S^n)^2 / r`` (>= 0)."""
    total = math.fsum(v * v for v in norm_innovs)
    along = z_along_sun * z_along_sun / r if r > 0.0 else 0.0
    return max(total - along, 0.0)


def flicker_b_gyro(cfg: FirmwareConfig) -> float:
    """Gyro bias instability B (rad/s) for the flicker term: at most the gyro bias's total sigma (the in-run part
    of a bias cannot move more than the bias itself; a configuration that says otherwise is read as the smaller)."""
    return min(cfg.gyro_bias_instability_deg_h, cfg.gyro_bias_sigma_deg_h) * DPH


def flicker_b_accel(cfg: FirmwareConfig) -> float:
    """Accelerometer bias instability B (m/s^2) for the flicker term, at most the bias's total sigma."""
    return min(cfg.accel_bias_instability_mg, cfg.accel_bias_sigma_mg) * 1e-3 * G_STD


def flicker_match_s(cfg: FirmwareConfig, vertical: bool = False) -> float:
    """The time (s) over which the filter's velocity estimate averages the GNSS velocity when its process noise
    is the flicker's white equivalent matched at that same time: a random walk of PSD ``q`` seen through
    measurements of variance ``r`` every ``D`` s is averaged over ``T = sqrt(r D / q)``; with
    ``q = (0.664 B_a)^2 T`` this gives ``T = (r D / (0.664 B_a)^2)^(1/3)`` (paper accelerometers: 3.3 s horizontal,
    5.1 s vertical; field: 32 s), bounded to [D, accelerometer correlation time]. D-5.15; per velocity row with that
    row's GNSS velocity figure, ``r`` horizontal or (``vertical``) vertical, D-5.25: the vertical velocity, aided by a
    velocity twice as noisy, averages longer and sees more of the flicker."""
    floor = _ALLAN_FLOOR * max(flicker_b_accel(cfg), 1e-8)
    sig = cfg.gnss_vel_sigma_v_mps if vertical else cfg.gnss_vel_sigma_h_mps
    t = (sig**2 * _VEL_AID_INTERVAL_S / floor**2) ** (1.0 / 3.0)
    return float(min(max(t, _VEL_AID_INTERVAL_S), cfg.accel_bias_corr_time_s))


def flicker_white_psd(cfg: FirmwareConfig, b: float, vertical: bool = False) -> float:
    """White-noise PSD (unit^2 s) whose Allan variance ``N^2 / T`` equals the flicker floor ``(0.664 B)^2`` at
    the matching time ``T`` (:func:`flicker_match_s`, the horizontal or the ``vertical`` velocity row's):
    ``N^2 = (0.664 B)^2 T`` (B in rad/s or m/s^2)."""
    return (_ALLAN_FLOOR * b) ** 2 * flicker_match_s(cfg, vertical)


def gyro_bias_walk_psd(cfg: FirmwareConfig) -> float:
    """PSD ((rad/s)^2/s) of the gyro bias's random walk matched to the in-run Gauss-Markov of the sheet's bias
    instability B and correlation time tau: ``q = 2 B^2 / tau`` (D-5.11)."""
    return 2.0 * (cfg.gyro_bias_instability_deg_h * DPH) ** 2 / cfg.bias_corr_time_s


def gyro_flicker_band(cfg: FirmwareConfig) -> tuple[float, float]:
    """Correlation time (s) and sigma (rad/s) of the Gauss-Markov that carries the gyro flicker's middle band (D-5.28),
    from the spec sheet's bias instability B, its correlation time tau and the white equivalent's matching time
    ``T_w`` (:func:`flicker_match_s`) alone.

    The flicker's Allan deviation is flat at ``0.664 B`` from ``T_w`` to ``tau``. The 15-state model covers the two
    ends: the bias random walk ``q = 2 B^2 / tau`` (Allan variance ``q T / 3``, D-5.11) near ``tau`` and the white
    equivalent ``N^2 = (0.664 B)^2 T_w`` (Allan variance ``N^2 / T``, D-5.15) at ``T_w``. Their sum is lowest at
    ``T* = sqrt(3 N^2 / q) = 0.664 sqrt(1.5 T_w tau)`` with the value ``2 q T* / 3`` (default sheet: T* = 36 s, 0.43
    of the floor in deviation). A Gauss-Markov of correlation time ``c = T* / 1.8928`` peaks there; its sigma fills
    the gap to the floor at ``T*``: ``s^2 = ((0.664 B)^2 - 2 q T* / 3) / 0.61736^2``. Returns ``(c, 0)`` when the sum
    already reaches the floor (no gap: ``T_w`` near ``tau``). Default sheet: c = 19 s, s = 0.97 B; field: 146 s,
    0.94 B."""
    b = flicker_b_gyro(cfg)
    tau = cfg.bias_corr_time_s
    floor2 = (_ALLAN_FLOOR * b) ** 2
    q = gyro_bias_walk_psd(cfg)
    n2 = flicker_white_psd(cfg, b)
    if q <= 0.0 or n2 <= 0.0:
        return tau, 0.0
    t_star = math.sqrt(3.0 * n2 / q)
    gap = floor2 - 2.0 * q * t_star / 3.0
    return t_star / GM_ALLAN_PEAK_X, math.sqrt(max(gap, 0.0)) / GM_ALLAN_PEAK


def spec_process_noise(cfg: FirmwareConfig) -> F64Array:
    """Continuous process-noise PSD ``q`` (15,) of the 15-state model (Eq. 48) from the spec sheet: ARW^2 and VRW^2,
    the bias random walks matched to the in-run Gauss-Markov (``q = 2 B^2 / tau``, D-5.11), and the flicker's white
    equivalent on the attitude and velocity rows (D-5.15). Shared by every filter with the 15-state model (the base
    filter, the federated sub-filters)."""
    arw = cfg.gyro_arw_deg_rt_h * DEG / 60.0
    vrw = cfg.accel_noise_ug_rt_hz * 1e-6 * G_STD
    qg = gyro_bias_walk_psd(cfg)
    qa = 2.0 * (cfg.accel_bias_instability_mg * 1e-3 * G_STD) ** 2 / cfg.accel_bias_corr_time_s
    q = np.asarray(process_noise_psd(arw, vrw, qg, qa), dtype=np.float64)
    # the bias instability is flicker noise (Allan floor 0.664 B from ~1 s up to the correlation time): over the
    # seconds the GNSS velocity needs to see a bias, it moves as much as over minutes, which the random walk above
    # (matched at tau) does not; its white-noise equivalent whose Allan deviation touches the floor at the
    # velocity-aiding time constant (sigma_A^2 = N^2 / T) is added to the attitude and velocity rows (D-5.15)
    q[IDX_ATT] += flicker_white_psd(cfg, flicker_b_gyro(cfg))
    # (per velocity row: the vertical velocity averages its noisier GNSS velocity over a longer time, D-5.25)
    b_a = flicker_b_accel(cfg)
    q[DV_E] += flicker_white_psd(cfg, b_a)
    q[DV_N] += flicker_white_psd(cfg, b_a)
    q[DV_U] += flicker_white_psd(cfg, b_a, vertical=True)
    return q


def spec_initial_covariance(cfg: FirmwareConfig, nav: NavState, heading_sigma_rad: float) -> F64Array:
    """P0 (15, 15) of the 15-state model from the spec sheet: level from the accelerometer bias (correlated with the
    bias states, D-5.14) plus the averaged white noise, heading from the alignment, velocity 0.1 m/s, position from the
    first fix's total sigma, the biases' stationary sigmas (D-5.11). Shared by the base filter and the federated
    sub-filters."""
    lat, h = float(nav.pos[0]), float(nav.pos[2])
    rm, rn = earth.radii(lat)
    rmh, rnh_cl = rm + h, (rn + h) * math.cos(lat)
    sig_acc = cfg.accel_bias_sigma_mg * 1e-3 * G_STD  # m/s^2, per body axis
    # the level comes from the accelerometers averaged over the coarse alignment: its error is the bias (below)
    # plus the averaged white noise (VRW / sqrt(T_align)), rad
    # (the accelerometer white noise and the white equivalent of its flicker bias, D-5.15)
    vrw2 = (cfg.accel_noise_ug_rt_hz * 1e-6 * G_STD) ** 2
    vrw2 += flicker_white_psd(cfg, flicker_b_accel(cfg))
    lvl_noise = math.sqrt(vrw2 / max(cfg.align_time_s, 0.1)) / G_STD
    p0 = np.zeros(N_STATES)
    p0[IDX_ATT] = (lvl_noise**2, lvl_noise**2, heading_sigma_rad**2)
    p0[IDX_VEL] = 0.1**2
    p0[IDX_POS] = ((cfg.gnss_pos_sigma_h_m / rmh) ** 2, (cfg.gnss_pos_sigma_h_m / rnh_cl) ** 2,
                   cfg.gnss_pos_sigma_v_m**2)
    p0[IDX_GYRO] = (cfg.gyro_bias_sigma_deg_h * DPH) ** 2
    p0[IDX_ACC] = sig_acc**2
    P = np.diag(p0)
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
    return P


def rotation_attitude_noise(cfg: FirmwareConfig, cbn: FloatArray, rot_b: tuple[float, float, float]) -> F64Array:
    """Attitude noise (3, 3, rad^2, n frame) the gyros' scale-factor error s and misalignment m add over an interval
    in which the body turned ``rot_b`` (rad per body axis, absolute), D-5.14.

    A rotation ``theta_i`` about body axis i leaves ``s theta_i`` about that axis and ``m theta_i`` about each of
    the other two; the filters have no states for them (a consider approach: Groves 2013, section 14.2.7). The
    error of one manoeuvre is coherent (a 90 deg turn with m = 0.33 mrad tilts the level by 0.03 deg), while the
    white noise of Q adds in quadrature; the variance added per interval is therefore ``sigma^2 theta_i
    THETA_REF`` (``THETA_REF`` = 90 deg): over one turn of 90 deg it sums to ``(sigma * 90 deg)^2``, the turn's
    coherent error, and over several turns it grows with the total angle, as errors of alternating turns do.
    Body variances ``s^2 t_i + m^2 (t_j + t_k)`` (times ``THETA_REF``), rotated to n: ``C_b^n diag C_b^n^T``.
    Cost: :data:`ROTATION_NOISE_FLOPS` (charged by the caller as ``kf_rotation_noise``)."""
    s2 = (cfg.gyro_scale_factor_ppm * 1e-6) ** 2
    m2 = (cfg.gyro_misalignment_mrad * 1e-3) ** 2
    tx, ty, tz = (abs(float(v)) for v in rot_b)
    var_b = np.array([s2 * tx + m2 * (ty + tz), s2 * ty + m2 * (tx + tz), s2 * tz + m2 * (tx + ty)])
    var_b *= _THETA_REF_RAD
    c = np.asarray(cbn, dtype=np.float64)
    return np.asarray((c * var_b) @ c.T, dtype=np.float64)


def warmup_gyro_bias_variance(cfg: FirmwareConfig, t0_s: float, tk_s: float) -> float:
    """Variance ((rad/s)^2 per body axis) by which the gyro bias changes over the KF interval ``[t0, t0 + T_k]`` (s
    since power-on) as the box warms up (D-5.27): the bias the temperature gradient drives, ``b_T`` (sigma
    ``gyro_temp_gradient_deg_h``, in P0 as a turn-on bias), follows the gradient, which after power-on decays with
    the box's warm-up time constant ``tau`` (``gyro_temp_gradient_time_s``): ``b_T(t) = b_T(0) exp(-t / tau)``.
    Over the interval it moves by ``b_T(0) d`` with ``d = exp(-t0 / tau) - exp(-(t0 + T_k) / tau)``. The change is
    coherent (one unknown ``b_T(0)``), so as for the turns' noise (D-5.14) the variance added per interval is
    ``sigma^2 d`` (not ``sigma^2 d^2``): summed over the warm-up it is ``sigma^2``, the whole change's variance. Zero
    without a warm-up figure. Cost: one ``expdp`` and four flops per KF interval (charged by the caller as
    ``kf_warmup_noise``: ``exp(-t0 / tau)`` is the previous interval's end value)."""
    tau = cfg.gyro_temp_gradient_time_s
    sig = cfg.gyro_temp_gradient_deg_h * DPH
    if tau <= 0.0 or sig <= 0.0 or tk_s <= 0.0:
        return 0.0
    d = math.exp(-max(t0_s, 0.0) / tau) * -math.expm1(-tk_s / tau)
    return sig * sig * d


#: cycles of :func:`warmup_gyro_bias_variance` per KF interval
WARMUP_NOISE_CYCLES = c674x.mathlib("expdp") + c674x.flops(3, 1) + c674x.CALL_OVERHEAD


def _full_q(qk: FloatArray) -> F64Array:
    """``Q_k`` as a full float64 matrix that may be modified in place: the diagonal (n,) expanded, a full (n, n)
    copied (the predict's extra noise terms add blocks to it)."""
    return np.diag(qk.astype(np.float64)) if qk.ndim == 1 else qk.astype(np.float64, copy=True)


#: multiplies and adds of :func:`rotation_attitude_noise` (6 + 9 x 3 for C diag C^T, the 12 body variances)
ROTATION_NOISE_FLOPS = (45, 36)


def gnss_dop_scale(cfg: FirmwareConfig, hdop: float | None) -> float:
    """The factor (>= 1) on the GNSS sigmas of a fix whose receiver reports ``hdop`` (D-5.42): ``sigma = DOP x
    UERE`` (Kaplan & Hegarty 2017, ch. 7), so a geometry worse than the one the sheet's figures hold at
    (``cfg.gnss_hdop_ref``) widens position and velocity alike: ``max(1, hdop / hdop_ref)``. The sheet's figures are
    the floor: a better geometry never narrows them. 1 without a reference or without a usable HDOP (a NAV-PVT-only
    stream, an empty field). Cost: one ``divsp`` per fix, charged by the caller."""
    ref = cfg.gnss_hdop_ref
    if ref <= 0.0 or hdop is None or not math.isfinite(hdop) or hdop <= 0.0:
        return 1.0
    return max(1.0, hdop / ref)


def gnss_fix_scale(cfg: FirmwareConfig, meas: GnssMeasurement) -> float:
    """The factor (>= 1) on every GNSS sigma of the fix ``meas`` (D-5.51): the larger of the geometry's
    (:func:`gnss_dop_scale`) and the receiver's own estimate of its horizontal error (GST, per axis) over the sheet's
    horizontal figure, ``reported_sigma_h_m / gnss_pos_sigma_h_m``. A receiver sees its multipath in its
    pseudorange residuals where the HDOP cannot show it (a street canyon); the sheet stays the floor. A fix from 4
    satellites or fewer has no residual to show it: the sheet's ``gnss_unverified_multipath_m`` (a range error)
    through the fix's HDOP is added in quadrature, ``k^2 + (HDOP m / sqrt(2) / sheet)^2``. Cost: one more
    ``divsp`` when the fix carries GST, charged by the caller."""
    k = gnss_dop_scale(cfg, meas.hdop)
    sheet = cfg.gnss_pos_sigma_h_m
    r = meas.reported_sigma_h_m
    if r is not None and math.isfinite(r) and r > 0.0 and sheet > 0.0:
        k = max(k, r / sheet)
    mp, n, hdop = cfg.gnss_unverified_multipath_m, meas.num_sats, meas.hdop
    if mp > 0.0 and n is not None and n <= 4 and hdop is not None and math.isfinite(hdop) and hdop > 0.0 \
            and sheet > 0.0:
        # no fifth satellite: the receiver's residuals cannot show its multipath, so the sheet's is assumed
        k = math.sqrt(k * k + (hdop * mp / math.sqrt(2.0) / sheet) ** 2)
    return k


def gnss_corr_sigmas(cfg: FirmwareConfig) -> tuple[float, float]:
    """Sigmas (m, horizontal per axis and vertical) of the time-correlated GNSS position error: the spec's
    total less its white part, in quadrature (D-5.12)."""
    h = math.sqrt(max(cfg.gnss_pos_sigma_h_m**2 - cfg.gnss_pos_white_sigma_h_m**2, 0.0))
    v = math.sqrt(max(cfg.gnss_pos_sigma_v_m**2 - cfg.gnss_pos_white_sigma_v_m**2, 0.0))
    return h, v


class GnssErrorStates:
    """The three augmented Gauss-Markov states of the correlated GNSS position error ``b = [b_E b_N b_U]`` (m) at
    state index ``i`` (docs/decisions/filter-consistency.md D-5.12, D-5.17), declared once for every filter that
    carries them (the base filter, the federated SINS/GNSS sub-filter).

    ``db/dt = -b / tau + w``, ``q = 2 sigma_c^2 / tau`` (sigma_c from :func:`gnss_corr_sigmas`); the position rows
    become ``z = p_INS - p_GNSS = dp - b`` with ``R`` the white part only; P0 correlates the first fix's position
    error with ``b``; a fix after a gap longer than ``gnss_relock_gap_s`` re-draws them. A fix reporting a worse
    geometry scales the error's variance by ``level = k^2`` (:func:`gnss_dop_scale`, D-5.42): its white ``R``, the
    states' process noise and, when the level rises, their variance (:meth:`set_level`)."""

    #: state offset of each position row's error component: E for dlambda, N for dL, U for dh
    ROW_OFFSET: ClassVar[dict[int, int]] = {D_LON: 0, D_LAT: 1, D_H: 2}

    def __init__(self, cfg: FirmwareConfig, i: int) -> None:
        self.cfg = cfg
        self.i = i
        sc_h, sc_v = gnss_corr_sigmas(cfg)
        #: stationary variances (m^2, E N U) and the decay rate (1/s)
        self.var = np.array([sc_h**2, sc_h**2, sc_v**2])
        self.tau = cfg.gnss_pos_corr_time_s
        self.rate = 1.0 / self.tau
        #: FPGA time of the last position fix (s), for the loss-of-lock re-draw
        self.t_last_fix: float | None = None
        #: the variance scale of the receiver's error at the last fix (``k^2`` of :func:`gnss_dop_scale`; 1: the sheet)
        self.level = 1.0

    @property
    def psd(self) -> F64Array:
        """Process-noise PSD (m^2/s) of the three states: ``2 level sigma_c^2 / tau``."""
        return 2.0 * self.level * self.var / self.tau

    def set_level(self, P: FloatArray, level: float, prior: tuple[float, float] | None = None) -> bool:
        """The receiver's error variance is now ``level`` times the sheet's (D-5.42). When it rises, the correlated
        error that the states hold gains the difference ``d = level - old``: ``d var`` on their diagonal (an
        independent addition: ``P`` stays positive semi-definite); when it falls, the states keep their variance and
        decay towards the new stationary level through their smaller process noise. ``prior = (R_Mh, R_Nh cos L)``
        (m) on the first fix after :meth:`set_prior`: the position prior came from a fix of the same geometry (the
        alignment's), so it rises with it as :meth:`set_prior` would have set it at this level: the position
        variance by ``d`` times the sheet's total (``gnss_pos_sigma_*``), its covariance with the states by ``d var``
        (per axis ``[[d s^2, d v], [d v, d v]]``, positive semi-definite since ``s^2 >= v``). True when the level
        changed (the caller updates its process noise from :attr:`psd`)."""
        if level == self.level:
            return False
        d = level - self.level
        if d > 0.0:
            i = self.i
            idx = np.arange(i, i + 3)
            P[idx, idx] += (d * self.var).astype(P.dtype)
            if prior is not None:
                rmh, rnh_cl = prior
                sh, sv = self.cfg.gnss_pos_sigma_h_m, self.cfg.gnss_pos_sigma_v_m
                for pos_idx, off, scale, s in ((D_LON, 0, 1.0 / rnh_cl, sh), (D_LAT, 1, 1.0 / rmh, sh),
                                               (D_H, 2, 1.0, sv)):
                    P[pos_idx, pos_idx] += d * s * s * scale * scale
                    c = d * float(self.var[off]) * scale
                    P[pos_idx, i + off] += c
                    P[i + off, pos_idx] += c
        self.level = level
        return True

    def set_prior(self, P: F64Array, rmh: float, rnh_cl: float) -> None:
        """Stationary variances on the diagonal and the first fix's correlation with the position states:
        the position comes from a fix, ``dp = b + w``, so ``cov(dp, b) = var(b)`` (in the states' units:
        ``dL = dN / R_Mh``, ``dlambda = dE / (R_Nh cos L)``)."""
        i = self.i
        self.level = 1.0
        P[i:i + 3, i:i + 3] = np.diag(self.var)
        for pos_idx, off, scale in ((D_LON, 0, 1.0 / rnh_cl), (D_LAT, 1, 1.0 / rmh), (D_H, 2, 1.0)):
            P[pos_idx, i + off] = P[i + off, pos_idx] = self.var[off] * scale

    def position_row(self, h: FloatArray, idx: int) -> float:
        """Put ``-1`` for the GNSS error of position row ``idx`` into ``h``; the row's R (m^2), the white part."""
        h[self.i + self.ROW_OFFSET[idx]] = -1.0
        w = self.cfg.gnss_pos_white_sigma_v_m if idx == D_H else self.cfg.gnss_pos_white_sigma_h_m
        return w * w * self.level

    def relock(self, x: FloatArray, P: FloatArray, t_fix: float) -> bool:
        """After a loss of lock (no position fix for more than ``gnss_relock_gap_s``) the receiver's correlated error is
        a fresh draw (D-5.17): the states restart from zero with their stationary variance and no correlation with
        the other states (``x``, ``P`` in place). Without this, the Gauss-Markov keeps ``exp(-gap / tau)`` of its
        pre-outage estimate and correlation, and the filter puts the re-acquisition jump into position and vertical
        velocity. True when it re-drew (the caller counts and charges ``6 n`` adds)."""
        gap, last = self.cfg.gnss_relock_gap_s, self.t_last_fix
        self.t_last_fix = t_fix
        if gap <= 0.0 or last is None or t_fix - last <= gap:
            return False
        i = self.i
        x[i:i + 3] = 0.0
        P[i:i + 3, :] = 0.0
        P[:, i:i + 3] = 0.0
        P[i:i + 3, i:i + 3] = np.diag(self.level * self.var).astype(P.dtype)
        return True


class GyroFlickerStates:
    """The three augmented states of the gyro bias's flicker middle band ``f`` (rad/s, body axes) at state index ``i``
    (docs/decisions/filter-consistency.md D-5.28), declared once for every filter that carries them.

    ``df/dt = -f / c + w``, ``q = 2 s^2 / c`` with ``(c, s)`` from :func:`gyro_flicker_band`; they drive the attitude
    as the bias state does, ``dphi/dt = ... - C_b^n (eps + f)`` (F's attitude rows take F's gyro-bias columns), and
    start at their stationary variance ``s^2``. Not fed back: the strapdown compensates the bias state ``eps`` only;
    the estimate of ``f`` stays in the state and decays with it."""

    def __init__(self, cfg: FirmwareConfig, i: int) -> None:
        self.i = i
        self.tau, sigma = gyro_flicker_band(cfg)
        #: stationary variance ((rad/s)^2 per axis) and decay rate (1/s)
        self.var = sigma * sigma
        self.rate = 1.0 / self.tau

    @property
    def psd(self) -> F64Array:
        """Process-noise PSD ((rad/s)^2/s) of the three states: ``2 s^2 / c``."""
        return np.full(3, 2.0 * self.var / self.tau)


class SolarBiasStates:
    """The three augmented states of the systematic solar-vector error ``mu`` (rad) at state index ``i``
    (docs/decisions/filter-consistency.md D-5.13, D-5.16), declared once for every filter that carries them (the base
    filter, the federated MIMU/polarization sub-filter).

    With a sky figure (``psns_sky_bias_deg`` > 0) ``mu`` is the solved sun's rotation in the local-level frame,
    ``S^n measured = (I + [mu x]) S^n``, ``Z = -[S^n x] phi + [S^n x] mu``, of stationary covariance
    ``(m^2 + s^2) I + (s_el^2 - s^2) u u^T`` with ``u = z x S^n / |z x S^n|`` across the solar meridian (set at the
    first solar update, :meth:`set_axis`); without, a body-frame rotation ``s_b measured = (I + [mu x]) s_b``,
    ``Z = -[S^n x] phi + [S^n x] C_b^n mu``, isotropic. First-order Gauss-Markov of ``psns_bias_corr_time_s``
    (local-level: ``psns_sky_corr_time_s`` when stated, and in the heading turned, D-5.33)."""

    def __init__(self, cfg: FirmwareConfig, i: int) -> None:
        self.cfg = cfg
        self.i = i
        self.sigma2 = (cfg.psns_bias_sigma_deg * DEG) ** 2
        sky2 = (cfg.psns_sky_bias_deg * DEG) ** 2
        #: the sky's variance (rad^2 per axis across the sun) and the isotropic rest (camera mount)
        self.sky2 = sky2
        #: the sky's variance along the solar meridian (rad^2): the elevation figure, or D-5.16's ``2 s^2``
        self.sky_el2 = (cfg.psns_sky_bias_el_deg * DEG) ** 2 if cfg.psns_sky_bias_el_deg > 0 else 2.0 * sky2
        self.iso2 = max(self.sigma2 - sky2, 0.0)
        #: correlation time (s): the local-level sky figure when the states are shaped and it is stated (D-5.33)
        self.tau = (cfg.psns_sky_corr_time_s if sky2 > 0.0 and cfg.psns_sky_corr_time_s > 0.0
                    else cfg.psns_bias_corr_time_s)
        self.rate = 1.0 / self.tau
        #: the local-level states' decorrelation per radian of heading turned (1/rad; 0: none), across the solar
        #: meridian and along it (the elevation): a turn shows the camera another part of the sky (D-5.33)
        self.turn_rate = 1.0 / (cfg.psns_sky_turn_corr_deg * DEG) if cfg.psns_sky_turn_corr_deg > 0 else 0.0
        el_deg = cfg.psns_sky_turn_corr_el_deg or cfg.psns_sky_turn_corr_deg
        self.turn_rate_el = 1.0 / (el_deg * DEG) if el_deg > 0 else 0.0
        #: the body x axis's azimuth at the last :meth:`turn` (rad; None until the first)
        self.heading: float | None = None
        #: horizontal n-frame axis across the solar meridian (z x s_n, from the last solar update; None until the first)
        self.axis_n: F64Array | None = None

    @property
    def psd(self) -> F64Array:
        """Isotropic process-noise PSD (rad^2/s) of the three states: ``2 sigma^2 / tau``."""
        return np.full(3, 2.0 * self.sigma2 / self.tau)

    def cov(self) -> F64Array:
        """Stationary covariance (rad^2, local-level frame): ``(m^2 + s^2) I + (s_el^2 - s^2) u u^T`` (D-5.16,
        D-5.33; ``s_el^2 = 2 s^2`` when the sheet states no elevation figure)."""
        u = self.axis_n
        assert u is not None
        return (self.iso2 + self.sky2) * np.eye(3) + (self.sky_el2 - self.sky2) * np.outer(u, u)

    def reset(self, P: FloatArray) -> None:
        """The states before the first solar update, set at every (re)initialisation of the filter that carries
        them: the isotropic prior ``sigma^2 I`` in ``P``'s block, no solar-meridian axis yet (:meth:`set_axis`), no
        heading for :meth:`turn`."""
        i = self.i
        P[i:i + 3, i:i + 3] = np.diag(np.full(3, self.sigma2))
        self.axis_n = None
        self.heading = None

    def noise_block(self, Tk: float, turn_rad: float = 0.0) -> F64Array:
        """Q_k block (3, 3) over ``Tk`` s and a heading turn of ``turn_rad`` once the sun is known: ``2 T_k / tau``
        times :meth:`cov`, plus, for a turn, ``2 |d psi| / psi_c`` times the covariance's part across the meridian
        and ``2 |d psi| / psi_c,el`` times its part along ``u`` (a Gauss-Markov in time and in the angle turned,
        each axis with its own turn figure, D-5.33; :meth:`decay_block` is its ``Phi``). Cost: 9 multiplies and
        6 adds (``kf_sun_bias_noise``), 15 and 12 with a turn."""
        q = (2.0 * Tk / self.tau) * self.cov()
        if turn_rad > 0.0:
            u = self.axis_n
            assert u is not None
            uu = np.outer(u, u)
            q += 2.0 * turn_rad * (self.turn_rate * (self.iso2 + self.sky2) * (np.eye(3) - uu)
                                   + self.turn_rate_el * (self.iso2 + self.sky_el2) * uu)
        return q

    def decay_block(self, turn_rad: float) -> F64Array:
        """The decay over a heading turn of ``turn_rad`` (3, 3), subtracted from the states' diagonal block of
        ``Phi``: ``|d psi| (I / psi_c + (1 / psi_c,el - 1 / psi_c) u u^T)`` (``u`` unknown before the first solar
        update: isotropic)."""
        d = turn_rad * self.turn_rate * np.eye(3)
        if self.axis_n is not None:
            d += turn_rad * (self.turn_rate_el - self.turn_rate) * np.outer(self.axis_n, self.axis_n)
        return d

    def turn(self, cbn: FloatArray) -> float:
        """The heading turned (rad, >= 0) since the last call: the change of the body x axis's azimuth in the
        local-level frame, ``atan2(C_b^n[0, 0], C_b^n[1, 0])``, wrapped (0 at the first call, and always without a
        turn figure). Its decay (:meth:`decay_block`) joins ``T_k / tau`` on the states' diagonal of ``Phi``."""
        if self.turn_rate == 0.0:
            return 0.0
        h = math.atan2(float(cbn[0, 0]), float(cbn[1, 0]))
        last, self.heading = self.heading, h
        if last is None:
            return 0.0
        return abs((h - last + math.pi) % (2.0 * math.pi) - math.pi)

    def decay_over_turn(self, Phi: FloatArray, cbn: FloatArray, meter: c674x.CycleMeter,
                        cost: c674x.KernelCosts) -> float:
        """Subtract the decay over the heading turned since the last call (:meth:`turn`, :meth:`decay_block`) from
        the states' diagonal block of ``Phi`` in place, when the sky's error is shaped and has a turn figure (D-5.33);
        return the turn (rad; 0 otherwise), which the states' Q (:meth:`noise_block`) takes too. Cost: an ``atan2``
        and 12 multiplies, 12 adds (``solar_bias_turn``)."""
        if not (self.shaped and self.turn_rate > 0.0):
            return 0.0
        turn = self.turn(cbn)
        i = self.i
        Phi[i:i + 3, i:i + 3] -= self.decay_block(turn).astype(Phi.dtype)
        meter.charge("solar_bias_turn", cost.math("atan2") + c674x.flops(12, 12))
        return turn

    @property
    def shaped(self) -> bool:
        """True when the sky's error is modelled across the solar meridian (local-level states, a sky figure)."""
        return self.sky2 > 0.0

    def set_axis(self, s_n: FloatArray, P: FloatArray) -> bool:
        """Keep the n-frame axis across the solar meridian; at the first solar update give the states their prior in
        that shape in ``P`` (until then the states are uncorrelated with every other state, so this is the P0 the
        filter would have set knowing the sun; a federated sub-filter does not share it by ``1 / beta``, D-5.32). False
        (nothing done) with the sun at the zenith. Cost: 4 multiplies, 2 adds, a reciprocal square root
        (``solar_bias_axis``)."""
        e, nn = float(s_n[0]), float(s_n[1])
        norm = math.hypot(e, nn)
        if norm < 1e-3:  # sun at the zenith: no meridian
            return False
        first = self.axis_n is None
        self.axis_n = np.array([-nn / norm, e / norm, 0.0])
        if first:
            i = self.i
            P[i:i + 3, i:i + 3] = self.cov().astype(P.dtype)
        return True

    def rows(self, H: FloatArray, h_att: FloatArray, cbn: FloatArray) -> None:
        """Fill the states' columns of the solar rows ``H`` (3, n) from their attitude columns ``h_att = -[S^n x]``:
        ``[S^n x]`` (local-level states) or ``[S^n x] C_b^n`` (body states)."""
        if self.shaped:
            H[:, self.i:self.i + 3] = -h_att
        else:
            H[:, self.i:self.i + 3] = -h_att @ cbn


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
    #: the receiver's HDOP (GGA / GNS) when it reported one: scales the sigmas (:func:`gnss_dop_scale`, D-5.42)
    hdop: float | None = None
    #: the receiver's own estimate of its horizontal position error per axis (GST latitude and longitude error,
    #: m, 1 sigma) when it sent one: scales the sigmas too (:func:`gnss_fix_scale`, D-5.51)
    reported_sigma_h_m: float | None = None
    #: satellites used (GGA / GNS / NAV-PVT) when reported: 4 or fewer leave no residual (:func:`gnss_fix_scale`)
    num_sats: int | None = None


def gnss_measurement_rows(cfg: FirmwareConfig, meter: c674x.CycleMeter, meas: GnssMeasurement,
                          p_ins: FloatArray, v_ins: FloatArray) -> list[tuple[int, float, float, float]]:
    """The scalar rows of a GNSS update: ``(state index, H value, z, R)`` per measured component.

    Position (Eq. 23-24): ``Z_p = [R_Mh dL, R_Nh cosL dlambda, dh]`` (m), ``H_p = [0 diag(R_Mh, R_Nh cosL, 1) 0]``,
    charging the residual's cycles on ``meter``; velocity (Eq. 28-30): ``Z_v = v_INS - v_GNSS`` (ENU m/s),
    ``H_v = [0 I 0]``, the vertical only when measured (UBX velD). ``p_ins`` = (lat rad, lon rad, h m) and
    ``v_ins`` (ENU m/s) are the INS at the fix's time of validity. Shared by every filter with GNSS updates.
    Every R is the sheet's times ``k^2``, ``k`` from the fix's HDOP and GST (:func:`gnss_fix_scale`, D-5.42, D-5.51).
    """
    rows: list[tuple[int, float, float, float]] = []
    k2 = gnss_fix_scale(cfg, meas) ** 2
    if cfg.gnss_hdop_ref > 0.0 and meas.hdop is not None:
        meter.charge("gnss_dop_scale", c674x.mathlib("divsp") + c674x.flops(1, 0))
    if meas.reported_sigma_h_m is not None:
        meter.charge("gnss_reported_scale", c674x.mathlib("divsp") + c674x.flops(1, 0))
    if meas.pos is not None:
        lat = float(p_ins[0])
        rm, rn = earth.radii(lat)
        rmh, rnh = rm + float(p_ins[2]), rn + float(p_ins[2])
        cl = math.cos(lat)
        sh = meas.sigma_pos_h_m or cfg.gnss_pos_sigma_h_m
        sv = meas.sigma_pos_v_m or cfg.gnss_pos_sigma_v_m
        rows += [
            (D_LAT, rmh, (float(p_ins[0]) - meas.pos[0]) * rmh, sh**2 * k2),
            (D_LON, rnh * cl, (float(p_ins[1]) - meas.pos[1]) * rnh * cl, sh**2 * k2),
        ]
        if meas.pos_up:
            rows.append((D_H, 1.0, float(p_ins[2]) - meas.pos[2], sv**2 * k2))
        meter.charge("gnss_residual", c674x.dp_flops(8, 6) + c674x.mathlib("cosdp") + c674x.mathlib("sqrtdp")
                     + c674x.mathlib("divdp"))
    if meas.vel is not None:
        svh = meas.sigma_vel_mps or cfg.gnss_vel_sigma_h_mps
        rows.append((DV_E, 1.0, float(v_ins[0]) - float(meas.vel[0]), svh**2 * k2))
        rows.append((DV_N, 1.0, float(v_ins[1]) - float(meas.vel[1]), svh**2 * k2))
        if meas.vel_up:
            rows.append((DV_U, 1.0, float(v_ins[2]) - float(meas.vel[2]), cfg.gnss_vel_sigma_v_mps**2 * k2))
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
    """What the main loop offers a variant (:class:`firmware_model.tasks.navigation.NavCore` implements it)."""

    def utc_days(self, t_fpga_s: float) -> float | None:
        """Grena days (UT) at FPGA time ``t_fpga_s``, once GNSS gave date and time (else None)."""

    def ins_at(self, t_meas: float) -> tuple[F64Array, FloatArray, FloatArray]:
        """INS position (lat, lon rad, h m; float64), ENU velocity and attitude quaternion ``q_b^n`` at ``t_meas``.

        Fresh arrays built from the INS history (docs/decisions/performance.md D-10.F2)."""

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

    def _count_rows(self, kind: str, dof: int, nis: float) -> None:
        """Add ``dof`` degrees of freedom carrying the NIS ``nis`` to :attr:`innovation_stats` under ``kind``."""
        st = self.innovation_stats.get(kind)
        if st is None:
            st = self.innovation_stats[kind] = {"rows": 0, "nis_sum": 0.0}
        st["rows"] += dof
        st["nis_sum"] += nis

    def _count_nis(self, kind: str, norm_innov: float) -> None:
        """Add one scalar row's normalised innovation ``nu / sqrt(s)`` to :attr:`innovation_stats`."""
        self._count_rows(kind, 1, norm_innov * norm_innov)

    def _count_solar_nis(self, norm_innovs: Sequence[float], z: FloatArray, s_n: FloatArray, r: float) -> None:
        """Count one accepted solar-vector fix in :attr:`innovation_stats` as ``SOLAR_VECTOR_DOF`` rows with its NIS
        across the sun (:func:`solar_fix_nis`; ``z`` the residual, ``s_n`` the unit sun in the local-level frame)."""
        along = float(np.dot(z.astype(np.float64), s_n.astype(np.float64)))
        self._count_rows("solar_vector", SOLAR_VECTOR_DOF, solar_fix_nis(norm_innovs, along, r))

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
