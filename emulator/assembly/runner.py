"""Build the emulated system from a scenario and run it.

:class:`Emulator` owns one run: it opens the links, wires sensors -> FPGA -> DSP -> host,
attaches the recorder, runs the clock to ``duration_s`` and writes the summary. It lives inside
an :class:`~emulator.clock.EmulatorLoop`; :func:`run_scenario` creates that loop, installs the
Ctrl-C / SIGTERM handlers (an interrupted run still writes its captures and a summary with
``"interrupted": true``) and returns the summary.

Time mode: ``--fast`` / ``--realtime`` on the command line win; else the scenario's ``mode`` if
the file sets one; else ``realtime`` when any port has a real endpoint (``pty://``, ``serial://``:
real peers live in wall time) and ``fast`` otherwise (DESIGN.md section 4).

Replay (:mod:`emulator.recording.replay`): the same assembly without sensors and FPGA acquisition; the
bytes a capture says each DSP UART received are handed to the DSP at their recorded times.
"""

from __future__ import annotations

import asyncio
import datetime as _dt
import gc
import json
import math
import signal
from pathlib import Path
from typing import Any, Callable

import numpy as np

from firmware_model import UART_GNSS, UART_HOST, UART_IMU, UART_PSNS, Firmware
from firmware_model.c674x import COST_MODEL_VERSION
from protocols import __version__ as VERSION
from protocols.host import HostFormat
from protocols.imu_frame import ImuFrameFormat
from protocols.nmea import NmeaFormat
from protocols.psns import PsnsFormat
from protocols.stim import Stim210Format

from ..clock import EmulatorLoop
from ..devices.fpga import FpgaConfig, VirtualFpga, monitor_api
from ..devices.gnss import GnssReceiver
from ..devices.imu import Stim210Gyro
from ..devices.sensors import build_sensors
from ..dsp.firmware_setup import build_firmware
from ..dsp.host import UartRxConfig, VirtualDsp, WatchdogConfig
from ..faults.targets import FaultTargets
from ..links import LineConfig, Link, MemHub, open_link, parse_link_url, parse_mode
from ..recording.recorder import CaptureRecord, Recorder
from ..scenario.schema import LinkSpec, Scenario
from ..verification.expectations import evaluate_expectations
from ..world.build import build_trajectory

__all__ = ["Emulator", "run_scenario", "run_emulator", "default_run_dir", "PortInfo", "resolve_mode",
           "port_formats", "UART_NUM", "EMIFA_BYTE_TIME_S", "dsp_uart_baud"]

UART_NUM = {"uart0": UART_HOST, "uart1": UART_IMU, "uart2": UART_PSNS, "uart3": UART_GNSS}
PORT_ROLES = {
    "gyro": "STIM210 gyro -> FPGA (RS422)",
    "gnss": "GNSS receiver -> FPGA (RS422)",
    "psns": "polarization sensor -> FPGA (RS232)",
    "host": "FPGA HOST (RS422) <-> DSP UART0: navigation out, commands in",
    "monitor": "FPGA MONITOR: every channel, tagged and time-stamped",
}
#: default baud of each external port
PORT_BAUD = {"gyro": 460800, "gnss": 9600, "host": 460800, "psns": 115200, "monitor": 3_000_000}
#: One byte read by the DSP from the FPGA UART core over EMIFA, s [E: a few EMIFA async cycles].
EMIFA_BYTE_TIME_S = 1e-7
#: 1 Hz samples (timeline.csv, filter_state.csv) are taken this long after each whole second, half an IMU
#: period, so that no tick of the 200 Hz executive coincides with them (a sample never depends on the
#: order of callbacks scheduled for the same instant).
SAMPLE_OFFSET_S = 0.0025


