"""Inertial sensors: the STIM210 gyro (RS422 datagrams) and the analog accelerometers.

Both sample the same truth (:class:`ImuTruthTap`) over the FPGA's trigger interval
``[t_prev, t]``: the STIM210 in *average angular rate* output (the mean rate over the
interval, TS1524 section 7.5.2.2 "average angular rate") and the accelerometers through the
FPGA's oversampling ADC, whose boxcar average over the same interval is the mean specific
force. Errors (``shared/reference`` figures from the base paper, DESIGN.md section 2):

* gyro: turn-on bias drawn from the bias repeatability (1 sigma), a first-order Gauss-Markov
  bias with the bias-stability sigma, angle random walk (STIM210 datasheet 0.15 deg/sqrt(h)),
  +-400 deg/s saturation, 2^-14 deg/s quantization (24-bit word);
* accelerometers: turn-on bias (repeatability), Gauss-Markov bias (stability), white noise
  (noise density), range saturation, then volts (V/g) and the 24-bit ADC code.

The paper's "< X" bias figures are limits that a unit meets; they are modelled as 3 sigma
(docs/decisions.md), so ``sigma = X / 3``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from protocols.imu_frame import ACCEL_VOLTS_PER_G, ADC_CODE_MAX, ADC_VOLTS_PER_LSB
from protocols.stim import GYRO_ANGLE_LSB_DEG, GYRO_RATE_LSB_DPS, STIM_COUNTER_HZ, Stim210Format, StimDatagram

from ..links.base import Link
from ..world.trajectory import Trajectory

__all__ = ["GyroErrors", "AccelErrors", "ImuTruthTap", "Stim210Gyro", "AnalogAccelerometers"]

DEG = math.pi / 180.0
DPH = DEG / 3600.0
G_STD = 9.80665


#: Base-paper limits (DESIGN.md section 2); the models use them as 3 sigma.
PAPER_GYRO_BIAS_REPEATABILITY_DPH = 40.0
PAPER_GYRO_BIAS_STABILITY_DPH = 20.0
PAPER_ACCEL_BIAS_REPEATABILITY_MG = (7.0, 7.0, 7.0)
PAPER_ACCEL_BIAS_STABILITY_MG = (3.0, 4.0, 4.0)


@dataclass
class GyroErrors:
    """STIM210 error figures, 1 sigma (units in the names)."""

    arw_deg_rt_h: float = 0.15
    bias_repeatability_deg_h: float = PAPER_GYRO_BIAS_REPEATABILITY_DPH / 3.0
    bias_instability_deg_h: float = PAPER_GYRO_BIAS_STABILITY_DPH / 3.0
    bias_corr_time_s: float = 600.0
    range_dps: float = 400.0


@dataclass
class AccelErrors:
    """Accelerometer error figures per axis, 1 sigma (x: MS9030, y/z: the +-25 g parts)."""

    bias_repeatability_mg: tuple[float, float, float] = tuple(x / 3.0 for x in PAPER_ACCEL_BIAS_REPEATABILITY_MG)  # type: ignore[assignment]
    bias_instability_mg: tuple[float, float, float] = tuple(x / 3.0 for x in PAPER_ACCEL_BIAS_STABILITY_MG)  # type: ignore[assignment]
    bias_corr_time_s: float = 600.0
    noise_ug_rt_hz: float = 100.0
    range_g: tuple[float, float, float] = (30.0, 25.0, 25.0)
    volts_per_g: tuple[float, float, float] = field(default_factory=lambda: ACCEL_VOLTS_PER_G)


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


def _gm_step(x: np.ndarray, sigma: np.ndarray, tau: float, dt: float, rng: np.random.Generator) -> np.ndarray:
    a = math.exp(-dt / tau)
    return a * x + np.sqrt(1.0 - a * a) * sigma * rng.standard_normal(3)


class Stim210Gyro:
    """A STIM210 in external-trigger mode on an RS422 link.

    Parameters
    ----------
    link : the gyro's serial link to the FPGA GYRO port.
    tap : truth increments.
    fmt : datagram format letter (default ``"m"``: rate, counter, latency).
    output : ``"rate"`` (average angular rate) or ``"angle"`` (incremental angle).
    response_delay_s : trigger edge to start of transmission (<= 86 us, TS1524 5.3).
    latency_us : value reported in the latency field.
    """

    def __init__(self, link: Link, tap: ImuTruthTap, rng: np.random.Generator, errors: GyroErrors | None = None,
                 fmt: str = "m", output: str = "rate", response_delay_s: float = 40e-6,
                 trigger_rate_hz: float = 200.0, latency_us: int = 0) -> None:
        self.link = link
        self.tap = tap
        self.rng = rng
        self.err = errors or GyroErrors()
        self.format = Stim210Format(fmt)
        self.output = output
        self.response_delay_s = response_delay_s
        self.latency_us = latency_us
        self.counter = 0
        self.counter_step = int(round(STIM_COUNTER_HZ / trigger_rate_hz))
        e = self.err
        self.turn_on_bias = rng.standard_normal(3) * e.bias_repeatability_deg_h * DPH
        self.gm_bias = rng.standard_normal(3) * e.bias_instability_deg_h * DPH
        self._t_prev: float | None = None
        self.datagrams_sent = 0
        self.last_measured = np.zeros(3)

    def trigger(self, t: float, t_prev: float) -> None:
        """External-trigger falling edge at ``t`` (scenario s); interval started at ``t_prev``."""
        dt = t - t_prev
        dtheta, _ = self.tap.increments(t_prev, t)
        e = self.err
        self.gm_bias = _gm_step(self.gm_bias, np.full(3, e.bias_instability_deg_h * DPH), e.bias_corr_time_s, dt, self.rng)
        arw = e.arw_deg_rt_h * DEG / 60.0  # rad/sqrt(s)
        rate = dtheta / dt + self.turn_on_bias + self.gm_bias + self.rng.standard_normal(3) * (arw / math.sqrt(dt))
        lim = e.range_dps * DEG
        rate = np.clip(rate, -lim, lim)
        self.last_measured = rate
        if self.output == "rate":
            words = np.round(rate / (GYRO_RATE_LSB_DPS * DEG))
        else:
            words = np.round(rate * dt / (GYRO_ANGLE_LSB_DEG * DEG))
        words = np.clip(words, -0x800000, 0x7FFFFF).astype(np.int64)
        self.counter = (self.counter + self.counter_step) & 0xFF
        d = StimDatagram(
            ident=self.format.ident,
            gyro=(int(words[0]), int(words[1]), int(words[2])),
            status=0,
            counter=self.counter,
            latency_us=self.latency_us,
            temperature=(25 * 256, 25 * 256, 25 * 256),
        )
        frame = self.format.build(d)
        self.link.loop.call_at(t + self.response_delay_s, self._send, frame)

    def _send(self, frame: bytes) -> None:
        self.link.send(frame)
        self.datagrams_sent += 1


class AnalogAccelerometers:
    """Three analog accelerometers behind the FPGA's 24-bit oversampling ADC."""

    def __init__(self, tap: ImuTruthTap, rng: np.random.Generator, errors: AccelErrors | None = None) -> None:
        self.tap = tap
        self.rng = rng
        self.err = e = errors or AccelErrors()
        self.turn_on_bias = rng.standard_normal(3) * np.array(e.bias_repeatability_mg) * 1e-3 * G_STD
        self._gm_sigma = np.array(e.bias_instability_mg) * 1e-3 * G_STD
        self.gm_bias = rng.standard_normal(3) * self._gm_sigma
        self.last_measured = np.zeros(3)

    def sample(self, t: float, t_prev: float) -> tuple[int, int, int]:
        """ADC codes of the mean specific force over ``[t_prev, t]``."""
        dt = t - t_prev
        _, dv = self.tap.increments(t_prev, t)
        e = self.err
        self.gm_bias = _gm_step(self.gm_bias, self._gm_sigma, e.bias_corr_time_s, dt, self.rng)
        # white noise of density rho over the Nyquist band of the trigger rate: sigma = rho sqrt(fs/2)
        sigma = e.noise_ug_rt_hz * 1e-6 * G_STD * math.sqrt(0.5 / dt)
        f = dv / dt + self.turn_on_bias + self.gm_bias + self.rng.standard_normal(3) * sigma
        rng_g = np.array(e.range_g)
        f_g = np.clip(f / G_STD, -rng_g, rng_g)
        self.last_measured = f_g * G_STD
        volts = f_g * np.array(e.volts_per_g)
        codes = np.clip(np.round(volts / ADC_VOLTS_PER_LSB), -ADC_CODE_MAX - 1, ADC_CODE_MAX).astype(np.int64)
        return int(codes[0]), int(codes[1]), int(codes[2])
