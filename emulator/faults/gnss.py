"""GNSS faults: outages, glitches, a degraded solution (the modelled receiver)."""

from __future__ import annotations

from typing import Any

from .base import Injector, bind_error, injects
from .targets import FaultTargets

__all__ = ["GnssDegraded", "GnssGlitch", "GnssOutage"]


def _gnss(targets: FaultTargets, kind: str) -> Any:
    rx = getattr(targets.sensors, "gnss", None) if targets.sensors is not None else None
    if rx is None or not hasattr(rx, "add_outage"):
        raise bind_error(kind, "needs the modelled GNSS receiver on an in-process (mem://) gnss link")
    return rx


@injects("gnss_outage")
class GnssOutage(Injector):
    effect_keys: tuple[str, ...] = ("epochs_without_fix",)

    def __init__(self, *a: Any) -> None:
        super().__init__(*a)
        self.rx = _gnss(self.targets, self.kind)

    @property
    def target(self) -> str:
        return "gnss receiver"

    def on(self, t: float) -> None:
        end = self.spec.end_s(self.targets.duration_s)
        self.rx.add_outage(t, max(end - t, 1e-9))

    def off(self, t: float) -> None:
        pass  # the outage is time-windowed in the receiver; re-acquisition follows it

    def _counts(self) -> dict[str, int]:
        return {"epochs_without_fix": self.rx.no_fix_epochs}


@injects("gnss_glitch")
class GnssGlitch(GnssOutage):
    effect_keys: tuple[str, ...] = ("glitched_fixes",)

    def on(self, t: float) -> None:
        end = self.spec.end_s(self.targets.duration_s)
        self.rx.add_glitch(t, max(end - t, 1e-9), tuple(self.spec.offset_enu_m))

    def _counts(self) -> dict[str, int]:
        return {"glitched_fixes": self.rx.glitched_fixes}


@injects("gnss_degraded")
class GnssDegraded(GnssOutage):
    effect_keys: tuple[str, ...] = ("degraded_fixes", "epochs_without_fix")

    def on(self, t: float) -> None:
        s = self.spec
        self.rx.set_degraded(s.noise_scale, s.num_sats, s.hdop, s.fix_quality)

    def off(self, t: float) -> None:
        self.rx.clear_degraded()

    def _counts(self) -> dict[str, int]:
        return {"degraded_fixes": self.rx.degraded_fixes, "epochs_without_fix": self.rx.no_fix_epochs}
