"""Inertial sensors: the STIM210 gyro (RS422 datagrams) and the analog accelerometers.

Both sample the same truth (:class:`ImuTruthTap`) over the FPGA's trigger interval
``[t_prev, t]``: the STIM210 in *average angular rate* output (the mean rate over the
interval, TS1524 section 7.5.2.2) and the accelerometers through the FPGA's oversampling ADC,
whose boxcar average over the same interval is the mean specific force (docs/decisions.md D4).

Error model (:class:`InertialErrorModel`, one per sensor triad; figures in the YAML presets of
``emulator/presets/imu.yaml``, sources in ``docs/sensors.md``). For the true mean input ``x``
(rad/s or m/s^2, body axes) over an interval of length ``dt``::

    y = (I + S + M) x + A |x| + NL(x) + b_0 + b_T(T, dT/dt) + G f + b_flicker(t) + b_rrw(t) + n_white

* ``S`` diagonal scale-factor errors and ``M`` off-diagonal axis misalignments (random constants
  per unit), ``A`` the scale-factor asymmetry (half the difference between the positive and
  negative scale factors), ``NL`` a terminal-based cubic nonlinearity
  ``k FS (3 sqrt(3)/2)(u^3 - u)``, ``u = x/FS`` (zero at 0 and +-FS, peak ``k FS``);
* ``b_0`` the turn-on bias (bias repeatability), ``b_T`` the residual temperature bias
  (coefficient times ``T - T_cal`` plus a gradient term times ``dT/dt``), ``G f`` the gyro's
  linear-acceleration sensitivity;
* ``b_flicker`` the in-run bias instability: flicker (1/f) noise approximated by a bank of
  first-order Gauss-Markov processes, two per decade of correlation time from 0.3 s to
  ``bias_corr_time_s``, scaled so that the flat part of its Allan deviation equals
  ``0.664 B`` (IEEE Std 952: the Allan-deviation floor of bias instability ``B``);
* ``b_rrw`` a random walk of rate random walk ``K`` (Allan deviation ``K sqrt(tau/3)``);
* ``n_white`` white noise of density ``N`` (angle / velocity random walk): the mean over ``dt``
  has variance ``N^2/dt`` (Allan deviation ``N/sqrt(tau)``).

Then the range (saturation) and the 24-bit words (STIM: 2^-14 deg/s; accelerometers: volts
through the 24-bit ADC). The stochastic part is generated vectorised in blocks of 200 samples
(:meth:`InertialErrorModel.noise`), which is the same code that the Allan-deviation test runs
over a two-hour record.

The paper's "< X" limits are 3 sigma (docs/decisions.md D1): the presets hold ``X / 3``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from scipy.signal import lfilter

from protocols.imu_frame import ACCEL_VOLTS_PER_G, ADC_CODE_MAX, ADC_VOLTS_PER_LSB
from protocols.stim import GYRO_ANGLE_LSB_DEG, GYRO_RATE_LSB_DPS, STIM_COUNTER_HZ, TEMP_LSB_DEGC, Stim210Format, StimDatagram

from ..links.base import Link
from ..world.trajectory import Trajectory

__all__ = [
    "GyroErrors",
    "AccelErrors",
    "ImuTemperature",
    "ImuTruthTap",
    "InertialErrorModel",
    "FlickerBank",
    "gyro_error_model",
    "accel_error_model",
    "Stim210Gyro",
    "AnalogAccelerometers",
    "InjectedFaults",
    "allan_deviation",
]

DEG = math.pi / 180.0
DPH = DEG / 3600.0
G_STD = 9.80665
BLOCK = 200

#: Base-paper limits (DESIGN.md section 2); the presets use them as 3 sigma.
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
    volts_per_g: tuple[float, float, float] = field(default_factory=lambda: ACCEL_VOLTS_PER_G)


@dataclass
class ImuTemperature:
    """IMU temperature profile ``T(t) = start_c + rate_c_per_min t / 60`` and the calibration temperature."""

    start_c: float = 25.0
    rate_c_per_min: float = 0.0
    cal_c: float = 25.0

    def at(self, t: float) -> float:
        return self.start_c + self.rate_c_per_min * t / 60.0


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

    FLOOR = math.sqrt(2.0 * math.log(2.0) / math.pi)  # 0.664

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
                y, zf = lfilter([b * self.sigma[ax]], [1.0, -a], w[:, i, ax], zi=[a * self.state[i, ax]])
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

    def __init__(self, rng: np.random.Generator, white: np.ndarray, bias_instability: np.ndarray, bias_corr_time_s: float,
                 rrw: np.ndarray, bias0: np.ndarray, m: np.ndarray, asym: np.ndarray, nl: np.ndarray, fs: np.ndarray,
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

    def deterministic_rows(self, x: np.ndarray, temp_c: np.ndarray, temp_rate_c_per_min: float = 0.0,
                           cal_c: float = 25.0, f_b: np.ndarray | None = None) -> np.ndarray:
        """:meth:`deterministic` of ``n`` inputs at once: ``x`` (n, 3), ``temp_c`` (n,), ``f_b`` (n, 3).

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
            y = y + self.temp_coeff * (temp_c[:, None] - cal_c) + self.temp_gradient * temp_rate_c_per_min
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
        bias0=rng.standard_normal(3) * e.bias_repeatability_deg_h * DPH,
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
        bias0=rng.standard_normal(3) * np.array(e.bias_repeatability_mg) * g,
        m=m,
        asym=np.zeros(3),
        nl=np.zeros(3),
        fs=fs,
        temp_coeff=rng.standard_normal(3) * e.bias_temp_coeff_mg_per_c * g,
        temp_gradient=np.zeros(3),
    )


