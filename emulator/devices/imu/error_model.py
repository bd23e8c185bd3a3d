"""Error models of one sensor triad: the specifications (gyro, accelerometers), the temperature, the flicker
bank and :class:`InertialErrorModel` (see :mod:`emulator.devices.imu`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
from scipy.signal import lfilter

from protocols.constants import DEG, DPH, G_STD
from protocols.imu_frame import ACCEL_VOLTS_PER_G

__all__ = [
    "BLOCK",
    "AccelErrors",
    "FlickerBank",
    "GyroErrors",
    "ImuTemperature",
    "InertialErrorModel",
    "accel_error_model",
    "gyro_error_model",
]

BLOCK = 200

#: Base-paper limits (docs/architecture.md); the presets use them as 3 sigma.
PAPER_GYRO_BIAS_REPEATABILITY_DPH = 40.0
PAPER_GYRO_BIAS_STABILITY_DPH = 20.0
PAPER_ACCEL_BIAS_REPEATABILITY_MG = (7.0, 7.0, 7.0)
PAPER_ACCEL_BIAS_STABILITY_MG = (3.0, 4.0, 4.0)


@dataclass
class GyroErrors:
    """STIM210 error figures, 1 sigma per axis (units in the names). Defaults: the ``paper`` preset."""

    arw_deg_rt_h: float = 0.15
    bias_repeatability_deg_h: float = PAPER_GYRO_BIAS_REPEATABILITY_DPH / 3.0
    bias_instability_deg_h: float = PAPER_GYRO_BIAS_STABILITY_DPH / 3.0
    bias_corr_time_s: float = 600.0
    rate_random_walk_deg_h_rt_h: float = 0.0
    scale_factor_ppm: float = 500.0 / 3.0
    scale_asymmetry_ppm: float = 500.0 / 3.0
    misalignment_mrad: float = 1.0 / 3.0
    nonlinearity_ppm_fs: float = 200.0 / 3.0
    bias_temp_coeff_deg_h_per_c: float = 0.0
    bias_temp_gradient_deg_h: float = 10.0
    g_sensitivity_deg_h_per_g: float = 10.0
    range_dps: float = 400.0
    #: the unit's turn-on bias per axis, deg/h (an envelope's draw); None: drawn from ``bias_repeatability_deg_h``
    turn_on_bias_deg_h: tuple[float, float, float] | None = None


@dataclass
class AccelErrors:
    """Accelerometer error figures per axis (x: MS9030, y/z: the +-25 g parts), 1 sigma. Defaults: ``paper``."""

    bias_repeatability_mg: tuple[float, float, float] = tuple(x / 3.0 for x in PAPER_ACCEL_BIAS_REPEATABILITY_MG)  # type: ignore[assignment]
    bias_instability_mg: tuple[float, float, float] = tuple(x / 3.0 for x in PAPER_ACCEL_BIAS_STABILITY_MG)  # type: ignore[assignment]
    bias_corr_time_s: float = 600.0
    noise_ug_rt_hz: float = 100.0
    bias_random_walk_mg_rt_h: float = 0.0
    scale_factor_ppm: tuple[float, float, float] = (300.0, 1000.0 / 3.0, 1000.0 / 3.0)
    scale_error_ppm: tuple[float, float, float] = (200.0 / 3.0, 200.0 / 3.0, 200.0 / 3.0)
    misalignment_mrad: float = 1.0 / 3.0
    bias_temp_coeff_mg_per_c: float = 0.0
    range_g: tuple[float, float, float] = (30.0, 25.0, 25.0)
    #: vibration rectification error per axis, ug/g^2: a vibration of g_rms shifts the mean by vre g_rms^2
    vre_ug_per_g2: tuple[float, float, float] = (0.0, 0.0, 0.0)
    volts_per_g: tuple[float, float, float] = field(default_factory=lambda: ACCEL_VOLTS_PER_G)
    #: the unit's turn-on bias per axis, mg (an envelope's draw); None: drawn from ``bias_repeatability_mg``
    turn_on_bias_mg: tuple[float, float, float] | None = None


@dataclass
class ImuTemperature:
    """IMU temperature profile and the calibration temperature.

    ``T(t) = start_c + warmup_c (1 - exp(-t / warmup_tau_s)) + rate_c_per_min t / 60`` (degC, ``t`` s since
    power-on = scenario start): a first-order thermal warm-up after power-on (the unit's self-heating, a rise
    ``warmup_c`` with time constant ``warmup_tau_s``) on top of a linear ambient ramp. ``warmup_c = 0`` is the
    linear ramp of before. :meth:`rate_at` is ``dT/dt`` in degC/min, the input of the temperature-gradient
    bias term (docs/sensors.md, "IMU temperature").
    """

    start_c: float = 25.0
    rate_c_per_min: float = 0.0
    cal_c: float = 25.0
    warmup_c: float = 0.0
    warmup_tau_s: float = 600.0

    @property
    def warms_up(self) -> bool:
        """True when the profile has a warm-up (its rate changes with time)."""
        return self.warmup_c != 0.0

    def at(self, t: float) -> float:
        """Temperature at ``t`` (s), degC."""
        if self.warmup_c == 0.0:
            return self.start_c + self.rate_c_per_min * t / 60.0
        return (self.start_c + self.warmup_c * -math.expm1(-t / self.warmup_tau_s)
                + self.rate_c_per_min * t / 60.0)

    def rate_at(self, t: float) -> float:
        """``dT/dt`` at ``t`` (s), degC per minute: ``rate_c_per_min + 60 warmup_c / tau exp(-t / tau)``."""
        if self.warmup_c == 0.0:
            return self.rate_c_per_min
        return self.rate_c_per_min + 60.0 * self.warmup_c / self.warmup_tau_s * math.exp(-t / self.warmup_tau_s)


def _av_gm(q: float, tau_c: float, T: np.ndarray) -> np.ndarray:
    """Allan variance of a first-order Gauss-Markov process of variance ``q`` and correlation time ``tau_c``."""
    x = T / tau_c
    return q * tau_c**2 / T**2 * (2 * x - 3 + 4 * np.exp(-x) - np.exp(-2 * x))


class FlickerBank:
    """Flicker (1/f) bias noise as a bank of Gauss-Markov processes (see module docstring).

    Parameters
    ----------
    b : bias-instability coefficient ``B`` (SI), the Allan floor is ``0.664 B``.
    tau_max : longest correlation time, s. ``tau_min`` shortest.
    """

    FLOOR: ClassVar[float] = math.sqrt(2.0 * math.log(2.0) / math.pi)  # 0.664

    def __init__(self, b: np.ndarray, tau_max: float, tau_min: float = 0.3, per_decade: int = 2) -> None:
        k = np.arange(0, 100)
        taus = tau_max * 10.0 ** (-k / per_decade)
        self.taus = taus[taus >= tau_min] if tau_max > tau_min else np.array([tau_max])
        T = np.logspace(math.log10(max(self.taus.min(), 1e-3)), math.log10(self.taus.max()), 200)
        unit = np.sqrt(sum(_av_gm(1.0, tc, T) for tc in self.taus)).max()
        b = np.asarray(b, dtype=np.float64)
        #: per-process standard deviation (n_axes,)
        self.sigma = self.FLOOR * b / unit
        self.state = np.zeros((len(self.taus), len(b)))

    def init_stationary(self, rng: np.random.Generator) -> None:
        self.state = rng.standard_normal(self.state.shape) * self.sigma[None, :]

    def block(self, w: np.ndarray, dt: float) -> np.ndarray:
        """Advance by ``len(w)`` steps of ``dt`` driven by ``w`` (n, K, axes) standard normals; returns (n, axes)."""
        out = np.zeros((w.shape[0], w.shape[2]))
        for i, tc in enumerate(self.taus):
            a = math.exp(-dt / tc)
            b = math.sqrt(1.0 - a * a)
            for ax in range(w.shape[2]):
                if self.sigma[ax] == 0.0:
                    continue
                y, _zf = lfilter([b * self.sigma[ax]], [1.0, -a], w[:, i, ax], zi=[a * self.state[i, ax]])
                out[:, ax] += y
                self.state[i, ax] = y[-1]
        return out

    def allan_variance(self, T: np.ndarray) -> np.ndarray:
        """Analytic Allan variance of the bank (n_T, axes)."""
        return np.stack([sum(_av_gm(s * s, tc, T) for tc in self.taus) for s in self.sigma], axis=1)


class InertialErrorModel:
    """Errors of one sensor triad (see module docstring); all quantities SI.

    Parameters
    ----------
    white : (3,) white-noise density ``N`` (SI sqrt(s): rad/sqrt(s) or m/s/sqrt(s)).
    bias_instability : (3,) ``B`` (SI), with ``bias_corr_time_s`` the top of the flicker band.
    rrw : (3,) rate random walk ``K`` (SI/sqrt(s)).
    bias0 : (3,) turn-on bias (drawn by the caller).
    m : (3, 3) ``I + S + M``; ``asym`` (3,) asymmetry; ``nl`` (3,) nonlinearity peak (SI) with ``fs`` (3,) full scale.
    temp_coeff, temp_gradient : (3,) bias per degC and per (degC/min) (SI).
    g_sens : (3, 3) bias per m/s^2 of specific force (gyro), or None.
    """

    def __init__(self, rng: np.random.Generator, white: np.ndarray, bias_instability: np.ndarray,
                 bias_corr_time_s: float, rrw: np.ndarray, bias0: np.ndarray, m: np.ndarray, asym: np.ndarray,
                 nl: np.ndarray, fs: np.ndarray,
                 temp_coeff: np.ndarray, temp_gradient: np.ndarray, g_sens: np.ndarray | None = None) -> None:
        self.rng = rng
        self.white = np.asarray(white, dtype=np.float64)
        self.flicker = FlickerBank(np.asarray(bias_instability, dtype=np.float64), bias_corr_time_s)
        self.flicker.init_stationary(rng)
        self.rrw = np.asarray(rrw, dtype=np.float64)
        self.rw_state = np.zeros(3)
        self.bias0 = np.asarray(bias0, dtype=np.float64)
        self.m = np.asarray(m, dtype=np.float64)
        self.asym = np.asarray(asym, dtype=np.float64)
        self.nl = np.asarray(nl, dtype=np.float64)
        self.fs = np.asarray(fs, dtype=np.float64)
        self.temp_coeff = np.asarray(temp_coeff, dtype=np.float64)
        self.temp_gradient = np.asarray(temp_gradient, dtype=np.float64)
        self.g_sens = g_sens
        self._block: np.ndarray | None = None
        self._block_i = 0
        self._block_dt = 0.0
        self._stochastic = bool(np.any(self.white) or np.any(self.flicker.sigma) or np.any(self.rrw))
        self._deterministic = bool(np.any(self.m != np.eye(3)))
        self._has_asym = bool(np.any(self.asym))
        self._has_nl = bool(np.any(self.nl))
        self._has_temp = bool(np.any(self.temp_coeff) or np.any(self.temp_gradient))

    # -- stochastic part ---------------------------------------------------------------------
    def noise(self, n: int, dt: float) -> np.ndarray:
        """(n, 3) stochastic errors of the next ``n`` intervals of ``dt``: white mean + flicker + random walk."""
        k = len(self.flicker.taus)
        w = self.rng.standard_normal((n, 2 + k, 3))
        out = w[:, 0, :] * (self.white / math.sqrt(dt))
        out += self.flicker.block(w[:, 2:, :], dt)
        if np.any(self.rrw):
            rw = self.rw_state + np.cumsum(w[:, 1, :] * (self.rrw * math.sqrt(dt)), axis=0)
            self.rw_state = rw[-1].copy()
            out += rw
        return out

    @property
    def stochastic(self) -> bool:
        """True when the model has a stochastic part (white noise, flicker or random walk)."""
        return self._stochastic

    def noise_position(self) -> tuple[np.ndarray | None, int]:
        """The current noise block (None before the first draw) and the index of the row :meth:`next_noise`
        returns next. For the look-ahead (:mod:`.lookahead`), which reads rows ahead without drawing."""
        return self._block, self._block_i

    def consume_noise_row(self, block: np.ndarray | None, i: int, dt: float) -> bool:
        """Consume row ``i`` of ``block``, as :meth:`next_noise` would, if it is the row next_noise would return
        for an interval ``dt`` (same block, same position, same ``dt``): True. Else nothing changes: False."""
        if self._block is not block or self._block_i != i or abs(dt - self._block_dt) > 1e-9 * dt:
            return False
        self._block_i += 1
        return True

    def next_noise(self, dt: float) -> np.ndarray:
        """The stochastic error of one interval (from a vectorised block of 200)."""
        if not self._stochastic:
            return np.zeros(3)
        if self._block is None or self._block_i >= BLOCK or abs(dt - self._block_dt) > 1e-9 * dt:
            self._block = self.noise(BLOCK, dt)
            self._block_i = 0
            self._block_dt = dt
        v = self._block[self._block_i]
        self._block_i += 1
        return v

    # -- deterministic part ------------------------------------------------------------------
    def deterministic(self, x: np.ndarray, temp_c: float = 25.0, temp_rate_c_per_min: float = 0.0,
                      cal_c: float = 25.0, f_b: np.ndarray | None = None) -> np.ndarray:
        """Input ``x`` (.., 3) through scale, misalignment, asymmetry, nonlinearity and the constant biases."""
        y = x @ self.m.T if self._deterministic else np.array(x, dtype=np.float64)
        if self._has_asym:
            y = y + self.asym * np.abs(x)
        if self._has_nl:
            u = x / self.fs
            y = y + self.nl * (1.5 * math.sqrt(3.0)) * (u * u * u - u)
        y = y + self.bias0
        if self._has_temp:
            y = y + self.temp_coeff * (temp_c - cal_c) + self.temp_gradient * temp_rate_c_per_min
        if self.g_sens is not None and f_b is not None:
            y = y + self.g_sens @ f_b if np.ndim(f_b) == 1 else y + f_b @ self.g_sens.T
        return y

    def deterministic_rows(self, x: np.ndarray, temp_c: np.ndarray,
                           temp_rate_c_per_min: float | np.ndarray = 0.0,
                           cal_c: float = 25.0, f_b: np.ndarray | None = None) -> np.ndarray:
        """:meth:`deterministic` of ``n`` inputs at once: ``x`` (n, 3), ``temp_c`` (n,), ``f_b`` (n, 3);
        ``temp_rate_c_per_min`` one rate or one per row (n,).

        Bit for bit the per-row results: the matrix products are stacked (numpy runs the same
        1 x 3 kernel per row), every other step is element-wise in the same order."""
        y = (x[:, None, :] @ self.m.T)[:, 0, :] if self._deterministic else np.array(x, dtype=np.float64)
        if self._has_asym:
            y = y + self.asym * np.abs(x)
        if self._has_nl:
            u = x / self.fs
            y = y + self.nl * (1.5 * math.sqrt(3.0)) * (u * u * u - u)
        y = y + self.bias0
        if self._has_temp:
            rates = np.asarray(temp_rate_c_per_min, dtype=np.float64)
            y = y + self.temp_coeff * (temp_c[:, None] - cal_c) + self.temp_gradient * (
                rates[:, None] if rates.ndim else rates)
        if self.g_sens is not None and f_b is not None:
            y = y + (self.g_sens[None, :, :] @ f_b[:, :, None])[:, :, 0]
        return y

    def measure(self, x: np.ndarray, dt: float, temp_c: float = 25.0, temp_rate_c_per_min: float = 0.0,
                cal_c: float = 25.0, f_b: np.ndarray | None = None) -> np.ndarray:
        """One interval: ``x`` (3,) true mean input -> measured mean (before range and quantization)."""
        return self.deterministic(x, temp_c, temp_rate_c_per_min, cal_c, f_b) + self.next_noise(dt)


def _misalignment(rng: np.random.Generator, sigma: float) -> np.ndarray:
    m = rng.standard_normal((3, 3)) * sigma
    np.fill_diagonal(m, 0.0)
    return m


def _turn_on_bias(drawn: np.ndarray, given: tuple[float, float, float] | None) -> np.ndarray:
    """The unit's turn-on bias (the figure's unit): ``given`` when the scenario fixes it, else the draw (taken from
    the stream either way, so fixing it leaves every other constant of the unit as it was)."""
    return drawn if given is None else np.asarray(given, dtype=np.float64)


def gyro_error_model(e: GyroErrors, rng: np.random.Generator) -> InertialErrorModel:
    """Draw one STIM210 unit from the figures ``e`` (turn-on constants) and return its error model."""
    sf = rng.standard_normal(3) * e.scale_factor_ppm * 1e-6
    m = np.eye(3) + np.diag(sf) + _misalignment(rng, e.misalignment_mrad * 1e-3)
    fs = np.full(3, e.range_dps * DEG)
    g_sens = rng.standard_normal((3, 3)) * (e.g_sensitivity_deg_h_per_g * DPH / G_STD / math.sqrt(3.0))
    return InertialErrorModel(
        rng,
        white=np.full(3, e.arw_deg_rt_h * DEG / 60.0),
        bias_instability=np.full(3, e.bias_instability_deg_h * DPH),
        bias_corr_time_s=e.bias_corr_time_s,
        rrw=np.full(3, e.rate_random_walk_deg_h_rt_h * DPH / 60.0),
        bias0=_turn_on_bias(rng.standard_normal(3) * e.bias_repeatability_deg_h, e.turn_on_bias_deg_h) * DPH,
        m=m,
        asym=rng.standard_normal(3) * e.scale_asymmetry_ppm * 1e-6,
        nl=rng.standard_normal(3) * e.nonlinearity_ppm_fs * 1e-6 * fs,
        fs=fs,
        temp_coeff=rng.standard_normal(3) * e.bias_temp_coeff_deg_h_per_c * DPH,
        temp_gradient=rng.standard_normal(3) * e.bias_temp_gradient_deg_h * DPH,
        g_sens=g_sens if e.g_sensitivity_deg_h_per_g > 0 else None,
    )


def accel_error_model(e: AccelErrors, rng: np.random.Generator) -> InertialErrorModel:
    """Draw one accelerometer triad from the figures ``e``."""
    g = 1e-3 * G_STD
    sf = rng.standard_normal(3) * np.hypot(np.array(e.scale_factor_ppm), np.array(e.scale_error_ppm)) * 1e-6
    m = np.eye(3) + np.diag(sf) + _misalignment(rng, e.misalignment_mrad * 1e-3)
    fs = np.array(e.range_g) * G_STD
    return InertialErrorModel(
        rng,
        white=np.full(3, e.noise_ug_rt_hz * 1e-6 * G_STD),
        bias_instability=np.array(e.bias_instability_mg) * g,
        bias_corr_time_s=e.bias_corr_time_s,
        rrw=np.full(3, e.bias_random_walk_mg_rt_h * g / 60.0),
        bias0=_turn_on_bias(rng.standard_normal(3) * np.array(e.bias_repeatability_mg), e.turn_on_bias_mg) * g,
        m=m,
        asym=np.zeros(3),
        nl=np.zeros(3),
        fs=fs,
        temp_coeff=rng.standard_normal(3) * e.bias_temp_coeff_mg_per_c * g,
        temp_gradient=np.zeros(3),
    )
