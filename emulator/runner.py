"""Build the emulated system from a scenario and run it.

:class:`Emulator` owns one run: it opens the links, wires sensors -> FPGA -> DSP -> host,
attaches the recorder, runs the clock to ``duration_s`` and writes the summary. It lives inside
an :class:`~emulator.clock.EmulatorLoop`; :func:`run_scenario` creates that loop, installs the
Ctrl-C / SIGTERM handlers (an interrupted run still writes its captures and a summary with
``"interrupted": true``) and returns the summary.
"""

from __future__ import annotations

import asyncio
import datetime as _dt
import math
import signal
from pathlib import Path
from typing import Any, Callable

from firmware_model import UART_GNSS, UART_HOST, UART_IMU, UART_PSNS, Firmware
from firmware_model.c674x import COST_MODEL_VERSION
from protocols import __version__ as VERSION
from protocols.host import HostFormat
from protocols.imu_frame import ImuFrameFormat
from protocols.nmea import NmeaFormat
from protocols.psns import PsnsFormat
from protocols.stim import Stim210Format

from .clock import EmulatorLoop
from .devices.dsp import VirtualDsp
from .devices.fpga import FpgaConfig, VirtualFpga
from .devices.gnss import GnssReceiver
from .devices.imu import Stim210Gyro
from .devices.sensors import build_sensors
from .expectations import evaluate_expectations
from .firmware_setup import build_firmware
from .links import LineConfig, Link, MemHub, open_link, parse_link_url, parse_mode
from .recorder import Recorder
from .scenario.schema import LinkSpec, Scenario
from .world.build import build_trajectory

__all__ = ["Emulator", "run_scenario", "default_run_dir", "PortInfo"]

UART_NUM = {"uart0": UART_HOST, "uart1": UART_IMU, "uart2": UART_PSNS, "uart3": UART_GNSS}
PORT_ROLES = {
    "gyro": "STIM210 gyro -> FPGA (RS422)",
    "gnss": "GNSS receiver -> FPGA (RS422)",
    "psns": "polarization sensor -> FPGA (RS232)",
    "host": "FPGA HOST (RS422) <-> DSP UART0: navigation out, commands in",
}


class PortInfo(dict):
    """One row of the port map printed at start: name, role, url, baud, mode, path."""


def default_run_dir(name: str, base: str | Path = "runs") -> Path:
    stamp = _dt.datetime.now(_dt.timezone.utc).strftime("%Y%m%dT%H%M%SZ")
    return Path(base) / f"{name}-{stamp}"


def _line(spec: LinkSpec, default_baud: int) -> LineConfig:
    bits, parity, stop = parse_mode(spec.mode)
    return LineConfig(baud=spec.baud or default_baud, data_bits=bits, parity=parity, stop_bits=stop,
                      tx_queue_bytes=spec.queue_bytes)