def port_formats(name: str) -> dict[str, list[Any]]:
    """Stream-decoder formats per direction for a port / UART name (recorder, monitor, tests)."""
    host = {"out": [HostFormat()], "in": [HostFormat()]}
    table: dict[str, dict[str, list[Any]]] = {
        "gyro": {"in": [Stim210Format("m")]},
        "gnss": {"in": [NmeaFormat()]},
        "psns": {"in": [PsnsFormat()]},
        "host": host,
        "uart0": host,
        "uart1": {"in": [ImuFrameFormat()]},
        "uart2": {"in": [PsnsFormat()]},
        "uart3": {"in": [NmeaFormat()]},
    }
    api = monitor_api()
    if api is not None:
        from protocols.monitor import MonitorFormat

        table["monitor"] = {"out": [MonitorFormat()]}
    try:  # C2: UART1 carries MAG frames too
        from protocols.imu_frame import FpgaFrameFormat  # type: ignore[attr-defined]

        table["uart1"] = {"in": [FpgaFrameFormat()]}
    except ImportError:
        pass
    try:  # a GNSS port may carry UBX after the NMEA sentences
        from protocols.ubx import UbxFormat  # type: ignore[import-not-found]

        table["gnss"] = table["uart3"] = {"in": [NmeaFormat(), UbxFormat()]}
    except ImportError:
        pass
    return {d: list(f) for d, f in table.get(name, {}).items()}


class PortInfo(dict):
    """One row of the port map printed at start: name, role, url, baud, mode, path."""


def default_run_dir(name: str, base: str | Path = "runs") -> Path:
    stamp = _dt.datetime.now(_dt.timezone.utc).strftime("%Y%m%dT%H%M%SZ")
    return Path(base) / f"{name}-{stamp}"


def resolve_mode(scn: Scenario, requested: str | None = None) -> str:
    """The time mode of a run (see module docstring)."""
    if requested:
        return requested
    if "mode" in scn.model_fields_set:
        return scn.mode
    for spec in _port_specs(scn).values():
        if parse_link_url(spec.url).scheme != "mem":
            return "realtime"
    return "fast"


def dsp_uart_baud(nominal: int, uart_clock_hz: float | None, oversampling: int) -> int:
    """Baud a C6747 UART really runs at: ``clock / (os x divisor)``, divisor rounded (SPRS377 6.24)."""
    if uart_clock_hz is None:
        return nominal
    div = max(1, min(65535, int(round(uart_clock_hz / (oversampling * nominal)))))
    return int(round(uart_clock_hz / (oversampling * div)))


def _port_specs(scn: Scenario) -> dict[str, LinkSpec]:
    specs = {"gyro": scn.links.gyro, "gnss": scn.links.gnss, "host": scn.links.host}
    if scn.links.psns is not None:
        specs["psns"] = scn.links.psns
    if scn.links.monitor is not None:
        specs["monitor"] = scn.links.monitor
    return specs


def _line(spec: LinkSpec, default_baud: int) -> LineConfig:
    bits, parity, stop = parse_mode(spec.mode)
    return LineConfig(baud=spec.baud or default_baud, data_bits=bits, parity=parity, stop_bits=stop,
                      tx_queue_bytes=spec.queue_bytes)


def _device_line(spec: LinkSpec, fpga_line: LineConfig) -> LineConfig:
    kw: dict[str, Any] = {}
    if spec.device_baud is not None:
        kw["baud"] = spec.device_baud
    if spec.device_mode is not None:
        kw["data_bits"], kw["parity"], kw["stop_bits"] = parse_mode(spec.device_mode)
    return fpga_line.with_(**kw) if kw else fpga_line


