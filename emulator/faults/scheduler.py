"""The scenario's faults on the emulator's clock: bind, switch on and off, report."""

from __future__ import annotations

from typing import Any

from ..devices.base import EventSink, device_rng
from ..errors import ScenarioError
from ..scenario.faults_schema import Fault
from .base import Injector, injector_classes
from .targets import FaultTargets

__all__ = ["FIRMWARE_COUNTERS", "FaultScheduler", "acts_after_the_capture"]

#: firmware counters whose change over a fault's window is reported in ``fault_end``
FIRMWARE_COUNTERS = ("gnss_fixes", "gnss_updates", "psns_frames", "psns_updates", "psns_rejected", "psns_invalid",
                     "compass_frames", "fpga_gyro_missing", "gyro_counter_jumps", "imu_frames", "imu_time_gaps")



def acts_after_the_capture(f: Fault) -> bool:
    """True for a fault a replay must apply again: what it does is not in the DSP UARTs' captured input (the host
    link's faults act between the FPGA and the host, ``dsp_extra_load`` on the DSP's cycles); every other fault
    acted upstream, and its effect is in the bytes the DSP received."""
    return f.kind == "dsp_extra_load" or getattr(f.spec, "link", None) == "host"


class FaultScheduler:
    """The scenario's faults on the emulator's clock (see module docstring).

    Parameters
    ----------
    targets : what the faults may touch (sensors, links, FPGA, DSP), built by the assembly.
    faults : the scenario's ``faults`` section.
    seed : the run's seed.
    events : where ``fault_start`` / ``fault_end`` go (the recorder).
    """

    def __init__(self, targets: FaultTargets, faults: list[Fault], seed: int, events: EventSink,
                 replay: bool = False) -> None:
        self.targets = targets
        self.events = events
        self.injectors: list[Injector] = []
        self._fw0: dict[int, dict[str, int]] = {}
        self._fw_delta: dict[int, dict[str, int]] = {}
        for i, f in enumerate(faults):
            if replay and not acts_after_the_capture(f):  # its effect is in the captured bytes already
                continue
            kind = f.kind
            cls = injector_classes()[kind]
            try:
                inj = cls(targets, kind, f.spec, i, device_rng(seed, f"fault:{i}:{kind}"))
            except ScenarioError as exc:
                for issue in exc.issues:
                    issue.file = targets.source_file
                    issue.path = f"faults[{i}].{kind}"
                raise ScenarioError(exc.issues) from None
            self.injectors.append(inj)

    def start(self) -> None:
        """Schedule every fault (call right after the scenario clock restarted at 0)."""
        loop = self.targets.clock
        dur = self.targets.duration_s
        for inj in self.injectors:
            spec = inj.spec
            loop.call_at(spec.start_s, self._on, inj)
            end = spec.end_s(dur)
            if end < dur:
                loop.call_at(end, self._off, inj)

    def _fw_counters(self) -> dict[str, int]:
        c = self.targets.firmware_counters()
        return {k: int(c.get(k, 0)) for k in FIRMWARE_COUNTERS}

    def _on(self, inj: Injector) -> None:
        t = self.targets.clock.time()
        self._fw0[inj.index] = self._fw_counters()
        inj.start(t)
        spec = inj.spec
        self.events.emit(t, "fault", "fault_start", fault=inj.kind, index=inj.index, target=inj.target,
                         end_s=spec.end_s(self.targets.duration_s))

    def _off(self, inj: Injector) -> None:
        if not inj.active:
            return
        t = self.targets.clock.time()
        inj.stop(t)
        fw1 = self._fw_counters()
        fw0 = self._fw0.get(inj.index, {})
        self._fw_delta[inj.index] = {k: fw1[k] - fw0.get(k, 0) for k in fw1 if fw1[k] != fw0.get(k, 0)}
        self.events.emit(t, "fault", "fault_end", fault=inj.kind, index=inj.index, target=inj.target,
                         evidence=inj.evidence(), fired=inj.fired, firmware=self._fw_delta[inj.index])

    def finish(self) -> list[dict[str, Any]]:
        """End the faults still active (at the current time) and return one record per fault."""
        for inj in self.injectors:
            if inj.active:
                self._off(inj)
        return [self.record(inj) for inj in self.injectors]

    def record(self, inj: Injector) -> dict[str, Any]:
        return {"index": inj.index, "kind": inj.kind, "target": inj.target, "start_s": inj.spec.start_s,
                "end_s": inj.spec.end_s(self.targets.duration_s), "active_from_s": inj.t_on,
                "active_until_s": inj.t_off, "evidence": inj.evidence(), "effect": list(inj.effect_keys),
                "fired": inj.fired if inj.t_on is not None else None,
                "firmware": self._fw_delta.get(inj.index, {})}

    @property
    def valid(self) -> bool:
        """False when a fault that was switched on never took effect."""
        return all(inj.fired for inj in self.injectors if inj.t_on is not None)
