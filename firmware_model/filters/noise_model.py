"""The spec sheet's inertial error model as the error-state KF carries it: continuous process noise ``q``, the initial
covariance P0, and the noise terms the predict adds per interval (docs/decisions/filter-consistency.md D-5.11 to
D-5.15, D-5.25, D-5.27, D-5.28).

Units: gyro quantities in rad/s (PSDs in (rad/s)^2/s, white noise in rad^2/s), accelerometer quantities in m/s^2
(PSDs in (m/s^2)^2/s), times in s; the 15-state layout of :mod:`firmware_model.kf` (attitude error ``phi`` in the
local-level ENU frame n, velocity error ENU m/s, position error ``dL dlambda`` rad and ``dh`` m, gyro bias ``eps``
and accelerometer bias ``nabla`` in body axes). Shared by every filter with the 15-state model (the base filter, the
federated sub-filters): one declaration per fact (D-5.18). The gyro flicker's middle band (D-5.28) is the augmented
state :class:`GyroFlickerStates` (rad/s, body axes).
"""

from __future__ import annotations

import math

import numpy as np

from .. import c674x, earth
from ..arrays import F64Array, FloatArray
from ..attitude import q2mat_fast
from ..config import FirmwareConfig
from ..kf import DV_E, DV_N, DV_U, IDX_ACC, IDX_ATT, IDX_GYRO, IDX_POS, IDX_VEL, N_STATES, process_noise_psd
from ..nav_state import NavState
from ..units import DEG, DPH, G_STD

__all__ = [
    "GM_ALLAN_PEAK",
    "GM_ALLAN_PEAK_X",
    "ROTATION_NOISE_FLOPS",
    "WARMUP_NOISE_CYCLES",
    "GyroFlickerStates",
    "flicker_b_accel",
    "flicker_b_gyro",
    "flicker_match_s",
    "flicker_white_psd",
    "gyro_bias_walk_psd",
    "gyro_flicker_band",
    "rotation_attitude_noise",
    "spec_initial_covariance",
    "spec_process_noise",
    "warmup_gyro_bias_variance",
]


#: reference angle of the rotation-dependent attitude noise (BaseFilter._rotation_noise), rad
_THETA_REF_RAD = math.pi / 2.0
#: Allan-deviation floor of flicker bias noise per unit bias instability B (IEEE Std 952: 0.664 B)
_ALLAN_FLOOR = math.sqrt(2.0 * math.log(2.0) / math.pi)
#: interval of the GNSS velocity aiding (s): 1 Hz fixes (for the flicker's matching time, flicker_match_s)
_VEL_AID_INTERVAL_S = 1.0
#: a first-order Gauss-Markov of sigma s and correlation time c has the Allan variance
#: ``s^2 (c / T)^2 (2 x - 3 + 4 exp(-x) - exp(-2 x))``, ``x = T / c`` (from its autocorrelation ``s^2 exp(-|t| / c)``);
#: its Allan deviation peaks at ``T = GM_ALLAN_PEAK_X c`` with the value ``GM_ALLAN_PEAK s`` (the root of its
#: derivative, to 5 digits; tests/firmware_model/test_spec_sheet.py checks both against the formula)
GM_ALLAN_PEAK_X = 1.8928
GM_ALLAN_PEAK = 0.61736


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


#: multiplies and adds of :func:`rotation_attitude_noise` (6 + 9 x 3 for C diag C^T, the 12 body variances)
ROTATION_NOISE_FLOPS = (45, 36)


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
