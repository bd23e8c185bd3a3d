"""The look-ahead: the measured means of the coming trigger intervals, computed in one vectorised pass.

Both inertial devices sample the same truth (:class:`ImuTruthTap`) on the FPGA's trigger grid; instead of one
error-model call per interval, :func:`measure_ahead` evaluates as many intervals as the error model's current
noise block and the trajectory's current increment block hold, bit for bit what the per-interval path gives,
and :class:`Ahead` hands the rows out while nothing else drew from the noise block.
"""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np

from ...world.trajectory import Trajectory
from ...world.vibration import VibrationModel
from .error_model import BLOCK, ImuTemperature, InertialErrorModel

__all__ = ["Ahead", "ImuTruthTap", "TruthTap", "delayed_interval", "measure_ahead", "sensor_input"]


class TruthTap(Protocol):
    """What a sensor reads of the truth (:class:`ImuTruthTap`, or a test's stand-in): the exact increments of a
    trigger interval and the vibration at its end. A protocol, so the compiled path (docs/performance.md 5.5)
    checks no class at the call."""

    def increments(self, t0: float, t1: float) -> tuple[np.ndarray, np.ndarray]: ...

    def vibration_at(self, t: float) -> np.ndarray | None: ...


class ImuTruthTap:
    """Caches the exact truth increments of the last trigger interval for both sensors, and holds the world's
    vibration (:class:`~emulator.world.vibration.VibrationModel`, None: none) that both sensors feel."""

    def __init__(self, trajectory: Trajectory, vibration: VibrationModel | None = None) -> None:
        self.trajectory = trajectory
        self.vibration = vibration
        self._key: tuple[float, float] | None = None
        self._val: tuple[np.ndarray, np.ndarray] = (np.zeros(3), np.zeros(3))

    def increments(self, t0: float, t1: float) -> tuple[np.ndarray, np.ndarray]:
        if self._key != (t0, t1):
            self._val = self.trajectory.imu_increments(t0, t1)
            self._key = (t0, t1)
        return self._val

    def vibration_at(self, t: float) -> np.ndarray | None:
        """The vibration acceleration (3,) m/s^2, body axes, of the interval ending at ``t`` (None: none)."""
        return None if self.vibration is None else self.vibration.at(t)


def delayed_interval(t: float, t_prev: float, delay: float) -> tuple[float, float]:
    """The interval ``(t, t_prev)`` (s) a sensor whose output lags the motion by ``delay`` (s) describes at the
    trigger edges ``(t, t_prev)``: both moved back by ``delay``.

    An interval that would reach before the scenario start is the first ``t - t_prev`` seconds of the scenario
    instead: the box was in its initial state before ``t = 0`` (at rest, or in the motion of its first segment),
    so every datagram, the first ones included, integrates a whole trigger interval. (Clipping both ends at 0
    left the first datagram a 1 ns interval, whose white noise is ``sqrt(5 ms / 1 ns)`` ~ 2200 times that of a
    200 Hz datagram: 80-140 deg/s at the STIM210's ARW, with STATUS 0.)"""
    t_prev_d = t_prev - delay
    if t_prev_d >= 0.0:
        return t - delay, t_prev_d
    return t - t_prev, 0.0


def sensor_input(tap: TruthTap, t: float, dt: float, dth: np.ndarray, dv: np.ndarray, gyro: bool,
                 vre: np.ndarray | None) -> tuple[np.ndarray, np.ndarray | None]:
    """What one triad measures over the interval ``(t - dt, t)``: ``(x, f_b)``.

    Gyro: ``x`` the mean angular rate, ``f_b`` the mean specific force with the vibration (its g-sensitivity
    input). Accelerometers: ``x`` the mean specific force plus the vibration ``v`` plus the vibration
    rectification ``vre * v^2`` (per axis; ``vre`` in 1/(m/s^2), its mean is ``vre g_rms^2``), ``f_b`` None."""
    v = tap.vibration_at(t)
    if gyro:
        f = dv / dt
        return dth / dt, (f if v is None else f + v)
    x = dv / dt
    if v is not None:
        x = x + v
        if vre is not None:
            x = x + vre * v * v
    return x, None


