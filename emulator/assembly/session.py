"""The run session: :class:`Emulator` owns one run, :func:`run_emulator` runs it on its own loop.

:class:`Emulator` opens the links, wires sensors -> FPGA -> DSP -> host (the pieces come from
:mod:`~emulator.assembly.build` and :mod:`.ports`), attaches the recorder, runs the clock to ``duration_s`` and
writes the summary (:mod:`.summary`). It lives inside an :class:`~emulator.clock.EmulatorLoop`; :func:`run_scenario`
creates that loop, installs the Ctrl-C / SIGTERM handlers (an interrupted run still writes its captures
and a summary with ``"interrupted": true``) and returns the summary.

The build reads one resolved configuration (:attr:`Emulator.cfg`, :func:`.build.resolve_run`): every sensor
preset merged and every port's URL parsed once, before anything is built. :meth:`Emulator.build` is the build's
order, nothing started; :meth:`Emulator.start` builds, then starts the clock and the sources. The steps a variant
of the run changes are methods of their own (:meth:`Emulator._open_ports`, :meth:`~Emulator._build_uarts`,
:meth:`~Emulator._cut_dsp_uarts`, :meth:`~Emulator._build_sensors`, :meth:`~Emulator.build_dsp`,
:meth:`~Emulator._start_sources`): a split run
(:mod:`emulator.distributed.split`) and a replay (:class:`emulator.postrun.replay.ReplayEmulator`: the same
assembly without sensors and FPGA acquisition, the captured DSP-UART bytes handed to the DSP at their recorded
times) override those, and the build itself has no branch for either.
"""

from __future__ import annotations

import asyncio
import contextlib
import datetime as _dt
import functools
import gc
import json
import math
import os
import signal
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from firmware_model.calibration import load_calibration, save_calibration
from firmware_model.registry import FirmwareProtocol
from protocols import __version__ as VERSION
from protocols.stim import gyro_port_format

from .. import early_signals
from ..clock import EmulatorLoop, sleep_until
from ..devices.fpga import VirtualFpga
from ..devices.gnss import GnssReceiver
from ..devices.imu import Stim210Gyro
from ..devices.sensors import InstalledUnit, build_sensors, build_sun, installed_unit
from ..dsp.external import DirectionSwap, ExternalDsp, cut_dsp_uarts
from ..dsp.firmware_setup import calibration_for
from ..dsp.host import UartRxConfig, VirtualDsp, WatchdogConfig
from ..dsp.lockstep import LockstepFirmware, open_lockstep
from ..errors import STORAGE_ERRNOS, EmulatorError, StorageError
from ..faults import FaultScheduler, FaultTargets
from ..links import Link, MemHub, open_link
from ..recording.recorder import Recorder
from ..recording.rundir import claim_run_dir
from ..scenario.resolved import ResolvedPort, ResolvedScenario
from ..scenario.schema import Scenario
from ..verification.expectations import evaluate_expectations
from ..world.build import build_trajectory
from .build import build_dsp, build_uarts, fpga_config, port_map, resolve_run
from .ports import (
    PORT_BAUD,
    PortInfo,
    SensorPortBinding,
    device_line,
    port_formats,
    port_line,
)
from .summary import SAMPLE_OFFSET_S, dsp_sections, fpga_section, take_sample

__all__ = ["Emulator", "default_run_dir", "run_emulator", "run_scenario"]


def default_run_dir(name: str, base: str | Path = "runs") -> Path:
    """``runs/<name>-<UTC timestamp>``: where a run writes unless told otherwise."""
    stamp = _dt.datetime.now(_dt.UTC).strftime("%Y%m%dT%H%M%SZ")
    return Path(base) / f"{name}-{stamp}"


