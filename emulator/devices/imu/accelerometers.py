"""The analog accelerometers, sampled by the FPGA's oversampling 24-bit ADC."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from protocols.constants import G_STD
from protocols.imu_frame import ADC_CODE_MAX, ADC_VOLTS_PER_LSB

from .error_model import AccelErrors, ImuTemperature, accel_error_model
from .injected import FaultableTriad, InjectedFaults
from .lookahead import Ahead, ImuTruthTap, measure_ahead, sensor_input

__all__ = ["AnalogAccelerometers"]


class AnalogAccelerometers(FaultableTriad):
    """Three analog accelerometers behind the FPGA's 24-bit oversampling ADC.

    ``source`` (recorded data): ``f(t0, t1) -> mean specific force (3,) m/s^2`` replaces truth and errors.
    """

    def __init__(self, tap: ImuTruthTap, rng: np.random.Generator, errors: AccelErrors | None = None,
                 temperature: ImuTemperature | None = None, source: Callable[[float, float], Any] | None = None,
                 trigger_rate_hz: float = 200.0) -> None:
        self.tap = tap
        self.rng = rng
        self.err = e = errors or AccelErrors()
        self.model = accel_error_model(e, rng)
        #: vibration rectification per axis, 1/(m/s^2): a vibration v adds vre * v^2 (mean vre g_rms^2)
        vre = np.asarray(e.vre_ug_per_g2, dtype=np.float64) * 1e-6 / G_STD
        self.vre: np.ndarray | None = vre if np.any(vre) else None
        self.temperature = temperature or ImuTemperature()
        self.source = source
        self.last_measured = np.zeros(3)
        self._range = np.array(e.range_g)
        self._vpg = np.array(e.volts_per_g)
        #: injected faults (bias step, stuck axis, reduced range); see :class:`InjectedFaults`
        self.faults = InjectedFaults()
        #: look-ahead (:func:`measure_ahead`) on the FPGA's trigger grid
        self._period = 1.0 / trigger_rate_hz
        self._look_ahead = source is None
        self._ahead: Ahead | None = None

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
                f, ahead = measure_ahead(self.model, self.tap, t, t_prev, self._period, temp, False, self.vre)
                self._ahead = ahead
                if ahead is not None:
                    ahead.post = self._codes(ahead)
            else:
                dth, dv = self.tap.increments(t_prev, t)
                x, _f = sensor_input(self.tap, t, dt, dth, dv, False, self.vre)
                f = self.model.measure(x, dt, temp.at(t), temp.rate_at(t), temp.cal_c)
        rng_g: np.ndarray | float = self._range
        if self.faults.active:
            f, lim = self.faults.apply(f, self._range * G_STD)
            rng_g = lim / G_STD
        f_g = np.clip(f / G_STD, -rng_g, rng_g)
        self.last_measured = f_g * G_STD
        volts = f_g * self._vpg
        codes = np.clip(np.round(volts / ADC_VOLTS_PER_LSB), -ADC_CODE_MAX - 1, ADC_CODE_MAX).astype(np.int64)
        return int(codes[0]), int(codes[1]), int(codes[2])

    def _codes(self, ahead: Ahead) -> list[tuple[tuple[int, int, int], np.ndarray]]:
        """The look-ahead rows as the fault-free path of :meth:`sample` turns them into ADC codes."""
        f_g = np.clip(ahead.raw / G_STD, -self._range, self._range)
        volts = f_g * self._vpg
        codes = np.clip(np.round(volts / ADC_VOLTS_PER_LSB), -ADC_CODE_MAX - 1, ADC_CODE_MAX).astype(np.int64)
        return [(tuple(c), m) for c, m in zip(codes.tolist(), f_g * G_STD)]