class Ahead:
    """Measured means of the coming trigger intervals of one sensor triad (see :func:`measure_ahead`).

    ``times[j]`` is the ``(t, t_prev)`` of row ``j``; ``raw[j]`` the measured mean before injected
    faults; ``post[j]`` what the device makes of it without faults (words / codes as ints, the
    clipped value it remembers and, for the gyro, its STATUS byte). Row ``j`` may be used only while the
    error model's noise block is the one peeked at, at the row ``i0 + j`` (so nothing was drawn in between).
    """

    __slots__ = ("block", "i0", "j", "post", "raw", "stochastic", "times")

    def __init__(self, times: list[tuple[float, float]], raw: np.ndarray, block: np.ndarray | None, i0: int,
                 stochastic: bool) -> None:
        self.times = times
        self.raw = raw
        self.post: list[tuple[Any, ...]] = []
        self.j = 1
        self.block = block
        self.i0 = i0
        self.stochastic = stochastic

    def take(self, t: float, t_prev: float, model: InertialErrorModel, dt: float) -> int:
        """Index of the row for the interval ``(t_prev, t)`` (its noise row consumed), or -1."""
        j = self.j
        if j >= len(self.times) or self.times[j] != (t, t_prev):
            return -1
        if self.stochastic and not model.consume_noise_row(self.block, self.i0 + j, dt):
            return -1  # something drew from the noise block in between: next_noise would draw
        self.j = j + 1
        return j


def measure_ahead(model: InertialErrorModel, tap: ImuTruthTap, t: float, t_prev: float, period: float,
                  temp: ImuTemperature, gyro: bool, vre: np.ndarray | None = None,
                  delay: float = 0.0) -> tuple[np.ndarray, Ahead | None]:
    """The measured mean of the interval ``(t_prev, t)`` (pre-fault, exactly :meth:`InertialErrorModel.measure`)
    and the same for the following trigger intervals ``t_j = (k + j) period``, ``t_prev_j = t_j - period``
    computed in one vectorised pass: as many as the current noise block and the trajectory's current
    increment block hold (neither is advanced; rows are bit for bit what the per-interval path gives).

    ``gyro``: the input is the mean angular rate and the g-sensitivity input the mean specific force;
    else (the accelerometers) the input is the mean specific force (:func:`sensor_input`, with the
    vibration and, ``vre``, its rectification).

    ``delay`` (s, >= 0): the sensor's output describes the motion ``delay`` earlier (the gyro's low-pass group
    delay): ``t``/``t_prev`` are the trigger edges, the measured interval is :func:`delayed_interval` of them,
    and ``Ahead.times`` holds those delayed intervals.
    """
    k = round(t / period)
    on_grid = k * period == t and t - period == t_prev
    if delay > 0.0:
        t, t_prev = delayed_interval(t, t_prev, delay)
    dt = t - t_prev
    dth, dv = tap.increments(t_prev, t)
    if not on_grid:  # not the FPGA's trigger grid: no look-ahead
        x, f_b = sensor_input(tap, t, dt, dth, dv, gyro, vre)
        return model.measure(x, dt, temp.at(t), temp.rate_at(t), temp.cal_c, f_b), None
    noise0 = model.next_noise(dt)
    stochastic = model.stochastic
    if stochastic:
        block, i_next = model.noise_position()
        i0 = i_next - 1  # the row noise0 came from
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
        if delay > 0.0:
            tj, tpj = delayed_interval(tj, tpj, delay)
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
    vib = tap.vibration
    if vib is not None:  # as sensor_input, row by row
        v = vib.samples(np.array([round(a * vib.fs) for a, _b in times]))
        if gyro:
            f = f + v
        else:
            x = x + v
            if vre is not None:
                x = x + vre * v * v
    rates = np.array([temp.rate_at(a) for a, _b in times]) if temp.warms_up else temp.rate_c_per_min
    det = model.deterministic_rows(x, temps, rates, temp.cal_c, f)
    noise = (np.concatenate([noise0[None, :], block[i0 + 1:i0 + n]])  # type: ignore[index]
             if stochastic else np.zeros((n, 3)))
    raw = det + noise
    return raw[0], (Ahead(times, raw, block, i0, stochastic) if n > 1 else None)