class Emulator:
    """One emulated run (see module docstring)."""

    def __init__(self, scn: Scenario, run_dir: Path, mode: str | None = None, seed: int | None = None,
                 progress: Callable[[float, float], None] | None = None) -> None:
        self.scn = scn
        self.run_dir = Path(run_dir)
        self.mode = mode or scn.mode
        self.seed = scn.seed if seed is None else seed
        self.progress = progress
        self.loop: EmulatorLoop | None = None
        self.links: dict[str, Link] = {}
        self.ports: list[PortInfo] = []
        self.recorder: Recorder | None = None
        self.fw: Firmware | None = None
        self.dsp: VirtualDsp | None = None
        self.fpga: VirtualFpga | None = None
        self.gyro: Stim210Gyro | None = None
        self.gnss: GnssReceiver | None = None
        self.summary: dict[str, Any] = {}
        self._started = False
        self._wall0 = 0.0

    # -- construction ------------------------------------------------------------------------
    async def start(self) -> None:
        loop = asyncio.get_running_loop()
        assert isinstance(loop, EmulatorLoop), "the emulator runs on an EmulatorLoop"
        self.loop = loop
        scn = self.scn
        traj = self.trajectory = build_trajectory(scn)
        rec = self.recorder = Recorder(self.run_dir, traj)
        hub = MemHub()
        port_dir = self.run_dir / "ports"
        ext: dict[str, Link] = {}
        internal: dict[str, Link] = {}
        specs = {"gyro": (scn.links.gyro, 460800), "gnss": (scn.links.gnss, 9600), "host": (scn.links.host, 460800)}
        if scn.links.psns is not None:
            specs["psns"] = (scn.links.psns, 115200)
        for port, (spec, dbaud) in specs.items():
            line = _line(spec, dbaud)
            u = parse_link_url(spec.url)
            if u.scheme == "mem":
                a, b = hub.pair(port, line, loop, key=f"{port}:{u.target}")
                ext[port], internal[port] = a, b
            else:
                ext[port] = open_link(spec.url, port, loop, default_line=line, hub=hub, run_dir=port_dir)
            self.links[port] = ext[port]
        uart_fpga: dict[str, Link] = {}
        uart_dsp: dict[int, Link] = {}
        for uname, uspec in scn.fpga.uarts.items():
            line = LineConfig(baud=uspec.baud, tx_queue_bytes=uspec.queue_bytes)
            a, b = hub.pair(uname, line, loop)
            uart_fpga[uname], uart_dsp[UART_NUM[uname]] = a, b
            self.links[uname] = b
        # sensors
        sensors = build_sensors(scn, self.seed, traj, internal, pps=lambda t: self.fpga.pps_edge(t))  # type: ignore[union-attr]
        self.sensors = sensors
        self.gyro, self.gnss = sensors.gyro, sensors.gnss
        fcfg = FpgaConfig(imu_rate_hz=scn.sensors.imu.rate_hz, gyro_timeout_s=scn.fpga.gyro_timeout_s,
                          gyro_format=scn.sensors.imu.format,
                          gyro_counter_step=int(round(2000 / scn.sensors.imu.rate_hz)),
                          routing=dict(scn.fpga.routing))
        self.fpga = VirtualFpga(loop, fcfg, ext, uart_fpga, self.gyro, sensors.accel, rec)
        self.fw = build_firmware(scn)
        self.dsp = VirtualDsp(loop, self.fw, uart_dsp, scn.dsp.clock_hz, rec,
                              tick_period_s=1.0 / scn.sensors.imu.rate_hz)
        # recorder taps
        fmt_stim = [Stim210Format(scn.sensors.imu.format)]
        rec.tap("gyro", ext["gyro"], {"in": fmt_stim})
        rec.tap("gnss", ext["gnss"], {"in": [NmeaFormat()]})
        rec.tap("host", ext["host"], {"out": [HostFormat()], "in": [HostFormat()]})
        if "psns" in ext:
            rec.tap("psns", ext["psns"], {"in": [PsnsFormat()]})
        rec.tap("uart0", self.links["uart0"], {"out": [HostFormat()], "in": [HostFormat()]})
        rec.tap("uart1", self.links["uart1"], {"in": [ImuFrameFormat()]})
        rec.tap("uart2", self.links["uart2"], {"in": [PsnsFormat()]})
        rec.tap("uart3", self.links["uart3"], {"in": [NmeaFormat()]})
        for link in ext.values():
            await link.open()
        for port, link in ext.items():
            self.ports.append(PortInfo(name=port, role=PORT_ROLES.get(port, port), url=link.url,
                                       baud=link.line.baud, mode=link.line.mode, path=link.describe()))
        rec.start({"scenario": scn.name, "seed": self.seed, "epoch": scn.epoch.isoformat(),
                   "mode": self.mode, "link_baud": {k: v.line.baud for k, v in self.links.items()}})
        loop.restart_clock()
        self._wall0 = loop.wall_elapsed()
        self.fpga.start()
        sensors.start()
        if self.progress is not None:
            self._progress_tick()
        self._started = True

    def _progress_tick(self) -> None:
        assert self.loop is not None and self.progress is not None
        t = self.loop.time()
        self.progress(t, self.scn.duration_s)
        if t < self.scn.duration_s:
            self.loop.call_at(math.floor(t) + 1.0, self._progress_tick)

    # -- running -------------------------------------------------------------------------------
    async def run_until(self, t: float) -> None:
        from .clock import sleep_until

        await sleep_until(t)

    async def run(self) -> dict[str, Any]:
        interrupted = False
        try:
            await self.start()
            await self.run_until(self.scn.duration_s)
        except asyncio.CancelledError:
            interrupted = True
        finally:
            summary = await self.stop(interrupted=interrupted)
        return summary

    async def stop(self, interrupted: bool = False) -> dict[str, Any]:
        loop = self.loop
        rec = self.recorder
        if loop is None or rec is None:
            return {}
        for link in self.links.values():
            try:
                await link.close()
            except Exception:  # noqa: BLE001 - closing must not lose the summary
                pass
        sim_t = min(loop.time(), self.scn.duration_s) if not interrupted else loop.time()
        wall = loop.wall_elapsed()
        self.summary = s = self._summary(sim_t, wall, interrupted)
        results = evaluate_expectations(self.scn.expectations, rec, s)
        s["expectations"] = [r.as_dict() for r in results]
        s["passed"] = all(r.passed for r in results) and not interrupted
        rec.write_summary(s)
        rec.close()
        return s

    def _summary(self, sim_t: float, wall: float, interrupted: bool) -> dict[str, Any]:
        rec = self.recorder
        assert rec is not None and self.fw is not None and self.dsp is not None and self.fpga is not None
        dsp = self.dsp
        fw = self.fw
        return {
            "psns_hil_version": VERSION,
            "scenario": self.scn.name,
            "scenario_file": self.scn.source_file,
            "seed": self.seed,
            "mode": self.mode,
            "epoch": self.scn.epoch.isoformat(),
            "sim_duration_s": sim_t,
            "wall_s": wall,
            "realtime_factor": sim_t / wall if wall > 0 else None,
            "interrupted": interrupted,
            "run_dir": str(self.run_dir),
            "nav_error": {k: v.as_dict() for k, v in rec.errors.items()},
            "nav_frames": rec.nav_count,
            "links": rec.link_summary(),
            "link_stats": {k: v.stats.as_dict() for k, v in self.links.items()},
            "dsp": {
                "clock_hz": dsp.clock_hz,
                "cpu_load_pct_max": dsp.cpu_load_pct_max(),
                "tick_utilization_max_pct": 100.0 * dsp.max_tick_cycles / fw.meter.tick_budget,
                "tick_budget_cycles": fw.meter.tick_budget,
                "deadline_misses": dsp.deadline_misses,
                "ticks": dsp.ticks,
                "cost_model": COST_MODEL_VERSION,
                "tasks": fw.meter.table(),
            },
            "firmware": {"filter": fw.cfg.filter, "precision": fw.cfg.precision, "counters": dict(fw.counters),
                         "decoders": fw.decoder_stats()},
            "fpga": {"imu_frames": self.fpga.imu_frames, "gyro_missing": self.fpga.gyro_missing,
                     "routes": self.fpga.routes},
            "devices": self.sensors.counters(),
            "ports": [dict(p) for p in self.ports],
            "events": dict(rec.event_counts),
        }