class Emulator:
    """One emulated run (see module docstring).

    Parameters
    ----------
    scn : the validated scenario.
    run_dir : where the recorder writes.
    mode : ``fast`` / ``realtime`` (None: :func:`.ports.resolve_mode`'s rule).
    seed : overrides the scenario's seed.
    progress : called once per simulated second with ``(t, duration)``.
    """

    #: a replay of a capture (:class:`emulator.postrun.replay.ReplayEmulator`) rather than a run of sensors
    replaying = False

    #: set by run_emulator's signal handler (or a signal before it existed): the run ends once started
    _interrupt_requested = False
    #: set when stop() begins: a signal then no longer cancels the run (it is writing its files)
    _writing_files = False
    #: set when the run directory stopped taking data: (the error, whether summary.json was written)
    storage_error: tuple[OSError, bool] | None = None


    def __init__(self, scn: Scenario, run_dir: Path, mode: str | None = None, seed: int | None = None,
                 progress: Callable[[float, float], None] | None = None) -> None:
        # the envelope (docs/sensors.md "The envelope"): this seed's draw of the world (and of how the unit was
        # calibrated), written into the scenario before anything is built from it; the firmware's sheet is untouched.
        # Then every preset merged and every URL parsed, once: the build reads nothing else (.build.resolve_run)
        self.envelope = scn.envelope
        cfg: ResolvedScenario = resolve_run(scn, seed, mode)
        self.cfg = cfg
        self.seed = cfg.seed
        self.envelope_pinned = list(cfg.envelope_pinned)
        self.envelope_draws = cfg.envelope_draws if cfg.envelope_draws is not None else {}
        self.scn = cfg.scenario
        self.run_dir = Path(run_dir)
        self.mode = cfg.mode
        self.progress = progress
        self.loop: EmulatorLoop | None = None
        self.links: dict[str, Link] = {}
        self.device_ends: dict[str, Link] = {}
        #: sensor ports bound out to real ports (links.NAME.direction out / tee), by port
        self.bindings: dict[str, SensorPortBinding] = {}
        self.ports: list[PortInfo] = []
        self.recorder: Recorder | None = None
        self.dsp: VirtualDsp | None = None
        self.fpga: VirtualFpga | None = None
        self.gyro: Stim210Gyro | None = None
        self.gnss: GnssReceiver | None = None
        self.sensors: Any = None
        self.summary: dict[str, Any] = {}
        self._fw0: FirmwareProtocol | None = None
        self.faults: Any = None
        self._last_sample_t = 0.0
        self._started = False
        self._stopped = False
        self._wall0 = 0.0
        self._status_prev = (0.0, 0.0, 0)
        #: the cut FPGA-DSP UARTs when the DSP is outside (``dsp.external``), by UART name
        self.external_uarts: dict[str, Link] = {}

    @property
    def fw(self) -> FirmwareProtocol | None:
        """The firmware the DSP runs now (a watchdog reset replaces it)."""
        return self.dsp.fw if self.dsp is not None else self._fw0

    # -- construction ------------------------------------------------------------------------
    def _publish_clock(self, loop: EmulatorLoop) -> None:
        """``clock.json`` in the run directory: the scenario clock's origin for a tool on a real port (``psns-hil
        monitor`` on a pty shows ``t_s`` on the scenario clock with it): ``mode``, ``speed`` and
        ``t0_monotonic_s`` (:attr:`EmulatorLoop.wall_origin`: CLOCK_MONOTONIC of scenario time 0, s). Written aside
        and renamed: whole or absent."""
        doc = {"mode": loop.mode, "speed": loop.speed, "t0_monotonic_s": loop.wall_origin,
               "clock": "CLOCK_MONOTONIC"}
        tmp = self.run_dir / ".clock.json.tmp"
        tmp.write_text(json.dumps(doc) + "\n")
        os.replace(tmp, self.run_dir / "clock.json")

    async def start(self) -> None:
        """Build the run (:meth:`build`) and start it: the capture's header, the clock, the faults, the 1 Hz
        samples and the sources."""
        await self.build()
        loop, rec = self.loop, self.recorder
        assert isinstance(loop, EmulatorLoop) and rec is not None
        rec.start(self._run_header())
        if self.mode == "realtime":
            # everything built so far (modules, scenario, models) lives for the whole run: move it out of
            # the collector's generations, so a full collection no longer walks it (tens of ms, a late frame)
            gc.collect()
            gc.freeze()
            lead = realtime_lead_s(self._all_links())
            if lead:
                loop.set_lead(lead)
        loop.restart_clock()
        self._wall0 = loop.wall_elapsed()
        self._publish_clock(loop)
        if self.faults is not None:
            self.faults.start()
        loop.call_at(1.0 + SAMPLE_OFFSET_S, self._sample_tick)
        self._start_sources()
        if self.progress is not None:
            self._progress_tick()
        self._started = True

    async def build(self) -> None:
        """Build the run from :attr:`cfg` on the running :class:`EmulatorLoop`, nothing started: ports, FPGA-DSP
        UARTs, sensors, FPGA, DSP, faults, recorder taps; the real ports opened and ``ports.json`` written."""
        loop = asyncio.get_running_loop()
        if not isinstance(loop, EmulatorLoop):
            raise EmulatorError("the emulator runs on an emulator.clock.EmulatorLoop")
        self.loop = loop
        scn = self.scn
        traj = self.trajectory = build_trajectory(scn)
        rec = self.recorder = Recorder(self.run_dir, traj, sun=build_sun(scn))
        hub = MemHub()
        ext, internal = self._open_ports(hub, loop)
        self.links.update(ext)
        uart_fpga, uart_dsp, rx_cfg = self._build_uarts(hub, loop, ext)
        self._cut_dsp_uarts(uart_fpga, hub, loop)
        gyro, accel, mag = self._build_sensors(traj, internal)
        fpga_ports = {k: v for k, v in ext.items() if k != "monitor"}
        for port, bnd in self.bindings.items():
            if bnd.direction == "out":  # the FPGA's port stays idle: its sensor drives the real port only
                fpga_ports[port] = hub.pair(f"{port}:idle", ext[port].line, loop)[0]
        self.fpga = VirtualFpga(loop, fpga_config(scn), fpga_ports, uart_fpga, gyro, accel, rec,
                                monitor=ext.get("monitor"), mag=mag)
        gnss_port = ext.get("gnss")
        if gnss_port is not None and getattr(gnss_port, "pps_line", None):
            # an external receiver's PPS on a modem line (serial:// ?pps=dcd|cts): latched like the modelled one's
            gnss_port.on_pps = self._pps  # type: ignore[attr-defined]
        self.dsp = self.build_dsp(uart_dsp, rx_cfg, rec)
        if isinstance(self.dsp, VirtualDsp):  # the solar vectors it solves against truth (psns.csv)
            self.dsp.solar_listeners.append(rec.on_solar_solves)
        if scn.faults:  # bound now: a fault on a missing device fails before the run
            # a replay applies again the faults that act after the captured DSP input (host link, DSP load), with
            # the original's indices and random streams
            self.faults = FaultScheduler(self.fault_targets(), scn.faults, self.seed, rec, replay=self.replaying)
        self._tap_links(rec)
        for link in [*ext.values(), *(bnd.port for bnd in self.bindings.values()), *self.external_uarts.values()]:
            if link.scheme != "mem":
                await link.open()
        self._write_port_map(uart_fpga)

    # -- the build's steps (a split run and a replay override some) -------------------------------------------
    def _pair_port(self, hub: MemHub, loop: EmulatorLoop, rp: ResolvedPort, ext: dict[str, Link],
                   internal: dict[str, Link]) -> Link:
        """An in-process pair for port ``rp``: the FPGA's end in ``ext``, the device's in ``internal``."""
        port, spec = rp.name, rp.spec
        line = port_line(spec, PORT_BAUD[port])
        a, b = hub.pair(port, line, loop, line_b=device_line(spec, line), key=f"{port}:{rp.url.target}")
        a.url = b.url = spec.url if rp.scheme == "mem" else f"mem://{port}"
        ext[port], internal[port] = a, b
        self.device_ends[port] = b
        return a

    def _open_ports(self, hub: MemHub, loop: EmulatorLoop) -> tuple[dict[str, Link], dict[str, Link]]:
        """The external ports (FPGA ends by name) and the device ends of those wired in-process: a ``mem://`` port
        is a pair; a sensor port bound out (``direction: out | tee``) is a pair whose stream is also copied to its
        real port (:class:`.ports.SensorPortBinding`); any other port is its link."""
        ext: dict[str, Link] = {}
        internal: dict[str, Link] = {}
        for port, rp in self.cfg.ports.items():
            line = port_line(rp.spec, PORT_BAUD[port])
            if rp.scheme == "mem" or rp.bound_out:
                a = self._pair_port(hub, loop, rp, ext, internal)
                if rp.bound_out:  # the modelled sensor's stream also (tee) or only (out) on the real port
                    x = open_link(rp.url, port, loop, default_line=line, hub=hub, run_dir=self.run_dir / "ports")
                    self.bindings[port] = SensorPortBinding(port, rp.spec.direction, a, x)
            else:
                ext[port] = open_link(rp.url, port, loop, default_line=line, hub=hub, run_dir=self.run_dir / "ports")
        return ext, internal

    def _cut_dsp_uarts(self, uart_fpga: dict[str, Link], hub: MemHub, loop: EmulatorLoop) -> None:
        """The DSP outside on ports (``dsp.external.uarts``, docs/runtime.md, DSP out): those FPGA-DSP UARTs cut
        and their FPGA ends put on the ports (:attr:`external_uarts`); a lockstep firmware keeps the DSP-side UARTs
        (docs/icd.md 10)."""
        if not self.cfg.external_uarts:
            return
        if type(self)._build_uarts is not Emulator._build_uarts:
            raise EmulatorError("dsp.external puts the DSP outside; a split run also cuts its UARTs: "
                                "run it without --split")
        self.external_uarts = cut_dsp_uarts(dict(self.cfg.external_uarts), uart_fpga, loop, hub,
                                            self.run_dir / "ports")
        self.links.update(self.external_uarts)

    def _build_sensors(self, traj: Any, internal: dict[str, Link]) -> tuple[Any, Any, Any]:
        """The sensor models (docs/architecture.md, section "Firmware interface"): ``(gyro, accelerometers,
        magnetometer)`` for the FPGA; the rest drive their ports."""
        sensors = build_sensors(self.scn, self.seed, traj, internal, pps=self._pps, unit=self.unit,
                                sensors=self.cfg.sensors)
        self.sensors = sensors
        self.gyro, self.gnss = sensors.gyro, sensors.gnss
        return sensors.gyro, sensors.accel, sensors.mag

    def _start_sources(self) -> None:
        """Start what feeds the DSP: the FPGA's acquisition, the sensors, a DSP outside on ports."""
        assert self.fpga is not None
        self.fpga.start()
        self.sensors.start()
        if isinstance(self.dsp, ExternalDsp):
            self.dsp.start()

    def _tap_links(self, rec: Recorder) -> None:
        """The recorder's taps on every link, each with the stream formats its port carries."""
        scn = self.scn
        nmea_route = self.cfg.routing.get("host_nmea")  # None: NMEA (if any) on the host port with NAV
        nmea_on = bool(scn.firmware.nmea.sentences) or bool(scn.firmware.text_rate_hz)
        for name, link in self.links.items():
            nmea_here = (name == "host" and nmea_route is None) or (name == "uart0" and nmea_route in (None, "uart0"))
            fm: dict[str, Sequence[Any]] = dict(port_formats(name, nmea_out=nmea_on and nmea_here))
            if name == "gyro":
                fm = {"in": [gyro_port_format(scn.sensors.imu.device, scn.sensors.imu.format,
                                              int(scn.sensors.imu.stim300_datagram, 16))]}
            n0 = len(link.listeners)
            rec.tap(name, link, fm)
            if name in self.external_uarts:  # a cut UART is recorded from the DSP's side, as with the virtual DSP
                link.listeners[n0:] = [DirectionSwap(lst) for lst in link.listeners[n0:]]

    def _write_port_map(self, uart_fpga: dict[str, Link]) -> None:
        """:attr:`ports` and ``ports.json``: every external port, then every FPGA-DSP UART."""
        self.ports.extend(port_map(self.scn, self.links, uart_fpga, {p: b.port for p, b in self.bindings.items()},
                                   self.cfg.ports))
        for p in self.ports:
            cut = self.external_uarts.get(p["name"])
            if cut is not None:
                p["url"], p["path"] = cut.url, cut.describe()
                p["role"] = f"FPGA -> external DSP {p['name'].upper()}"
        (self.run_dir / "ports.json").write_text(json.dumps([dict(p) for p in self.ports], indent=2) + "\n")

    def _run_header(self) -> dict[str, Any]:
        """The capture's header: what a replay needs to build this run again."""
        scn = self.scn
        return {"scenario": scn.name, "seed": self.seed, "epoch": scn.epoch.isoformat(),
                "mode": self.mode, "link_baud": {k: v.line.baud for k, v in self.links.items()},
                "psns_hil_version": VERSION, "replay": self.replaying,
                # the fields the file set, not every default: a re-validated full dump would take each
                # sensor's default preset for one the file chose (a suite preset is chosen where a sensor
                # names none), and the run would not be the one replayed (issue 38)
                "scenario_spec": scn.model_dump(mode="json", exclude_unset=True),
                # where the scenario's relative files are (a spec sheet, recorded data): a replay reads them there
                "scenario_base_dir": str(Path(scn.base_dir).resolve()) if scn.base_dir is not None else None}

    def _replay_section(self) -> dict[str, Any] | None:
        """The summary's ``replay`` section (None: not a replay)."""
        return None

    def fault_targets(self) -> FaultTargets:
        """What the scenario's faults may touch (:mod:`emulator.faults`): sensors, links, FPGA, DSP."""
        assert self.loop is not None
        return FaultTargets(clock=self.loop, duration_s=self.scn.duration_s, imu_rate_hz=self.scn.sensors.imu.rate_hz,
                            source_file=self.scn.source_file, sensors=self.sensors, links=self.links, fpga=self.fpga,
                            dsp=self.dsp, firmware_counters=self._firmware_counters)

    def _firmware_counters(self) -> dict[str, int]:
        fw = self.fw
        return fw.snapshot().counters if fw is not None else {}

    @functools.cached_property
    def unit(self) -> InstalledUnit:
        """The installed unit (mountings, lens, iron: the world's truth a calibration measures), drawn once and
        shared by the sensor models and the calibration file (:func:`emulator.devices.sensors.installed_unit`)."""
        return installed_unit(self.scn, self.seed, self.cfg.sensors)

    def build_dsp(self, uart_dsp: dict[int, Link], rx_cfg: dict[int, UartRxConfig], events: Any) -> VirtualDsp:
        """The virtual DSP hosting this scenario's firmware on ``uart_dsp`` (also used by a split run's DSP
        process, :mod:`emulator.distributed.split`)."""
        assert self.loop is not None
        ext = self.scn.dsp.external
        if ext is not None and ext.lockstep is not None:
            return self._build_lockstep_dsp(uart_dsp, rx_cfg, events)
        if ext is not None:  # the DSP is outside: nothing of the firmware model runs
            return ExternalDsp(self.loop, self.external_uarts, ext.silence_s, events)  # type: ignore[return-value]
        return self._build_model_dsp(uart_dsp, rx_cfg, events)

    def _build_model_dsp(self, uart_dsp: dict[int, Link], rx_cfg: dict[int, UartRxConfig], events: Any
                         ) -> VirtualDsp:
        """The virtual DSP with this package's firmware model (or a ``psns_hil.firmware`` plugin)."""
        assert self.loop is not None
        # the calibration file: made from the world's truth plus residuals (or handed in), written into the run
        # directory, and read back: the firmware is configured from the file alone
        path = self.run_dir / "calibration.json"
        self.run_dir.mkdir(parents=True, exist_ok=True)
        save_calibration(calibration_for(self.scn, self.seed, self.unit), path)
        dsp = build_dsp(self.scn, self.loop, uart_dsp, rx_cfg, events, calibration=load_calibration(path),
                        sensors=self.cfg.sensors)
        self._fw0 = dsp.fw
        return dsp

    def _build_lockstep_dsp(self, uart_dsp: dict[int, Link], rx_cfg: dict[int, UartRxConfig], events: Any
                            ) -> VirtualDsp:
        """The virtual DSP hosting a foreign firmware in lockstep (docs/icd.md section 10): the same UARTs, timing
        and deadline model as for the built-in firmware; the watchdog only flags (a foreign firmware is not
        restarted)."""
        assert self.loop is not None
        scn = self.scn
        self.run_dir.mkdir(parents=True, exist_ok=True)
        fw = open_lockstep(scn, self.run_dir, events)
        wd = scn.dsp.watchdog
        dsp = VirtualDsp(self.loop, fw, uart_dsp, scn.dsp.clock_hz, events,
                         tick_period_s=1.0 / scn.sensors.imu.rate_hz, rx=rx_cfg,
                         watchdog=WatchdogConfig(wd.enabled, wd.overrun_multiple, "flag", wd.reset_time_s))
        fw.dsp = dsp
        self._fw0 = fw
        return dsp

    def lockstep(self) -> LockstepFirmware | None:
        """The lockstep firmware of this run (None: the built-in one or a DSP on ports)."""
        fw = self.fw
        return fw if isinstance(fw, LockstepFirmware) else None

    def _pps(self, t: float) -> None:
        assert self.fpga is not None
        self.fpga.pps_edge(t)

    def _build_uarts(self, hub: MemHub, loop: EmulatorLoop, ext: dict[str, Link]
                     ) -> tuple[dict[str, Link], dict[int, Link], dict[int, UartRxConfig]]:
        """The FPGA-DSP UARTs (:func:`.build.build_uarts`); their DSP ends join :attr:`links`. A split run
        overrides this to cut them."""
        uart_fpga, dsp_ends, uart_dsp, rx_cfg = build_uarts(self.scn, hub, loop)
        self.links.update(dsp_ends)
        return uart_fpga, uart_dsp, rx_cfg

    def _progress_tick(self) -> None:
        assert self.loop is not None and self.progress is not None
        t = self.loop.time()
        self.progress(t, self.scn.duration_s)
        if t < self.scn.duration_s:
            self.loop.call_at(math.floor(t) + 1.0, self._progress_tick)

    # -- 1 Hz samples: timeline.csv and filter_state.csv -------------------------------------------
    def _sample_tick(self) -> None:
        assert self.loop is not None
        t = self.loop.time()
        sec = round(t - SAMPLE_OFFSET_S)
        self._sample(float(sec))
        if sec + 1 + SAMPLE_OFFSET_S < self.scn.duration_s:
            self.loop.call_at(sec + 1 + SAMPLE_OFFSET_S, self._sample_tick)

    def _sample(self, t: float, final: bool = False) -> None:
        """One 1 Hz sample (:func:`.summary.take_sample`)."""
        rec, dsp = self.recorder, self.dsp
        if rec is None or dsp is None:
            return
        self._last_sample_t = t
        take_sample(rec, dsp, t, final)

    # -- live status -----------------------------------------------------------------------------
    def status(self) -> dict[str, Any]:
        """Sim time, real-time factor, nav frames/s and error counts since the last call."""
        assert self.loop is not None and self.recorder is not None
        t = self.loop.time()
        wall = self.loop.wall_elapsed()
        t0, w0, n0 = self._status_prev
        n = self.recorder.nav_count
        self._status_prev = (t, wall, n)
        dt_sim = t - t0
        links = self.recorder.link_summary()
        crc = sum(v["crc_errors"] for v in links.values())
        dropped = sum(v["dropped"] for v in links.values())
        framing = sum(lk.stats.framing_errors for lk in self.links.values())
        return {
            "t_s": t,
            "wall_s": wall,
            "realtime_factor": (dt_sim / (wall - w0)) if wall > w0 else None,
            "nav_fps": (n - n0) / dt_sim if dt_sim > 0 else 0.0,
            "nav_frames": n,
            "crc_errors": crc,
            "dropped": dropped,
            "framing_errors": framing,
            "deadline_misses": self.dsp.deadline_misses if self.dsp else 0,
        }

    # -- running -------------------------------------------------------------------------------
    async def run_until(self, t: float) -> None:
        await sleep_until(t)

    async def run(self) -> dict[str, Any]:
        interrupted = False
        try:
            await self.start()
            if self._interrupt_requested:  # a signal during start-up: never run on
                raise asyncio.CancelledError
            await self.run_until(self.scn.duration_s)
        except asyncio.CancelledError:
            interrupted = True
        except BaseException:
            await self._abort()
            raise
        return await self.stop(interrupted=interrupted)

    def _all_links(self) -> list[Link]:
        """Every link this run opened: the ports, the device ends and the real ports sensors are bound to."""
        return [*self.links.values(), *self.device_ends.values(), *(b.port for b in self.bindings.values())]

    async def _abort(self) -> None:
        """Start failed: release what was opened (ptys, files); no summary."""
        self._stopped = True
        lock = self.lockstep()
        if lock is not None:
            lock.close()
        for link in self._all_links():
            with contextlib.suppress(Exception):
                await link.close()
        if self.recorder is not None:
            self.recorder.close()

    async def stop(self, interrupted: bool = False) -> dict[str, Any]:
        self._writing_files = True  # a signal from now on does not cancel the stop (run_emulator's on_signal)
        loop = self.loop
        rec = self.recorder
        if loop is None or rec is None or self._stopped:
            return self.summary
        if not self._started:  # interrupted while starting
            await self._abort()
            self.summary = {"scenario": self.scn.name, "interrupted": interrupted, "started": False,
                            "run_dir": str(self.run_dir), "passed": False}
            rec.write_summary(self.summary)
            return self.summary
        self._stopped = True
        fault_records = self.faults.finish() if self.faults is not None else []
        sim_t = min(loop.time(), self.scn.duration_s) if not interrupted else loop.time()
        if sim_t > self._last_sample_t + 1e-9:
            self._sample(sim_t, final=True)  # the end of the run
        lock = self.lockstep()
        if lock is not None:  # the foreign firmware ends with the run (psns_fw_close / quit)
            lock.close()
        for link in self._all_links():
            with contextlib.suppress(Exception):
                await link.close()
        wall = loop.wall_elapsed()
        s: dict[str, Any] = {}
        try:
            self.summary = s = self._summary(sim_t, wall, interrupted)
            s["faults"] = fault_records
            s["valid"] = self.faults.valid if self.faults is not None else True
            rec.flush()
            s["warnings"] = self._warnings(s)
            results = evaluate_expectations(self.scn.expectations, rec, s, run_dir=self.run_dir,
                                            base_dir=self.scn.base_dir)
            s["expectations"] = [r.as_dict() for r in results]
            s["passed"] = all(r.passed for r in results) and not interrupted and s["valid"]
            if lock is not None:
                s["lockstep"] = lock.section()
                s["passed"] = s["passed"] and lock.failed is None
            rec.write_summary(s)
            rec.close()
        except OSError as exc:
            if exc.errno not in STORAGE_ERRNOS:
                rec.abandon()
                raise
            s = self._storage_failed(exc, sim_t, wall, interrupted, s, fault_records)
        except BaseException:  # a second Ctrl-C while the summary is written: keep what can be kept
            with contextlib.suppress(Exception):
                rec.close()
            rec.abandon()
            raise
        return s

    def _storage_failed(self, exc: OSError, sim_t: float, wall: float, interrupted: bool, s: dict[str, Any],
                        fault_records: list[dict[str, Any]]) -> dict[str, Any]:
        """The run directory stopped taking data (disk full, file-size limit): close what is open, write the
        summary into the space reserved for it (``"storage_error"``, ``"passed": false``) and remember the
        error for :func:`run_emulator` (which raises :class:`~emulator.errors.StorageError`)."""
        rec = self.recorder
        assert rec is not None
        rec.abandon()  # from here the recorder's files are closed: reading its results writes nothing
        if "scenario" not in s:  # the error came while the summary was being built: build it again
            s = self._summary(sim_t, wall, interrupted)
            s["faults"] = fault_records
        self.summary = s
        s["storage_error"] = f"{exc.strerror or exc} (errno {exc.errno}) at t = {sim_t:.3f} s"
        s["passed"] = False
        try:
            rec.write_summary(s)
            written = True
        except OSError:
            written = False
        self.storage_error = (exc, written)
        return s
    def _warnings(self, s: dict[str, Any]) -> list[dict[str, Any]]:
        """The fallbacks of this run: the scenario's (:func:`.fallbacks.scenario_warnings`) and the ones its
        events show it took (:func:`.fallbacks.run_fallbacks`)."""
        from .fallbacks import run_fallbacks, scenario_warnings

        rec = self.recorder
        assert rec is not None
        it = getattr(rec, "iter_events", None)
        events = it() if it is not None else rec.events
        return [f.as_dict() for f in (*scenario_warnings(self.scn), *run_fallbacks(self.scn, events, s.get("psns")))]

    def _summary(self, sim_t: float, wall: float, interrupted: bool) -> dict[str, Any]:
        rec = self.recorder
        assert rec is not None and self.dsp is not None and self.fpga is not None
        return {
            "psns_hil_version": VERSION,
            "scenario": self.scn.name,
            "scenario_file": self.scn.source_file,
            "seed": self.seed,
            "mode": self.mode,
            "speed": self.loop.speed if self.loop is not None else None,
            "epoch": self.scn.epoch.isoformat(),
            "sim_duration_s": sim_t,
            "wall_s": wall,
            "realtime_factor": sim_t / wall if wall > 0 else None,
            # realtime with a lead: who wrote to the real ports, and whether the writer process died (D-10.E11)
            "paced_writer": self.loop.writer_summary() if isinstance(self.loop, EmulatorLoop) else None,
            "interrupted": interrupted,
            "replay": self._replay_section(),
            "run_dir": str(self.run_dir),
            "nav_error": {k: v.as_dict() for k, v in rec.errors.items()},
            "nav_error_by_phase": {ph: {k: v.as_dict() for k, v in e.items()} for ph, e in rec.errors_by_phase.items()},
            "nav_frames": rec.nav_count,
            "links": rec.link_summary(),
            "link_stats": {k: dict(v.stats.as_dict(), error=v.error, **_pps_stats(v)) for k, v in self.links.items()},
            "bound_ports": {k: dict(b.port.stats.as_dict(), direction=b.direction, url=b.port.url,
                                    peer_bytes=b.peer_bytes, error=b.port.error) for k, b in self.bindings.items()},
            **self.dsp_sections(),
            "fpga": fpga_section(self.fpga),
            "devices": self.sensors.counters() if self.sensors is not None else {},
            "ports": [dict(p) for p in self.ports],
            "events": dict(rec.event_counts),
            "psns": rec.psns_summary(),
            "envelope": {"preset": self.envelope.preset, "groups": self.envelope.groups,
                         "draws": self.envelope_draws, "pinned": self.envelope_pinned}
            if self.envelope.preset is not None else None,
        }


    def dsp_sections(self) -> dict[str, Any]:
        """The ``dsp`` and ``firmware`` sections of the summary (a split run's come from the DSP process)."""
        assert self.dsp is not None
        if isinstance(self.dsp, ExternalDsp):
            return self.dsp.sections(self.loop.time() if self.loop is not None else None)
        return dsp_sections(self.dsp)


