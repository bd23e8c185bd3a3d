"""Fault injection: the scenario's ``faults:`` section, scheduled on the emulator's clock.

:class:`FaultScheduler` turns every fault of the scenario into an injector bound to the device or
link it acts on, switches it on at ``start_s`` and off at ``start_s + duration_s`` (or at the end
of the run) and writes both moments to ``events.jsonl`` (source ``fault``, events ``fault_start``
and ``fault_end``). Injectors act only through small, explicit capabilities of the devices
(``Stim210Gyro.set_stuck_axis``, ``GnssReceiver.add_outage``, ``VirtualFpga.set_channel_stalled``,
``VirtualDsp.extra_cycles_per_tick``...) and through the links' byte-fault hooks
(:class:`emulator.links.base.ByteFault`, ``Link.faults_in`` / ``faults_out``), all reached through
a :class:`FaultTargets` that the assembly builds: the faults never see the whole emulator.

One module per target: :mod:`.gnss`, :mod:`.psns`, :mod:`.imu`, :mod:`.link`, :mod:`.board` (FPGA and
DSP); each injector class is registered for its kind with :func:`.base.injects` (the table
:data:`.base.INJECTORS`, complete once every module of the package is imported, :func:`.base.injector_classes`);
:mod:`.scheduler` binds and schedules them.

Evidence. While a fault is active its injector counts what it really did: bytes it corrupted or
dropped, epochs sent without a fix, samples it clipped, view rays under a cloud, ticks it loaded.
``fault_end`` carries those counts, and the summary lists them (``summary["faults"]``). A fault
whose effect count stayed at zero never took effect (a saturation limit above every rate the
vehicle reached, a cloud where no sensor looks, a baud error inside the UART tolerance): the run
is then **invalid** (``summary["valid"] = false``, exit code 1), because a test that passes with
a fault that did not fire proves nothing. ``fault_end`` also carries the changes of the
firmware's counters over the window (``firmware``: GNSS updates, PSNS rejections, missing gyro
data...), which show what the fault did downstream.

Directions of link faults are named from the DSP: ``to_dsp`` (sensor -> FPGA -> DSP, host commands)
and ``from_dsp`` (navigation output towards the host, the monitor port). On an external port the
fault sits on the FPGA's end of the cable, on ``uart0..3`` on the DSP's end, so the recorder's
decoders (the link table of the summary) see what the receiver got.

Every random draw comes from ``device_rng(seed, "fault:<index>:<kind>")``: a run is reproducible, and
adding a fault does not change the random numbers of the sensors.
"""

from .base import INJECTORS, Injector, injector_classes, injects
from .scheduler import FIRMWARE_COUNTERS, FaultScheduler
from .targets import FaultTargets

__all__ = ["FIRMWARE_COUNTERS", "INJECTORS", "FaultScheduler", "FaultTargets", "Injector", "injector_classes",
           "injects"]

injector_classes()  # every module of the package registers its injectors (INJECTORS is complete from here on)