class InjectedFaults:
    """Faults injected into one sensor triad (``emulator.faults`` drives them; all off by default).

    Applied to the measured mean of each interval (SI, body axes), in this order: the bias steps
    (``bias``), the stuck axes (held at the output they had when they froze) and a reduced range
    (``range_limit``, a scalar clipping every axis). The counters are the evidence that a fault took
    effect: intervals that carried a bias, held a stuck axis, and had a value clipped by the reduced
    range (only when the input really exceeded it).
    """

    __slots__ = ("bias", "_biases", "stuck", "stuck_value", "range_limit", "active", "biased", "stuck_samples",
                 "clipped")

    def __init__(self) -> None:
        self.bias = np.zeros(3)
        self._biases: dict[object, np.ndarray] = {}
        self.stuck = np.zeros(3, dtype=bool)
        self.stuck_value = np.zeros(3)
        self.range_limit: float | None = None
        self.active = False
        self.biased = 0
        self.stuck_samples = 0
        self.clipped = 0

    def _update(self) -> None:
        self.active = bool(np.any(self.bias) or self.stuck.any() or self.range_limit is not None)

    def set_bias(self, key: object, delta: np.ndarray | None) -> None:
        """Set (or with None remove) the bias step named ``key`` (SI); ``bias`` is the sum of the steps."""
        if delta is None:
            self._biases.pop(key, None)
        else:
            self._biases[key] = np.asarray(delta, dtype=np.float64)
        self.bias = sum(self._biases.values(), np.zeros(3)) if self._biases else np.zeros(3)
        self._update()

    def set_stuck(self, axis: int, stuck: bool, value: float = 0.0) -> None:
        self.stuck[axis] = stuck
        self.stuck_value[axis] = value
        self._update()

    def set_range_limit(self, limit: float | None) -> None:
        self.range_limit = limit
        self._update()

    def apply(self, x: np.ndarray, lim: np.ndarray | float) -> tuple[np.ndarray, np.ndarray | float]:
        """The faulted measurement and the range to clip it to."""
        if np.any(self.bias):
            x = x + self.bias
            self.biased += 1
        if self.stuck.any():
            x = np.where(self.stuck, self.stuck_value, x)
            self.stuck_samples += 1
        if self.range_limit is not None:
            if np.any(np.abs(x) > self.range_limit):
                self.clipped += 1
            lim = np.minimum(lim, self.range_limit)
        return x, lim


class ImuTruthTap:
    """Caches the exact truth increments of the last trigger interval for both sensors."""

    def __init__(self, trajectory: Trajectory) -> None:
        self.trajectory = trajectory
        self._key: tuple[float, float] | None = None
        self._val: tuple[np.ndarray, np.ndarray] = (np.zeros(3), np.zeros(3))

    def increments(self, t0: float, t1: float) -> tuple[np.ndarray, np.ndarray]:
        if self._key != (t0, t1):
            self._val = self.trajectory.imu_increments(t0, t1)
            self._key = (t0, t1)
        return self._val


