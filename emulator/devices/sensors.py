"""Build the sensor devices of a scenario (presets + overrides -> error models -> devices)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

from ..links.base import Link
from ..scenario.schema import Scenario
from ..world.trajectory import Trajectory
from .base import device_rng
from .gnss import GnssConfig, GnssErrors, GnssReceiver
from .imu import AccelErrors, AnalogAccelerometers, GyroErrors, ImuTruthTap, Stim210Gyro

__all__ = ["SensorSet", "build_sensors", "gyro_errors", "accel_errors", "gnss_config"]


@dataclass
class SensorSet:
    """The sensor models of one run (None where the port is driven from outside)."""

    gyro: Stim210Gyro | None
    accel: AnalogAccelerometers
    gnss: GnssReceiver | None

    def start(self) -> None:
        """Start the devices that schedule themselves (everything not driven by an FPGA trigger)."""
        if self.gnss is not None:
            self.gnss.start()

    def counters(self) -> dict[str, int | None]:
        """Frames each device has sent (for the summary)."""
        return {
            "gyro_datagrams": self.gyro.datagrams_sent if self.gyro else None,
            "gnss_epochs": self.gnss.epochs_sent if self.gnss else None,
        }


def gyro_errors(scn: Scenario) -> GyroErrors:
    imu = scn.sensors.imu
    e = GyroErrors() if imu.preset == "paper" else GyroErrors(0.0, 0.0, 0.0, 600.0, 400.0)
    for k, v in imu.gyro.model_dump(exclude_none=True).items():
        setattr(e, k, v)
    return e


def accel_errors(scn: Scenario) -> AccelErrors:
    imu = scn.sensors.imu
    e = AccelErrors()
    if imu.preset == "perfect":
        e.bias_repeatability_mg = (0.0, 0.0, 0.0)
        e.bias_instability_mg = (0.0, 0.0, 0.0)
        e.noise_ug_rt_hz = 0.0
    for k, v in imu.accel.model_dump(exclude_none=True).items():
        setattr(e, k, tuple(v) if isinstance(v, list) else v)
    return e


def gnss_config(scn: Scenario) -> GnssConfig:
    g = scn.sensors.gnss
    err = GnssErrors()
    if g.preset == "perfect":
        err = GnssErrors(0.0, 0.0, 0.0, 300.0, 0.0, 0.0)
    for k, v in g.errors.model_dump(exclude_none=True).items():
        setattr(err, k, v)
    return GnssConfig(rate_hz=g.rate_hz, latency_s=g.latency_s, sentences=tuple(g.sentences),
                      geoid_sep_m=g.geoid_sep_m, errors=err)


def build_sensors(scn: Scenario, seed: int, traj: Trajectory, internal: dict[str, Link],
                  pps: Callable[[float], None]) -> SensorSet:
    """Create the sensor models whose ports are wired in-process (``internal`` link ends)."""
    tap = ImuTruthTap(traj)
    gyro = None
    if "gyro" in internal:
        gyro = Stim210Gyro(internal["gyro"], tap, device_rng(seed, "gyro"), gyro_errors(scn),
                           fmt=scn.sensors.imu.format, output=scn.sensors.imu.output,
                           trigger_rate_hz=scn.sensors.imu.rate_hz)
    accel = AnalogAccelerometers(tap, device_rng(seed, "accel"), accel_errors(scn))
    gnss = None
    if "gnss" in internal and scn.sensors.gnss.enabled:
        gnss = GnssReceiver(internal["gnss"], traj, scn.epoch, device_rng(seed, "gnss"), gnss_config(scn), pps=pps)
    return SensorSet(gyro, accel, gnss)
