"""The STIM210 gyro in external-trigger mode: datagrams on its RS422 link."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from protocols.constants import DEG
from protocols.stim import (
    GYRO_ANGLE_LSB_DEG,
    GYRO_RATE_LSB_DPS,
    STIM_COUNTER_HZ,
    TEMP_LSB_DEGC,
    Stim210Format,
    overload_status,
)

from ...links.base import Link
from .error_model import GyroErrors, ImuTemperature, gyro_error_model
from .injected import FaultableTriad, InjectedFaults
from .lookahead import Ahead, ImuTruthTap, delayed_interval, measure_ahead, sensor_input

__all__ = ["LP_FILTER_SETTINGS_HZ", "Stim210Gyro", "group_delay_s"]

#: The STIM210's selectable low-pass filter -3 dB frequencies, Hz (datasheet; 0 here means no filter).
LP_FILTER_SETTINGS_HZ = (16.0, 33.0, 66.0, 131.0, 262.0)


def group_delay_s(f_c_hz: float) -> float:
    """Group delay at DC of a 2nd-order Butterworth low-pass with -3 dB frequency ``f_c_hz``: sqrt(2)/(2 pi f_c)."""
    return 0.0 if f_c_hz <= 0 else math.sqrt(2.0) / (2.0 * math.pi * f_c_hz)


class Stim210Gyro(FaultableTriad):
    """A STIM210 in external-trigger mode on an RS422 link.

    Parameters
    ----------
    link : the gyro's serial link to the FPGA GYRO port.
    tap : truth increments.
    errors : the unit's figures (drawn once into an :class:`InertialErrorModel`).
    fmt : datagram format letter (default ``"m"``: rate, counter, latency).
    output : ``"rate"`` (average angular rate) or ``"angle"`` (incremental angle).
    response_delay_s : trigger edge to start of transmission (<= 86 us, TS1524 5.3).
    latency_us : value reported in the latency field; None: from the low-pass setting (below).
    lp_filter_hz : the STIM210's low-pass filter setting, -3 dB frequency (16, 33, 66, 131 or 262 Hz; 0 = none).
        The filtered output lags the motion by the filter's group delay, modelled as that of a 2nd-order
        Butterworth low-pass at DC, ``sqrt(2) / (2 pi f_c)`` (0.86 ms at 262 Hz, 14 ms at 16 Hz; docs/sensors.md):
        each datagram carries the mean rate over the trigger interval shifted back by that delay, and its
        latency field reports the delay plus the response delay (sampling to start of transmission); without a
        filter it reports the response delay alone.
    temperature : temperature profile (reported in formats with temperature words).
    source : recorded data (:mod:`emulator.devices.recorded`): ``f(t0, t1) -> mean rate (3,) rad/s``
        replaces truth and error model.
    """

    def __init__(self, link: Link, tap: ImuTruthTap, rng: np.random.Generator, errors: GyroErrors | None = None,
                 fmt: str = "m", output: str = "rate", response_delay_s: float = 40e-6,
                 trigger_rate_hz: float = 200.0, latency_us: int | None = None,
                 temperature: ImuTemperature | None = None, source: Callable[[float, float], Any] | None = None,
                 lp_filter_hz: float = 0.0) -> None:
        self.link = link
        self.tap = tap
        self.rng = rng
        self.err = errors or GyroErrors()
        self.model = gyro_error_model(self.err, rng)
        self.format = Stim210Format(fmt)
        self.output = output
        self.response_delay_s = response_delay_s
        self.group_delay_s = group_delay_s(lp_filter_hz)
        # TS1524: the field is the time from the sampling of the data to the start of the transmission, so even
        # without a low-pass filter (group delay 0) it carries the response delay, never 0 (issue 37)
        self.latency_us = (latency_us if latency_us is not None
                           else round((self.group_delay_s + response_delay_s) * 1e6))
        self.temperature = temperature or ImuTemperature()
        self.source = source
        self.counter = 0
        self.counter_step = round(STIM_COUNTER_HZ / trigger_rate_hz)
        self._queued = 0
        self._last_send_t = -math.inf
        self.last_measured = np.zeros(3)
        self._accel_hint: np.ndarray | None = None
        #: injected faults (bias step, stuck axis, reduced range); see :class:`InjectedFaults`
        self.faults = InjectedFaults()
        self.drop_probability = 0.0
        self.datagrams_dropped = 0
        self._drop_rng: np.random.Generator | None = None
        #: look-ahead (:func:`measure_ahead`): on the trigger grid of ``trigger_rate_hz``, block-wise
        self._period = 1.0 / trigger_rate_hz
        self._look_ahead = source is None
        self._ahead: Ahead | None = None

    def set_datagram_drop(self, probability: float, rng: np.random.Generator | None = None) -> None:
        """Skip each datagram with ``probability`` (0 turns it off); the counter still advances."""
        self.drop_probability = probability
        if rng is not None:
            self._drop_rng = rng

    def trigger(self, t: float, t_prev: float) -> None:
        """External-trigger falling edge at ``t`` (scenario s); interval started at ``t_prev``."""
        temp = self.temperature
        t_edge, t_prev_edge = t, t_prev
        if self.group_delay_s > 0.0:  # the filtered output describes the motion one group delay ago
            t, t_prev = delayed_interval(t, t_prev, self.group_delay_s)
        dt = t - t_prev
        if self.source is not None:
            rec = self.source(t_prev, t)
            if rec is None:  # outside the record: silent (the FPGA flags the missing datagram)
                return
            rate = np.asarray(rec, dtype=np.float64)
        else:
            ahead = self._ahead
            j = ahead.take(t, t_prev, self.model, dt) if ahead is not None else -1
            if j >= 0 and not self.faults.active:  # the common case: all done in the look-ahead pass
                post = ahead.post  # type: ignore[union-attr]
                if j < len(post):  # the row's datagram, if its edge and counter are the ones due
                    frame, clipped, t_row, counter = post[j]
                    if t_row == t_edge and counter == (self.counter + self.counter_step) & 0xFF:
                        self.last_measured = clipped
                        self.counter = counter
                        self._send(t_edge, frame)
                        return
            if j >= 0:
                rate = ahead.raw[j]  # type: ignore[union-attr]
            elif self._look_ahead:
                rate, ahead = measure_ahead(self.model, self.tap, t_edge, t_prev_edge, self._period, temp, True,
                                            delay=self.group_delay_s)
                self._ahead = ahead
                if ahead is not None:
                    ahead.post = self._window(ahead, t_edge)
            else:
                dtheta, dv = self.tap.increments(t_prev, t)
                x, f_b = sensor_input(self.tap, t, dt, dtheta, dv, True, None)
                rate = self.model.measure(x, dt, temp.at(t), temp.rate_at(t), temp.cal_c, f_b)  # as measure_ahead
        lim: np.ndarray | float = self.err.range_dps * DEG
        if self.faults.active:
            rate, lim = self.faults.apply(rate, lim)
        counter = (self.counter + self.counter_step) & 0xFF
        frame, clipped = self._datagrams(rate[None, :], lim, dt, (temp.at(t_edge),), (counter,))
        self.last_measured = clipped[0]
        self.counter = counter
        self._send(t_edge, frame)

    def _datagrams(self, rate: np.ndarray, lim: np.ndarray | float, dt: np.ndarray | float,
                   temps_c: Sequence[float], counters: Sequence[int]) -> tuple[bytes, np.ndarray]:
        """The datagrams of ``n`` samples, back to back, and the clipped rates: the one algorithm of both the
        per-trigger path (a window of one) and the look-ahead window.

        ``rate`` (n, 3) rad/s, the measured means before saturation; ``lim`` rad/s, the range (scalar or per
        axis); ``dt`` s, the measured intervals (scalar or (n, 1); the incremental-angle output integrates over
        it); ``temps_c`` degC, the temperature at each trigger edge; ``counters`` the datagram counters.
        Per axis, the unit saturates and says so (STATUS overload bits, TS1524 Table 5-23,
        :func:`protocols.stim.overload_status`)."""
        over = np.abs(rate) > lim
        clipped = np.clip(rate, -lim, lim)
        if self.output == "rate":
            words = np.round(clipped / (GYRO_RATE_LSB_DPS * DEG))
        else:
            words = np.round(clipped * dt / (GYRO_ANGLE_LSB_DEG * DEG))
        words = np.clip(words, -0x800000, 0x7FFFFF).astype(np.int64)
        status = [overload_status(*o) if any(o) else 0 for o in over.tolist()] if over.any() else (0,) * len(rate)
        return self._encode(words.tolist(), status, counters, temps_c), clipped

    def _encode(self, words: list[list[int]], status: Sequence[int], counters: Sequence[int],
                temps_c: Sequence[float]) -> bytes:
        """The datagrams of the rows (s24 gyro words, STATUS bytes, counters, temperatures degC), back to back:
        one :meth:`~protocols.stim.Stim210Format.build_window`."""
        tws = [(tw, tw, tw) for tw in (round(t_c / TEMP_LSB_DEGC) for t_c in temps_c)]
        return self.format.build_window(words, status, counters, (self.latency_us,) * len(words), tws)

    def _window(self, ahead: Ahead, t_edge: float) -> list[tuple[bytes, np.ndarray, float, int]]:
        """The look-ahead rows as fault-free datagrams (:meth:`_datagrams` over the window), each with its
        clipped rate, the trigger edge it answers (s) and its counter: ``(frame, clipped, t_edge, counter)``.
        Row 0 answers ``t_edge``, row ``j`` the ``j``-th trigger of the grid after it; the counters continue
        from the present one. :meth:`trigger` uses a row only when its edge and counter are the ones due."""
        n = len(ahead.times)
        k = round(t_edge / self._period)
        edges = [t_edge] + [(k + j) * self._period for j in range(1, n)]
        temp = self.temperature
        temps = [temp.at(e) for e in edges] if "temperature" in self.format.groups else [0.0] * n
        step, c0 = self.counter_step, self.counter
        counters = [(c0 + (j + 1) * step) & 0xFF for j in range(n)]
        dts = np.array([a - b for a, b in ahead.times])[:, None]
        frames, clipped = self._datagrams(ahead.raw, self.err.range_dps * DEG, dts, temps, counters)
        size = self.format.length
        return [(frames[j * size:(j + 1) * size], clipped[j], edges[j], counters[j]) for j in range(n)]

    def _send(self, t: float, frame: bytes) -> None:
        """Put one datagram on the line ``response_delay_s`` after the trigger at ``t`` (or drop it, counted)."""
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