class _Ahead:
    """Measured means of the coming trigger intervals of one sensor triad (see :func:`_measure_ahead`).

    ``times[j]`` is the ``(t, t_prev)`` of row ``j``; ``raw[j]`` the measured mean before injected
    faults; ``post[j]`` what the device makes of it without faults (words / codes as ints, and the
    clipped value it remembers). Row ``j`` may be used only while the error model's noise block is
    the one peeked at, at the row ``i0 + j`` (so nothing was drawn in between).
    """

    __slots__ = ("times", "raw", "post", "j", "block", "i0", "stochastic")

    def __init__(self, times: list[tuple[float, float]], raw: np.ndarray, block: np.ndarray | None, i0: int,
                 stochastic: bool) -> None:
        self.times = times
        self.raw = raw
        self.post: list[tuple[tuple[int, int, int], np.ndarray]] = []
        self.j = 1
        self.block = block
        self.i0 = i0
        self.stochastic = stochastic

    def take(self, t: float, t_prev: float, model: "InertialErrorModel", dt: float) -> int:
        """Index of the row for the interval ``(t_prev, t)`` (its noise row consumed), or -1."""
        j = self.j
        if j >= len(self.times) or self.times[j] != (t, t_prev):
            return -1
        if self.stochastic:
            if (model._block is not self.block or model._block_i != self.i0 + j  # noqa: SLF001
                    or abs(dt - model._block_dt) > 1e-9 * dt):  # noqa: SLF001 - next_noise would draw
                return -1
            model._block_i += 1  # noqa: SLF001 - consumed, as next_noise does
        self.j = j + 1
        return j


def _measure_ahead(model: "InertialErrorModel", tap: "ImuTruthTap", t: float, t_prev: float, period: float,
                   temp: "ImuTemperature", gyro: bool) -> tuple[np.ndarray, _Ahead | None]:
    """The measured mean of the interval ``(t_prev, t)`` (pre-fault, exactly :meth:`InertialErrorModel.measure`)
    and the same for the following trigger intervals ``t_j = (k + j) period``, ``t_prev_j = t_j - period``
    computed in one vectorised pass: as many as the current noise block and the trajectory's current
    increment block hold (neither is advanced; rows are bit for bit what the per-interval path gives).

    ``gyro``: the input is the mean angular rate and the g-sensitivity input the mean specific force;
    else (the accelerometers) the input is the mean specific force.
    """
    dt = t - t_prev
    dth, dv = tap.increments(t_prev, t)
    k = round(t / period)
    if k * period != t or t - period != t_prev:  # not the FPGA's trigger grid: no look-ahead
        if gyro:
            return model.measure(dth / dt, dt, temp.at(t), temp.rate_c_per_min, temp.cal_c, dv / dt), None
        return model.measure(dv / dt, dt, temp.at(t), temp.rate_c_per_min, temp.cal_c), None
    noise0 = model.next_noise(dt)
    stochastic = model._stochastic  # noqa: SLF001
    if stochastic:
        block, i0 = model._block, model._block_i - 1  # noqa: SLF001
        n_max = BLOCK - i0
    else:
        block, i0 = None, 0
        n_max = BLOCK
    traj = tap.trajectory
    times = [(t, t_prev)]
    dths, dvs = [dth], [dv]
    for j in range(1, n_max):
        tj = (k + j) * period
        tpj = tj - period
        inc = traj.imu_increments_ready(tpj, tj)
        if inc is None:
            break
        times.append((tj, tpj))
        dths.append(inc[0])
        dvs.append(inc[1])
    n = len(times)
    dts = np.array([a - b for a, b in times])[:, None]
    temps = np.array([temp.at(a) for a, _b in times])
    if gyro:
        x = np.array(dths) / dts
        f = np.array(dvs) / dts
    else:
        x = np.array(dvs) / dts
        f = None
    det = model.deterministic_rows(x, temps, temp.rate_c_per_min, temp.cal_c, f)
    if stochastic:
        noise = np.concatenate([noise0[None, :], block[i0 + 1:i0 + n]])  # type: ignore[index]
    else:
        noise = np.zeros((n, 3))
    raw = det + noise
    return raw[0], (_Ahead(times, raw, block, i0, stochastic) if n > 1 else None)