#: realtime: how far (wall s) the loop computes ahead of the outside world when every real port can be written at
#: its instant by the paced writer (docs/decisions/performance.md D-10.E6): the bound on the extra latency with
#: which bytes from outside (host commands) take effect, and the longest hold-up of the loop that leaves the
#: bytes to real peers on time
REALTIME_LEAD_S = 0.02


def realtime_lead_s(links: Sequence[Link]) -> float:
    """The lead for a realtime run with ``links``: :data:`REALTIME_LEAD_S` when there is a port with a real peer and
    every such port writes through the paced writer (``Link.deferred_write``: pty, serial); else 0: zenoh and CAN
    publish at once (their peers would get the bytes early), and a run of in-process (``mem``) links only has no
    one outside to be on time for."""
    real = [link for link in links if link.scheme != "mem"]
    return REALTIME_LEAD_S if real and all(link.deferred_write for link in real) else 0.0


def _pps_stats(link: Link) -> dict[str, Any]:
    """PPS of a port with a modem-line PPS (``serial://...?pps=dcd``): edges latched and why none came (a pty)."""
    if not getattr(link, "pps_line", None):
        return {}
    return {"pps_line": link.pps_line, "pps_edges": link.pps_edges,  # type: ignore[attr-defined]
            "pps_error": link.pps_error}  # type: ignore[attr-defined]