def run_scenario(scn: Scenario, run_dir: Path, mode: str | None = None, speed: float | None = None,
                 seed: int | None = None, progress: Callable[[float, float], None] | None = None,
                 on_started: Callable[[Emulator], None] | None = None) -> dict[str, Any]:
    """Run ``scn`` to completion (or interruption) on a fresh :class:`EmulatorLoop`."""
    mode = mode or scn.mode
    loop = EmulatorLoop(mode, speed if speed is not None else scn.speed)
    emu = Emulator(scn, run_dir, mode=mode, seed=seed, progress=progress)
    asyncio.set_event_loop(loop)

    async def main() -> dict[str, Any]:
        if on_started is not None:
            async def _notify() -> None:
                while not emu._started:  # noqa: SLF001
                    await asyncio.sleep(0)
                on_started(emu)
            loop.create_task(_notify())
        return await emu.run()

    task = loop.create_task(main())
    for sig in (signal.SIGINT, signal.SIGTERM):
        try:
            loop.add_signal_handler(sig, task.cancel)
        except (NotImplementedError, RuntimeError, ValueError):
            pass
    try:
        return loop.run_until_complete(task)
    finally:
        for sig in (signal.SIGINT, signal.SIGTERM):
            try:
                loop.remove_signal_handler(sig)
            except (NotImplementedError, RuntimeError, ValueError):
                pass
        asyncio.set_event_loop(None)
        loop.close()

