"""The STIM210 gyro in external-trigger mode: datagrams on its RS422 link."""

from __future__ import annotations

import math
from collections.abc import Callable
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
        t_c = temp.at(t)
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
                gw, self.last_measured, status = ahead.post[j]  # type: ignore[union-attr]
                self._transmit(t_edge, t_c, gw, status)
                return
            if j >= 0:
                rate = ahead.raw[j]  # type: ignore[union-attr]
            elif self._look_ahead:
                rate, ahead = measure_ahead(self.model, self.tap, t_edge, t_prev_edge, self._period, temp, True,
                                            delay=self.group_delay_s)
                self._ahead = ahead
                if ahead is not None:
                    ahead.post = self._words(ahead)
            else:
                dtheta, dv = self.tap.increments(t_prev, t)
                x, f_b = sensor_input(self.tap, t, dt, dtheta, dv, True, None)
                rate = self.model.measure(x, dt, temp.at(t), temp.rate_at(t), temp.cal_c, f_b)  # as measure_ahead
        lim: np.ndarray | float = self.err.range_dps * DEG
        if self.faults.active:
            rate, lim = self.faults.apply(rate, lim)
        over = np.abs(rate) > lim  # per axis: the unit saturates and says so (STATUS overload, TS1524 Table 5-23)
        rate = np.clip(rate, -lim, lim)
        self.last_measured = rate
        if self.output == "rate":
            words = np.round(rate / (GYRO_RATE_LSB_DPS * DEG))
        else:
            words = np.round(rate * dt / (GYRO_ANGLE_LSB_DEG * DEG))
        words = np.clip(words, -0x800000, 0x7FFFFF).astype(np.int64)
        status = overload_status(bool(over[0]), bool(over[1]), bool(over[2])) if over.any() else 0
        self._transmit(t_edge, t_c, (int(words[0]), int(words[1]), int(words[2])), status)

    def _words(self, ahead: Ahead) -> list[tuple[tuple[int, int, int], np.ndarray, int]]:
        """The look-ahead rows as the fault-free path of :meth:`trigger` turns them into words and STATUS bytes."""
        lim = self.err.range_dps * DEG
        over = np.abs(ahead.raw) > lim
        rate = np.clip(ahead.raw, -lim, lim)
        if self.output == "rate":
            words = np.round(rate / (GYRO_RATE_LSB_DPS * DEG))
        else:
            dts = np.array([a - b for a, b in ahead.times])[:, None]
            words = np.round(rate * dts / (GYRO_ANGLE_LSB_DEG * DEG))
        words = np.clip(words, -0x800000, 0x7FFFFF).astype(np.int64)
        status = [overload_status(*o) if any(o) else 0 for o in over.tolist()]
        return [(tuple(w), r, st) for w, r, st in zip(words.tolist(), rate, status)]

    def _transmit(self, t: float, t_c: float, gyro_words: tuple[int, int, int], status: int = 0) -> None:
        """Send one datagram: ``gyro_words`` (s24), ``status`` the STATUS byte (:class:`protocols.stim.StimStatus`;
        the overload bits when an axis exceeded the range)."""
        self.counter = (self.counter + self.counter_step) & 0xFF
        tw = round(t_c / TEMP_LSB_DEGC)
        # the bytes of StimDatagram(ident, gyro_words, status, counter, latency, (tw, tw, tw)) without the object
        self._send(t, self.format.build_values(gyro_words, status, self.counter, self.latency_us, (tw, tw, tw)))

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
