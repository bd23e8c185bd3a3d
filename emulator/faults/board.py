"""Faults of the box itself: a stalled FPGA channel, extra DSP load."""

from __future__ import annotations

from typing import Any

from .base import Injector, bind_error, injects
from .targets import DspFaultHooks

__all__ = ["DspExtraLoad", "FpgaChannelStall"]


@injects("fpga_channel_stall")
class FpgaChannelStall(Injector):
    effect_keys: tuple[str, ...] = ("held_back",)

    def __init__(self, *a: Any) -> None:
        super().__init__(*a)
        fpga = self.targets.fpga
        if fpga is None:
            raise bind_error(self.kind, "needs the virtual FPGA")
        self.fpga = fpga

    @property
    def target(self) -> str:
        return f"FPGA channel {self.spec.channel}"

    def on(self, t: float) -> None:
        self.fpga.set_channel_stalled(self.spec.channel, True)

    def off(self, t: float) -> None:
        self.fpga.set_channel_stalled(self.spec.channel, False)

    def _counts(self) -> dict[str, int]:
        return {"held_back": self.fpga.stall_counts.get(self.spec.channel, 0)}


@injects("dsp_extra_load")
class DspExtraLoad(Injector):
    effect_keys: tuple[str, ...] = ("ticks_loaded",)

    def __init__(self, *a: Any) -> None:
        super().__init__(*a)
        s = self.spec
        dsp = self.targets.dsp
        if dsp is None or not hasattr(dsp, "extra_cycles_per_tick"):
            raise bind_error(self.kind, "needs the virtual DSP in this process (not a split run's remote DSP)")
        self.dsp: DspFaultHooks = dsp
        budget = dsp.clock_hz / self.targets.imu_rate_hz
        self.cycles = (int(s.cycles_per_tick) if s.cycles_per_tick is not None
                       else round(s.load_pct / 100.0 * budget))

    @property
    def target(self) -> str:
        return f"DSP (+{self.cycles} cycles per tick)"

    def on(self, t: float) -> None:
        self.dsp.extra_cycles_per_tick += self.cycles

    def off(self, t: float) -> None:
        self.dsp.extra_cycles_per_tick -= self.cycles

    def _counts(self) -> dict[str, int]:
        dsp = self.dsp
        return {"ticks_loaded": dsp.extra_load_ticks, "deadline_misses": dsp.deadline_misses}