class Emulator:
    """One emulated run (see module docstring).

    Parameters
    ----------
    scn : the validated scenario.
    run_dir : where the recorder writes.
    mode : ``fast`` / ``realtime`` (None: :func:`resolve_mode`).
    seed : overrides the scenario's seed.
    progress : called once per simulated second with ``(t, duration)``.
    replay : capture records to replay into the DSP instead of running sensors.
    """

    def __init__(self, scn: Scenario, run_dir: Path, mode: str | None = None, seed: int | None = None,
                 progress: Callable[[float, float], None] | None = None,
                 replay: list[CaptureRecord] | None = None) -> None:
        self.scn = scn
        self.run_dir = Path(run_dir)
        self.mode = resolve_mode(scn, mode)
        self.seed = scn.seed if seed is None else seed
        self.progress = progress
        self.replay = replay
        self.loop: EmulatorLoop | None = None
        self.links: dict[str, Link] = {}
        self.device_ends: dict[str, Link] = {}
        self.ports: list[PortInfo] = []
        self.recorder: Recorder | None = None
        self.dsp: VirtualDsp | None = None
        self.fpga: VirtualFpga | None = None
        self.gyro: Stim210Gyro | None = None
        self.gnss: GnssReceiver | None = None
        self.sensors: Any = None
        self.summary: dict[str, Any] = {}
        self.replayed_records = 0
        self.replay_source: str | None = None
        self._fw0: Firmware | None = None
        self.faults: Any = None
        self._last_sample_t = 0.0
        self._started = False
        self._stopped = False
        self._wall0 = 0.0
        self._status_prev = (0.0, 0.0, 0)

    @property
    def fw(self) -> Firmware | None:
        """The firmware the DSP runs now (a watchdog reset replaces it)."""
        return self.dsp.fw if self.dsp is not None else self._fw0

    # -- construction ------------------------------------------------------------------------
    async def start(self) -> None:
        loop = asyncio.get_running_loop()
        if not isinstance(loop, EmulatorLoop):
            from ..errors import EmulatorError

            raise EmulatorError("the emulator runs on an emulator.clock.EmulatorLoop")
        self.loop = loop
        scn = self.scn
        traj = self.trajectory = build_trajectory(scn)
        rec = self.recorder = Recorder(self.run_dir, traj)
        hub = MemHub()
        port_dir = self.run_dir / "ports"
        ext: dict[str, Link] = {}
        internal: dict[str, Link] = {}
        specs = _port_specs(scn)
        if self.replay is not None:
            specs = {"host": specs["host"]}  # sensors are replaced by the capture
        for port, spec in specs.items():
            line = _line(spec, PORT_BAUD[port])
            u = parse_link_url(spec.url)
            if u.scheme == "mem" or self.replay is not None:
                a, b = hub.pair(port, line, loop, line_b=_device_line(spec, line), key=f"{port}:{u.target}")
                a.url = b.url = spec.url if u.scheme == "mem" else f"mem://{port}"
                ext[port], internal[port] = a, b
                self.device_ends[port] = b
            else:
                ext[port] = open_link(spec.url, port, loop, default_line=line, hub=hub, run_dir=port_dir)
            self.links[port] = ext[port]
        uart_fpga, uart_dsp, rx_cfg = self._build_uarts(hub, loop, ext)
        # sensors (C3)
        if self.replay is None:
            sensors = build_sensors(scn, self.seed, traj, internal, pps=self._pps)
            self.sensors = sensors
            self.gyro, self.gnss = sensors.gyro, sensors.gnss
            gyro, accel = sensors.gyro, sensors.accel
        else:
            gyro = accel = None
        fcfg = FpgaConfig(imu_rate_hz=scn.sensors.imu.rate_hz, gyro_timeout_s=scn.fpga.gyro_timeout_s,
                          gyro_format=scn.sensors.imu.format,
                          gyro_counter_step=int(round(2000 / scn.sensors.imu.rate_hz)),
                          routing=dict(scn.fpga.routing),
                          monitor_channels=tuple(scn.fpga.monitor_channels) if scn.fpga.monitor_channels else None,
                          mag_rate_hz=scn.fpga.mag_rate_hz)
        fpga_ports = {k: v for k, v in ext.items() if k != "monitor"}
        mag = getattr(self.sensors, "mag", None) if self.replay is None else None
        self.fpga = VirtualFpga(loop, fcfg, fpga_ports, uart_fpga, gyro, accel, rec, monitor=ext.get("monitor"),
                                mag=mag)
        self.dsp = self.build_dsp(uart_dsp, rx_cfg, rec)
        if scn.faults and self.replay is None:  # bound now: a fault on a missing device fails before the run
            from ..faults import FaultScheduler

            self.faults = FaultScheduler(self.fault_targets(), scn.faults, self.seed, rec)
        # recorder taps
        for name, link in self.links.items():
            fm = port_formats(name)
            if name == "gyro":
                fm = {"in": [Stim210Format(scn.sensors.imu.format)]}
            rec.tap(name, link, fm)
        for link in ext.values():
            if link.scheme != "mem":
                await link.open()
        self._port_map(uart_fpga)
        (self.run_dir / "ports.json").write_text(json.dumps([dict(p) for p in self.ports], indent=2) + "\n")
        rec.start({"scenario": scn.name, "seed": self.seed, "epoch": scn.epoch.isoformat(),
                   "mode": self.mode, "link_baud": {k: v.line.baud for k, v in self.links.items()},
                   "psns_hil_version": VERSION, "replay": self.replay is not None,
                   "scenario_spec": scn.model_dump(mode="json")})
        if self.mode == "realtime":
            # everything built so far (modules, scenario, models) lives for the whole run: move it out of
            # the collector's generations, so a full collection no longer walks it (tens of ms, a late frame)
            gc.collect()
            gc.freeze()
        loop.restart_clock()
        self._wall0 = loop.wall_elapsed()
        if self.faults is not None:
            self.faults.start()
        loop.call_at(1.0 + SAMPLE_OFFSET_S, self._sample_tick)
        if self.replay is None:
            self.fpga.start()
            self.sensors.start()
        else:
            self._start_replay()
        if self.progress is not None:
            self._progress_tick()
        self._started = True

    def fault_targets(self) -> FaultTargets:
        """What the scenario's faults may touch (:mod:`emulator.faults`): sensors, links, FPGA, DSP."""
        assert self.loop is not None
        return FaultTargets(clock=self.loop, duration_s=self.scn.duration_s, imu_rate_hz=self.scn.sensors.imu.rate_hz,
                            source_file=self.scn.source_file, sensors=self.sensors, links=self.links, fpga=self.fpga,
                            dsp=self.dsp, firmware_counters=self._firmware_counters)

    def _firmware_counters(self) -> dict[str, int]:
        fw = self.fw
        return getattr(fw, "counters", {}) if fw is not None else {}

    def build_dsp(self, uart_dsp: dict[int, Link], rx_cfg: dict[int, UartRxConfig], events: Any) -> VirtualDsp:
        """The virtual DSP hosting this scenario's firmware on ``uart_dsp`` (also used by a split run's DSP
        process, :mod:`emulator.distributed.split`)."""
        assert self.loop is not None
        scn = self.scn
        self._fw0 = build_firmware(scn)
        wd = scn.dsp.watchdog
        return VirtualDsp(self.loop, self._fw0, uart_dsp, scn.dsp.clock_hz, events,
                          tick_period_s=1.0 / scn.sensors.imu.rate_hz, rx=rx_cfg,
                          watchdog=WatchdogConfig(wd.enabled, wd.overrun_multiple, wd.action, wd.reset_time_s),
                          firmware_factory=lambda: build_firmware(scn))

    def _pps(self, t: float) -> None:
        assert self.fpga is not None
        self.fpga.pps_edge(t)

    def _build_uarts(self, hub: MemHub, loop: EmulatorLoop, ext: dict[str, Link]
                     ) -> tuple[dict[str, Link], dict[int, Link], dict[int, UartRxConfig]]:
        scn = self.scn
        uart_fpga: dict[str, Link] = {}
        uart_dsp: dict[int, Link] = {}
        rx_cfg: dict[int, UartRxConfig] = {}
        routed_from = {u: p for p, u in scn.fpga.routing.items()}
        for uname, uspec in scn.fpga.uarts.items():
            dspec = scn.dsp.uarts[uname]
            bits, parity, stop = parse_mode(uspec.mode)
            emifa = uspec.effective_bus(uname) == "emifa"
            if emifa:  # the FPGA's UART core, read by the DSP over EMIFA
                f_line = LineConfig(baud=int(round(10 / EMIFA_BYTE_TIME_S)), tx_queue_bytes=uspec.fifo_bytes)
                d_line = f_line.with_(tx_queue_bytes=dspec.tx_ring_bytes)
            else:
                f_line = LineConfig(baud=uspec.effective_baud(uname), data_bits=bits, parity=parity, stop_bits=stop,
                                    tx_queue_bytes=uspec.fifo_bytes)
                d_baud = dspec.baud or f_line.baud
                if uname != "uart3":
                    d_baud = dsp_uart_baud(d_baud, scn.dsp.uart_clock_hz, dspec.oversampling)
                d_line = f_line.with_(baud=d_baud, tx_queue_bytes=dspec.tx_ring_bytes)
                if dspec.mode is not None:
                    db, dp, ds = parse_mode(dspec.mode)
                    d_line = d_line.with_(data_bits=db, parity=dp, stop_bits=ds)
            a, b = hub.pair(uname, f_line, loop, line_b=d_line)
            uart_fpga[uname], uart_dsp[UART_NUM[uname]] = a, b
            self.links[uname] = b
            # fastest byte arrival: the DSP line, or the routed port's line feeding an EMIFA core
            # (from the scenario, so that a replay, which has no such port, decides the same)
            min_pitch = d_line.byte_time
            src = routed_from.get(uname)
            src_spec = _port_specs(scn).get(src) if src is not None else None
            if emifa and src_spec is not None:
                min_pitch = max(min_pitch, _line(src_spec, PORT_BAUD[src]).byte_time)
            rx_cfg[UART_NUM[uname]] = UartRxConfig(
                fifo_bytes=dspec.fifo_bytes, trigger_level=dspec.trigger_level, service=dspec.service,
                service_latency_s=dspec.latency_s, rx_ring_bytes=dspec.rx_ring_bytes, min_pitch_s=min_pitch)
        return uart_fpga, uart_dsp, rx_cfg

    def _port_map(self, uart_fpga: dict[str, Link]) -> None:
        for port, link in self.links.items():
            if port.startswith("uart"):
                continue
            self.ports.append(PortInfo(name=port, role=PORT_ROLES.get(port, port), url=link.url,
                                       baud=link.line.baud, mode=link.line.mode, path=link.describe()))
        routed_from = {u: p for p, u in self.scn.fpga.routing.items()}
        for uname, f_end in uart_fpga.items():
            d_end = self.links[uname]
            emifa = self.scn.fpga.uarts[uname].effective_bus(uname) == "emifa"
            src = "IMU frames" if uname == "uart1" else routed_from.get(uname, "unrouted")
            role = (f"FPGA UART core on EMIFA -> DSP {uname.upper()} ({src})" if emifa
                    else f"FPGA -> DSP {uname.upper()} 16550 ({src})")
            baud = "EMIFA" if emifa else (f"{f_end.line.baud}" if f_end.line.baud == d_end.line.baud
                                          else f"{f_end.line.baud}/{d_end.line.baud}")
            self.ports.append(PortInfo(name=uname, role=role, url="internal", baud=baud, mode=d_end.line.mode,
                                       path="internal"))

    def _start_replay(self) -> None:
        """Schedule the captured DSP-UART input (see :mod:`emulator.recording.replay`)."""
        assert self.loop is not None and self.replay is not None
        recs = [r for r in self.replay if r.link in UART_NUM and r.direction == "in"]
        self._replay_recs = recs
        self._replay_i = 0
        if recs:
            self.loop.call_at(recs[0].t_s, self._replay_step)

    def _replay_step(self) -> None:
        recs = self._replay_recs
        i = self._replay_i
        t = recs[i].t_s
        while i < len(recs) and recs[i].t_s == t:
            r = recs[i]
            link = self.links[r.link]
            link.last_rx_pitch = r.pitch_s if r.pitch_s is not None else link.line.byte_time
            link._deliver(r.data)  # noqa: SLF001 - the bytes arrived: deliver as the link did
            self.replayed_records += 1
            i += 1
        self._replay_i = i
        if i < len(recs) and self.loop is not None:
            self.loop.call_at(recs[i].t_s, self._replay_step)

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
        sec = int(round(t - SAMPLE_OFFSET_S))
        self._sample(float(sec))
        if sec + 1 + SAMPLE_OFFSET_S < self.scn.duration_s:
            self.loop.call_at(sec + 1 + SAMPLE_OFFSET_S, self._sample_tick)

    def _sample(self, t: float, final: bool = False) -> None:
        """One row of ``timeline.csv`` (link counters, DSP load in the second before ``t``) and, except for
        the ``final`` row at the end of the run, of ``filter_state.csv`` (the filter's state)."""
        rec, dsp = self.recorder, self.dsp
        if rec is None or dsp is None:
            return
        self._last_sample_t = t
        local = isinstance(dsp, VirtualDsp)  # a split run's DSP lives in another process
        row: dict[str, Any] = {"time_s": t, "nav_frames": rec.nav_count}
        b = math.ceil(t - 1e-9) - 1  # the second [b, b + 1) that ends at or contains t
        span = min(1.0, t - b)
        if local:
            row["cpu_load_pct"] = 100.0 * dsp.busy_per_second.get(b, 0.0) / span if span > 0 else 0.0
        row["deadline_misses"] = dsp.deadline_misses
        row["watchdog_trips"] = dsp.watchdog_trips
        for name, v in rec.link_summary().items():
            for k in ("frames", "crc_errors", "dropped", "garbage_bytes", "framing_errors"):
                row[f"{name}_{k}"] = v[k]
        rec.table_row("timeline", row)
        if final or not local:
            return
        fw = dsp.fw
        flt = getattr(fw, "filter", None)
        st: dict[str, Any] = {"time_s": t, "state": getattr(fw, "state", ""), "mode": int(getattr(fw, "mode", 0))}
        p = getattr(flt, "P", None)
        if p is not None:
            for i, v in enumerate(np.asarray(p).diagonal().tolist()):
                st[f"p{i}"] = float(v)
        for name in ("gyro_bias", "accel_bias"):
            b = getattr(flt, name, None)
            if b is not None:
                for ax, v in zip("xyz", np.asarray(b).tolist()):
                    st[f"{name}_{ax}"] = float(v)
        rec.table_row("filter_state", st)

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
        from ..clock import sleep_until

        await sleep_until(t)

    async def run(self) -> dict[str, Any]:
        interrupted = False
        try:
            await self.start()
            await self.run_until(self.scn.duration_s)
        except asyncio.CancelledError:
            interrupted = True
        except BaseException:
            await self._abort()
            raise
        return await self.stop(interrupted=interrupted)

    async def _abort(self) -> None:
        """Start failed: release what was opened (ptys, files); no summary."""
        self._stopped = True
        for link in list(self.links.values()) + list(self.device_ends.values()):
            try:
                await link.close()
            except Exception:  # noqa: BLE001
                pass
        if self.recorder is not None:
            self.recorder.close()

    async def stop(self, interrupted: bool = False) -> dict[str, Any]:
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
        for link in list(self.links.values()) + list(self.device_ends.values()):
            try:
                await link.close()
            except Exception:  # noqa: BLE001 - closing must not lose the summary
                pass
        wall = loop.wall_elapsed()
        try:
            self.summary = s = self._summary(sim_t, wall, interrupted)
            s["faults"] = fault_records
            s["valid"] = self.faults.valid if self.faults is not None else True
            rec.flush()
            results = evaluate_expectations(self.scn.expectations, rec, s, run_dir=self.run_dir,
                                            base_dir=self.scn.base_dir)
            s["expectations"] = [r.as_dict() for r in results]
            s["passed"] = all(r.passed for r in results) and not interrupted and s["valid"]
            rec.write_summary(s)
        finally:
            rec.close()
        return s

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
            "interrupted": interrupted,
            "replay": {"source": self.replay_source, "records": self.replayed_records} if self.replay is not None
            else None,
            "run_dir": str(self.run_dir),
            "nav_error": {k: v.as_dict() for k, v in rec.errors.items()},
            "nav_frames": rec.nav_count,
            "links": rec.link_summary(),
            "link_stats": {k: dict(v.stats.as_dict(), error=v.error) for k, v in self.links.items()},
            **self.dsp_sections(),
            "fpga": {"imu_frames": self.fpga.imu_frames, "gyro_missing": self.fpga.gyro_missing,
                     "mag_frames": self.fpga.mag_frames, "routes": self.fpga.routes,
                     "monitor_records": self.fpga.monitor_records},
            "devices": self.sensors.counters() if self.sensors is not None else {},
            "ports": [dict(p) for p in self.ports],
            "events": dict(rec.event_counts),
        }


    def dsp_sections(self) -> dict[str, Any]:
        """The ``dsp`` and ``firmware`` sections of the summary."""
        dsp = self.dsp
        assert dsp is not None
        fw = dsp.fw
        return {
            "dsp": {
                "clock_hz": dsp.clock_hz,
                "cpu_load_pct_max": dsp.cpu_load_pct_max(),
                "tick_utilization_max_pct": 100.0 * dsp.max_tick_cycles / fw.meter.tick_budget,
                "tick_budget_cycles": fw.meter.tick_budget,
                "deadline_misses": dsp.deadline_misses,
                "ticks": dsp.ticks,
                "cost_model": COST_MODEL_VERSION,
                "tasks": fw.meter.table(),
                **dsp.counters(),
            },
            "firmware": {"filter": fw.cfg.filter, "precision": fw.cfg.precision, "counters": dict(fw.counters),
                         "decoders": fw.decoder_stats()},
        }


