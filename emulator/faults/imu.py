"""IMU faults: bias steps, stuck axes, saturation, dropped gyro datagrams."""

from __future__ import annotations

from typing import Any

import numpy as np

from protocols.constants import DEG, G_STD

from .base import AXES, Injector, bind_error, injects
from .targets import FaultTargets

__all__ = ["ImuBiasStep", "ImuDroppedDatagrams", "ImuSaturation", "ImuStuckAxis"]


def _imu(targets: FaultTargets, kind: str, sensor: str) -> Any:
    s = targets.sensors
    dev = getattr(s, sensor, None) if s is not None else None
    if dev is None:
        what = "STIM210 gyro on a mem:// gyro link" if sensor == "gyro" else "accelerometers"
        raise bind_error(kind, f"needs the modelled {what}")
    return dev


@injects("imu_bias_step")
class ImuBiasStep(Injector):
    effect_keys: tuple[str, ...] = ("samples_biased",)

    def __init__(self, *a: Any) -> None:
        super().__init__(*a)
        self.sensor: str = self.spec.sensor
        self.dev = _imu(self.targets, self.kind, self.sensor)

    @property
    def target(self) -> str:
        return self.sensor

    def on(self, t: float) -> None:
        s = self.spec
        if self.sensor == "gyro":
            delta = np.asarray(s.gyro_deg_h, dtype=np.float64) * (DEG / 3600.0)
        else:
            delta = np.asarray(s.accel_mg, dtype=np.float64) * (1e-3 * G_STD)
        self.dev.set_bias_step(("fault", self.index), delta)

    def off(self, t: float) -> None:
        self.dev.set_bias_step(("fault", self.index), None)

    def _counts(self) -> dict[str, int]:
        return {"samples_biased": self.dev.faults.biased}


@injects("imu_stuck_axis")
class ImuStuckAxis(ImuBiasStep):
    effect_keys: tuple[str, ...] = ("samples_stuck",)

    @property
    def target(self) -> str:
        return f"{self.sensor} axes {', '.join(self.spec.axes)}"

    def on(self, t: float) -> None:
        for a in self.spec.axes:
            self.dev.set_stuck_axis(AXES[a], True)

    def off(self, t: float) -> None:
        for a in self.spec.axes:
            self.dev.set_stuck_axis(AXES[a], False)

    def _counts(self) -> dict[str, int]:
        return {"samples_stuck": self.dev.faults.stuck_samples}


@injects("imu_saturation")
class ImuSaturation(ImuBiasStep):
    effect_keys: tuple[str, ...] = ("samples_clipped",)

    def on(self, t: float) -> None:
        s = self.spec
        lim = s.gyro_range_dps * DEG if self.sensor == "gyro" else s.accel_range_g * G_STD
        self.dev.set_range_limit(lim)

    def off(self, t: float) -> None:
        self.dev.set_range_limit(None)

    def _counts(self) -> dict[str, int]:
        return {"samples_clipped": self.dev.faults.clipped}


@injects("imu_dropped_datagrams")
class ImuDroppedDatagrams(Injector):
    effect_keys: tuple[str, ...] = ("datagrams_dropped",)

    def __init__(self, *a: Any) -> None:
        super().__init__(*a)
        self.dev = _imu(self.targets, self.kind, "gyro")

    @property
    def target(self) -> str:
        return "gyro"

    def on(self, t: float) -> None:
        self.dev.set_datagram_drop(self.spec.probability, self.rng)

    def off(self, t: float) -> None:
        self.dev.set_datagram_drop(0.0)

    def _counts(self) -> dict[str, int]:
        return {"datagrams_dropped": self.dev.datagrams_dropped}
