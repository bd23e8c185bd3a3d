"""Faults injected into one sensor triad: bias steps, stuck axes, a range limit."""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["FaultableTriad", "InjectedFaults"]


class InjectedFaults:
    """Faults injected into one sensor triad (``emulator.faults`` drives them; all off by default).

    Applied to the measured mean of each interval (SI, body axes), in this order: the bias steps
    (``bias``), the stuck axes (held at the output they had when they froze) and a reduced range
    (``range_limit``, a scalar clipping every axis). The counters are the evidence that a fault took
    effect: intervals that carried a bias, held a stuck axis, and had a value clipped by the reduced
    range (only when the input really exceeded it).
    """

    __slots__ = (
        "_biases",
        "active",
        "bias",
        "biased",
        "clipped",
        "range_limit",
        "stuck",
        "stuck_samples",
        "stuck_value",
    )

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


class FaultableTriad:
    """The fault controls ``emulator.faults`` calls on a sensor triad (the gyro, the accelerometers).

    The device sets ``faults`` (:class:`InjectedFaults`), ``last_measured`` ((3,) its last output, SI,
    body axes) and ``model`` (its error model, whose ``bias0`` is the turn-on bias drawn for this run).
    Values are in the triad's SI unit: rad/s for a gyro, m/s^2 for accelerometers.
    """

    faults: InjectedFaults
    last_measured: np.ndarray
    model: Any

    @property
    def turn_on_bias(self) -> np.ndarray:
        """The turn-on bias drawn for this run, (3,) SI, body axes."""
        return self.model.bias0

    def set_bias_step(self, key: object, delta: np.ndarray | None) -> None:
        """Step the bias by ``delta`` (3,) SI, body axes; ``None`` removes the step ``key``."""
        self.faults.set_bias(key, delta)

    def set_stuck_axis(self, axis: int, stuck: bool) -> None:
        """Freeze axis ``axis`` (0..2) at its last output, or release it."""
        self.faults.set_stuck(axis, stuck, float(self.last_measured[axis]))

    def set_range_limit(self, limit: float | None) -> None:
        """Clip every axis at ``limit`` (SI; a gain fault; None restores the parts' full range)."""
        self.faults.set_range_limit(limit)