def run_emulator(emu: Emulator, speed: float = 1.0, on_started: Callable[[Emulator], None] | None = None
                 ) -> dict[str, Any]:
    """Run ``emu`` to completion (or interruption) on a fresh :class:`EmulatorLoop`.

    SIGINT and SIGTERM cancel the run; the recorder still writes everything it has and a
    summary with ``"interrupted": true``.
    """
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
                while not emu._started:  # noqa: SLF001
                    await asyncio.sleep(0)
                on_started(emu)
            loop.create_task(_notify())
        return await emu.run()

    task = loop.create_task(main())
    loop.set_exception_handler(on_error)
    for sig in (signal.SIGINT, signal.SIGTERM):
        try:
            loop.add_signal_handler(sig, task.cancel)
        except (NotImplementedError, RuntimeError, ValueError):
            pass
    try:
        summary = loop.run_until_complete(task)
        if failure:
            from ..errors import EmulatorError

            ctx = failure[0]
            exc = ctx.get("exception")
            raise EmulatorError(f"the run stopped at t = {summary.get('sim_duration_s', 0):.6f} s: "
                                f"{ctx.get('message', 'error')}: {exc!r} (summary and captures kept in "
                                f"{emu.run_dir})") from exc
        return summary
    finally:
        for sig in (signal.SIGINT, signal.SIGTERM):
            try:
                loop.remove_signal_handler(sig)
            except (NotImplementedError, RuntimeError, ValueError):
                pass
        asyncio.set_event_loop(None)
        loop.close()


def run_scenario(scn: Scenario, run_dir: Path, mode: str | None = None, speed: float | None = None,
                 seed: int | None = None, progress: Callable[[float, float], None] | None = None,
                 on_started: Callable[[Emulator], None] | None = None) -> dict[str, Any]:
    """Run ``scn`` to completion (or interruption) on a fresh :class:`EmulatorLoop`."""
    emu = Emulator(scn, run_dir, mode=mode, seed=seed, progress=progress)
    return run_emulator(emu, speed if speed is not None else scn.speed, on_started)