def run_emulator(emu: Emulator, speed: float = 1.0, on_started: Callable[[Emulator], None] | None = None,
                 force: bool = False) -> dict[str, Any]:
    """Run ``emu`` to completion (or interruption) on a fresh :class:`EmulatorLoop`.

    SIGINT and SIGTERM cancel the run; the recorder still writes everything it has and a
    summary with ``"interrupted": true``. The run directory is held for the run
    (:func:`emulator.recording.rundir.claim_run_dir`: busy, finished-unless-``force`` and file paths refused).
    """
    with claim_run_dir(emu.run_dir, force=force):
        return _run_emulator(emu, speed, on_started)


def _run_emulator(emu: Emulator, speed: float, on_started: Callable[[Emulator], None] | None) -> dict[str, Any]:
    loop = EmulatorLoop(emu.mode, speed)
    asyncio.set_event_loop(loop)
    failure: list[dict[str, Any]] = []

    def on_error(lp: asyncio.AbstractEventLoop, context: dict[str, Any]) -> None:
        # an exception in a device callback is a bug: end the run (summary kept) and report it
        if not failure:
            failure.append(context)
            task.cancel()

    async def main() -> dict[str, Any]:
        if on_started is not None:
            async def _notify() -> None:
                while not emu._started:
                    await asyncio.sleep(0)
                on_started(emu)
            loop.create_task(_notify())
        return await emu.run()

    task = loop.create_task(main())
    loop.set_exception_handler(on_error)

    def stop_at_once(_signum: int, _frame: Any) -> None:
        raise KeyboardInterrupt  # a second Ctrl-C: stop at once (emulator.cli.main says what that leaves)

    def on_signal() -> None:
        if emu._writing_files:  # the run has reached its end and is writing its files: do not cancel that (the
            # cancellation would surface as a CancelledError traceback); the command learns of the signal
            # through early_signals.PENDING, drops the report and exits 1 (emulator.cli.main._AfterRun)
            early_signals.PENDING.append(int(signal.SIGINT))
        else:
            emu._interrupt_requested = True  # read by Emulator.run after start-up
            task.cancel()
        # the next signal must act even while the run writes its summary without returning to the loop (a loop
        # handler would then never run): a plain handler that raises in the main thread wherever it is
        for sig in (signal.SIGINT, signal.SIGTERM):
            with contextlib.suppress(NotImplementedError, RuntimeError, ValueError):
                loop.remove_signal_handler(sig)
                signal.signal(sig, stop_at_once)
        sys.stderr.write(f"\npsns-hil run: interrupted at t = {loop.time():.3f} s (emulated); writing the summary "
                         "and closing the captures (interrupt again to stop at once)\n")
        sys.stderr.flush()

    # the handlers to give back when the run ends (psns-hil run: emulator.early_signals', which remember a signal
    # for the command's report stage; a library caller: its own), never Python's defaults in between
    previous = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(NotImplementedError, RuntimeError, ValueError):
            loop.add_signal_handler(sig, on_signal)
    if early_signals.PENDING:  # a signal arrived before this loop existed (emulator.early_signals): the run
        early_signals.PENDING.clear()  # starts (run directory, recorder) and ends at once, interrupted
        emu._interrupt_requested = True
    try:
        summary = loop.run_until_complete(task)
        if failure and emu.storage_error is None:
            exc0 = failure[0].get("exception")
            if isinstance(exc0, OSError) and exc0.errno in STORAGE_ERRNOS and emu.recorder is not None:
                # a write during the run failed, the stop's own writes succeeded: the summary says so
                summary["storage_error"] = (f"{exc0.strerror or exc0} (errno {exc0.errno}) at t = "
                                            f"{summary.get('sim_duration_s', 0.0):.3f} s")
                summary["passed"] = False
                try:
                    emu.recorder.write_summary(summary)
                    written = True
                except OSError:
                    written = False
                emu.storage_error = (exc0, written)
        if emu.storage_error is not None:
            err, written = emu.storage_error
            raise StorageError(
                f"{emu.run_dir}: cannot write the run directory: {err.strerror or err} (errno {err.errno}); the run "
                f"stopped at t = {summary.get('sim_duration_s', 0.0):.3f} s (emulated); "
                + ("summary.json written (\"storage_error\"); " if written else "summary.json could not be written; ")
                + "the captures hold what was written before") from None
        if failure:
            ctx = failure[0]
            exc = ctx.get("exception")
            raise EmulatorError(f"the run stopped at t = {summary.get('sim_duration_s', 0):.6f} s: "
                                f"{ctx.get('message', 'error')}: {exc!r} (summary and captures kept in "
                                f"{emu.run_dir})") from exc
        return summary
    finally:
        for sig in (signal.SIGINT, signal.SIGTERM):
            with contextlib.suppress(NotImplementedError, RuntimeError, ValueError):
                loop.remove_signal_handler(sig)
            with contextlib.suppress(TypeError, ValueError, OSError):
                signal.signal(sig, previous[sig])
        asyncio.set_event_loop(None)
        loop.close()


def run_scenario(scn: Scenario, run_dir: Path, mode: str | None = None, speed: float | None = None,
                 seed: int | None = None, progress: Callable[[float, float], None] | None = None,
                 on_started: Callable[[Emulator], None] | None = None, force: bool = False) -> dict[str, Any]:
    """Run ``scn`` to completion (or interruption) on a fresh :class:`EmulatorLoop`."""
    emu = Emulator(scn, run_dir, mode=mode, seed=seed, progress=progress)
    return run_emulator(emu, speed if speed is not None else scn.speed, on_started, force=force)
