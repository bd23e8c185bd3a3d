"""What a fault may touch: the narrow view of an assembled run that the injectors get.

The assembly (:mod:`emulator.assembly`) builds one :class:`FaultTargets` per run; the injectors reach the
sensors, links, FPGA and DSP only through it, and never import the assembly.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

if TYPE_CHECKING:
    from ..devices.sensors import SensorSet
    from ..links.base import Link

__all__ = ["DspFaultHooks", "FaultClock", "FaultTargets", "FpgaFaultHooks"]


class FaultClock(Protocol):
    """The emulator's clock as the scheduler uses it."""

    def time(self) -> float: ...

    def call_at(self, when: float, callback: Callable[..., object], *args: Any) -> Any: ...


class FpgaFaultHooks(Protocol):
    """The virtual FPGA's fault capability: stalled channels and what they held back."""

    stall_counts: dict[str, int]

    def set_channel_stalled(self, channel: str, stalled: bool) -> None: ...


class DspFaultHooks(Protocol):
    """The virtual DSP's fault capability: extra cycles charged per tick, and what they caused."""

    clock_hz: float
    extra_cycles_per_tick: int
    extra_load_ticks: int
    deadline_misses: int


@dataclass(frozen=True)
class FaultTargets:
    """The parts of one run that faults act on (built by the assembly).

    Parameters
    ----------
    clock : the run's clock (fault windows are scheduled on it).
    duration_s : the scenario's duration (a fault without an end lasts to it), s.
    imu_rate_hz : the firmware's tick rate (the DSP's per-tick cycle budget), Hz.
    source_file : the scenario file (named in binding errors).
    sensors : the modelled sensors, or None (replay).
    links : every link by name (external ports and the FPGA-DSP UARTs).
    fpga : the virtual FPGA.
    dsp : the virtual DSP (None or a stand-in without fault hooks in a split run).
    firmware_counters : the counters of the firmware the DSP runs now (a watchdog reset replaces it).
    """

    clock: FaultClock
    duration_s: float
    imu_rate_hz: float
    source_file: str
    sensors: SensorSet | None
    links: Mapping[str, Link]
    fpga: FpgaFaultHooks | None
    dsp: DspFaultHooks | Any | None
    firmware_counters: Callable[[], Mapping[str, int]]