class Stim210Gyro:
    """A STIM210 in external-trigger mode on an RS422 link.

    Parameters
    ----------
    link : the gyro's serial link to the FPGA GYRO port.
    tap : truth increments.
    errors : the unit's figures (drawn once into an :class:`InertialErrorModel`).
    fmt : datagram format letter (default ``"m"``: rate, counter, latency).
    output : ``"rate"`` (average angular rate) or ``"angle"`` (incremental angle).
    response_delay_s : trigger edge to start of transmission (<= 86 us, TS1524 5.3).
    latency_us : value reported in the latency field.
    temperature : temperature profile (reported in formats with temperature words).
    source : recorded data (:mod:`emulator.devices.recorded`): ``f(t0, t1) -> mean rate (3,) rad/s``
        replaces truth and error model.
    """

    def __init__(self, link: Link, tap: ImuTruthTap, rng: np.random.Generator, errors: GyroErrors | None = None,
                 fmt: str = "m", output: str = "rate", response_delay_s: float = 40e-6,
                 trigger_rate_hz: float = 200.0, latency_us: int = 0, temperature: ImuTemperature | None = None,
                 source=None) -> None:
        self.link = link
        self.tap = tap
        self.rng = rng
        self.err = errors or GyroErrors()
        self.model = gyro_error_model(self.err, rng)
        self.format = Stim210Format(fmt)
        self.output = output
        self.response_delay_s = response_delay_s
        self.latency_us = latency_us
        self.temperature = temperature or ImuTemperature()
        self.source = source
        self.counter = 0
        self.counter_step = int(round(STIM_COUNTER_HZ / trigger_rate_hz))
        self._queued = 0
        self._last_send_t = -math.inf
        self.last_measured = np.zeros(3)
        self._accel_hint: np.ndarray | None = None
        #: injected faults (bias step, stuck axis, reduced range); see :class:`InjectedFaults`
        self.faults = InjectedFaults()
        self.drop_probability = 0.0
        self.datagrams_dropped = 0
        self._drop_rng: np.random.Generator | None = None
        #: look-ahead (:func:`_measure_ahead`): on the trigger grid of ``trigger_rate_hz``, block-wise
        self._period = 1.0 / trigger_rate_hz
        self._look_ahead = source is None
        self._ahead: _Ahead | None = None

    @property
    def turn_on_bias(self) -> np.ndarray:
        return self.model.bias0

    # -- injected faults (emulator.faults) ----------------------------------------------------------
    def set_bias_step(self, key: object, delta_rad_s: np.ndarray | None) -> None:
        """Step the rate bias by ``delta_rad_s`` (3,) rad/s, body axes; ``None`` removes the step ``key``."""
        self.faults.set_bias(key, delta_rad_s)

    def set_stuck_axis(self, axis: int, stuck: bool) -> None:
        """Freeze axis ``axis`` (0..2) at its last output, or release it."""
        self.faults.set_stuck(axis, stuck, float(self.last_measured[axis]))

    def set_range_limit(self, limit_rad_s: float | None) -> None:
        """Clip every axis at ``limit_rad_s`` (a gain fault; None restores the full range)."""
        self.faults.set_range_limit(limit_rad_s)

    def set_datagram_drop(self, probability: float, rng: np.random.Generator | None = None) -> None:
        """Skip each datagram with ``probability`` (0 turns it off); the counter still advances."""
        self.drop_probability = probability
        if rng is not None:
            self._drop_rng = rng

    def trigger(self, t: float, t_prev: float) -> None:
        """External-trigger falling edge at ``t`` (scenario s); interval started at ``t_prev``."""
        dt = t - t_prev
        temp = self.temperature
        t_c = temp.at(t)
        if self.source is not None:
            rec = self.source(t_prev, t)
            if rec is None:  # outside the record: silent (the FPGA flags the missing datagram)
                return
            rate = np.asarray(rec, dtype=np.float64)
        else:
            ahead = self._ahead
            j = ahead.take(t, t_prev, self.model, dt) if ahead is not None else -1
            if j >= 0 and not self.faults.active:  # the common case: all done in the look-ahead pass
                gw, self.last_measured = ahead.post[j]  # type: ignore[union-attr]
                self._transmit(t, t_c, gw)
                return
            if j >= 0:
                rate = ahead.raw[j]  # type: ignore[union-attr]
            elif self._look_ahead:
                rate, ahead = _measure_ahead(self.model, self.tap, t, t_prev, self._period, temp, True)
                self._ahead = ahead
                if ahead is not None:
                    ahead.post = self._words(ahead)
            else:
                dtheta, dv = self.tap.increments(t_prev, t)
                rate = self.model.measure(dtheta / dt, dt, t_c, temp.rate_c_per_min, temp.cal_c, dv / dt)
        lim = self.err.range_dps * DEG
        if self.faults.active:
            rate, lim = self.faults.apply(rate, lim)
        rate = np.clip(rate, -lim, lim)
        self.last_measured = rate
        if self.output == "rate":
            words = np.round(rate / (GYRO_RATE_LSB_DPS * DEG))
        else:
            words = np.round(rate * dt / (GYRO_ANGLE_LSB_DEG * DEG))
        words = np.clip(words, -0x800000, 0x7FFFFF).astype(np.int64)
        self._transmit(t, t_c, (int(words[0]), int(words[1]), int(words[2])))

    def _words(self, ahead: _Ahead) -> list[tuple[tuple[int, int, int], np.ndarray]]:
        """The look-ahead rows as the fault-free path of :meth:`trigger` turns them into words."""
        lim = self.err.range_dps * DEG
        rate = np.clip(ahead.raw, -lim, lim)
        if self.output == "rate":
            words = np.round(rate / (GYRO_RATE_LSB_DPS * DEG))
        else:
            dts = np.array([a - b for a, b in ahead.times])[:, None]
            words = np.round(rate * dts / (GYRO_ANGLE_LSB_DEG * DEG))
        words = np.clip(words, -0x800000, 0x7FFFFF).astype(np.int64)
        return [(tuple(w), r) for w, r in zip(words.tolist(), rate)]  # type: ignore[misc]

    def _transmit(self, t: float, t_c: float, gyro_words: tuple[int, int, int]) -> None:
        self.counter = (self.counter + self.counter_step) & 0xFF
        tw = int(round(t_c / TEMP_LSB_DEGC))
        d = StimDatagram(
            ident=self.format.ident,
            gyro=gyro_words,
            status=0,
            counter=self.counter,
            latency_us=self.latency_us,
            temperature=(tw, tw, tw),
        )
        frame = self.format.build(d)
        if self.drop_probability > 0.0:
            rng = self._drop_rng if self._drop_rng is not None else self.rng
            if rng.random() < self.drop_probability:
                self.datagrams_dropped += 1
                return
        # the gyro is its link's only writer, in time order: decide the transmission now (one timer,
        # the delivery, instead of two)
        t_send = t + self.response_delay_s
        self.link.send_at(t_send, frame)
        self._queued += 1
        self._last_send_t = t_send

    @property
    def datagrams_sent(self) -> int:
        """Datagrams whose transmission has started (one may be queued for its response delay)."""
        return self._queued - (1 if self._last_send_t > self.link.loop.time() else 0)


class AnalogAccelerometers:
    """Three analog accelerometers behind the FPGA's 24-bit oversampling ADC.

    ``source`` (recorded data): ``f(t0, t1) -> mean specific force (3,) m/s^2`` replaces truth and errors.
    """

    def __init__(self, tap: ImuTruthTap, rng: np.random.Generator, errors: AccelErrors | None = None,
                 temperature: ImuTemperature | None = None, source=None, trigger_rate_hz: float = 200.0) -> None:
        self.tap = tap
        self.rng = rng
        self.err = e = errors or AccelErrors()
        self.model = accel_error_model(e, rng)
        self.temperature = temperature or ImuTemperature()
        self.source = source
        self.last_measured = np.zeros(3)
        self._range = np.array(e.range_g)
        self._vpg = np.array(e.volts_per_g)
        #: injected faults (bias step, stuck axis, reduced range); see :class:`InjectedFaults`
        self.faults = InjectedFaults()
        #: look-ahead (:func:`_measure_ahead`) on the FPGA's trigger grid
        self._period = 1.0 / trigger_rate_hz
        self._look_ahead = source is None
        self._ahead: _Ahead | None = None

    @property
    def turn_on_bias(self) -> np.ndarray:
        return self.model.bias0

    # -- injected faults (emulator.faults) ----------------------------------------------------------
    def set_bias_step(self, key: object, delta_mps2: np.ndarray | None) -> None:
        """Step the bias by ``delta_mps2`` (3,) m/s^2, body axes; ``None`` removes the step ``key``."""
        self.faults.set_bias(key, delta_mps2)

    def set_stuck_axis(self, axis: int, stuck: bool) -> None:
        """Freeze axis ``axis`` (0..2) at its last output, or release it."""
        self.faults.set_stuck(axis, stuck, float(self.last_measured[axis]))

    def set_range_limit(self, limit_mps2: float | None) -> None:
        """Clip every axis at ``limit_mps2`` (None restores the parts' ranges)."""
        self.faults.set_range_limit(limit_mps2)

    def sample(self, t: float, t_prev: float) -> tuple[int, int, int]:
        """ADC codes of the mean specific force over ``[t_prev, t]``."""
        dt = t - t_prev
        if self.source is not None:
            f = np.asarray(self.source(t_prev, t), dtype=np.float64)
        else:
            ahead = self._ahead
            j = ahead.take(t, t_prev, self.model, dt) if ahead is not None else -1
            if j >= 0 and not self.faults.active:  # the common case: all done in the look-ahead pass
                codes, self.last_measured = ahead.post[j]  # type: ignore[union-attr]
                return codes
            temp = self.temperature
            if j >= 0:
                f = ahead.raw[j]  # type: ignore[union-attr]
            elif self._look_ahead:
                f, ahead = _measure_ahead(self.model, self.tap, t, t_prev, self._period, temp, False)
                self._ahead = ahead
                if ahead is not None:
                    ahead.post = self._codes(ahead)
            else:
                _, dv = self.tap.increments(t_prev, t)
                f = self.model.measure(dv / dt, dt, temp.at(t), temp.rate_c_per_min, temp.cal_c)
        rng_g = self._range
        if self.faults.active:
            f, lim = self.faults.apply(f, self._range * G_STD)
            rng_g = lim / G_STD
        f_g = np.clip(f / G_STD, -rng_g, rng_g)
        self.last_measured = f_g * G_STD
        volts = f_g * self._vpg
        codes = np.clip(np.round(volts / ADC_VOLTS_PER_LSB), -ADC_CODE_MAX - 1, ADC_CODE_MAX).astype(np.int64)
        return int(codes[0]), int(codes[1]), int(codes[2])

    def _codes(self, ahead: _Ahead) -> list[tuple[tuple[int, int, int], np.ndarray]]:
        """The look-ahead rows as the fault-free path of :meth:`sample` turns them into ADC codes."""
        f_g = np.clip(ahead.raw / G_STD, -self._range, self._range)
        volts = f_g * self._vpg
        codes = np.clip(np.round(volts / ADC_VOLTS_PER_LSB), -ADC_CODE_MAX - 1, ADC_CODE_MAX).astype(np.int64)
        return [(tuple(c), m) for c, m in zip(codes.tolist(), f_g * G_STD)]  # type: ignore[misc]


def allan_deviation(y: np.ndarray, dt: float, taus: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Overlapping Allan deviation of rate samples ``y`` (n,) or (n, k) taken every ``dt``.

    Returns the cluster times actually used (multiples of ``dt``) and the deviations.
    """
    y = np.asarray(y, dtype=np.float64)
    theta = np.concatenate([np.zeros((1,) + y.shape[1:]), np.cumsum(y, axis=0) * dt])
    n = len(y)
    ms = np.unique(np.maximum(1, np.round(np.asarray(taus) / dt).astype(int)))
    ms = ms[ms < n // 2]
    out = []
    for m in ms:
        d = theta[2 * m:] - 2 * theta[m:-m] + theta[:-2 * m]
        out.append(np.sqrt(np.mean(d * d, axis=0) / (2.0 * (m * dt) ** 2)))
    return ms * dt, np.array(out)

