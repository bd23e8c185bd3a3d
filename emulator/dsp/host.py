"""The virtual TMS320C6747: UARTs, the firmware host, cycles turned into time, the watchdog.

UARTs (docs/architecture.md, SPRS377 section 6.24): UART0-2 are the C6747's on-chip 16550-style
UARTs, fed by serial lines from the FPGA; UART3 is a 16550-compatible core inside the FPGA that
the DSP reads over EMIFA (its FIFO fills at the GNSS line's pace). Each has
(:class:`UartRxModel`):

* a hardware RX FIFO (16 bytes) and a trigger level (1/4/8/14);
* a service: ``isr`` / ``edma`` -- when the FIFO reaches its trigger level (or after the 16550
  character timeout of 4 character times with bytes below the trigger level) the FIFO is
  drained ``service_latency_s`` later; ``poll`` -- the main loop drains it once per tick.
  A byte that completes while the FIFO is full is an **overrun**: lost and counted
  (LSR.OE), exactly what a too-slow drain does to a real 16550;
* the firmware's RX ring buffer (``rx_ring_bytes``), emptied by the main loop whenever it is not
  running a tick: the bytes that arrive while a tick runs wait there until it ends; bytes that do
  not fit are lost and counted. (An idle main loop drains the ring whether or not the bytes make
  a frame: a stream of garbage on UART1 -- no valid IMU frame, hence no tick -- must not fill the
  ring for good and starve the firmware of the frames that follow: D-7.14.)

The surviving bytes go to the firmware's ``receive`` (:class:`firmware_model.registry.FirmwareProtocol`, the
only thing the DSP uses of a firmware) with their reception time; an
IMU frame on UART1 starts the cyclic executive. When no overrun is possible (the trigger level
plus the bytes that can arrive during the service latency fit in the FIFO) the byte-by-byte FIFO
model is skipped: it could not change anything.

Time: the firmware charges cycles; at ``clock_hz`` a tick that starts at ``t_start`` and charges
``c`` cycles ends at ``t_start + c / clock_hz``, and each output leaves its UART at the moment the
firmware produced it (``t_start + cycles_at_emit / clock_hz``), through the firmware's TX ring
(a frame that does not fit is dropped whole and counted). A tick that does not end within one
IMU period of its frame's arrival is a counted deadline miss.

Watchdog: the firmware kicks it once per tick. A tick running longer than
``overrun_multiple`` IMU periods trips it: a ``watchdog`` event, and with ``action: reset`` the
DSP drops that tick's remaining outputs, reboots (busy ``reset_time_s``, UART input ignored)
and starts a fresh firmware from the factory.
"""

from __future__ import annotations

import asyncio
import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from firmware_model import UART_IMU
from firmware_model.registry import FirmwareProtocol, SolarSolve

from ..devices.base import EventSink, NullEvents
from ..links.base import Link

__all__ = ["UartRxConfig", "UartRxModel", "VirtualDsp", "WatchdogConfig"]


@dataclass(frozen=True)
class UartRxConfig:
    """Receive path of one DSP UART (see module docstring; units in the names)."""

    fifo_bytes: int = 16
    trigger_level: int = 8
    service: str = "isr"
    service_latency_s: float = 2e-6
    rx_ring_bytes: int = 4096
    #: shortest possible spacing of arriving bytes, s (the line's byte time)
    min_pitch_s: float = 10 / 460800


@dataclass(frozen=True)
class WatchdogConfig:
    enabled: bool = True
    overrun_multiple: float = 4.0
    action: str = "flag"
    reset_time_s: float = 0.05


class UartRxModel:
    """16550 RX FIFO + service + firmware ring of one UART (see module docstring)."""

    __slots__ = (
        "_char_timeout",
        "bytes_in",
        "cfg",
        "drains",
        "level",
        "lossless",
        "overrun_bytes",
        "polls",
        "ring_fill",
        "ring_overflow_bytes",
        "t_drain",
        "t_last",
        "uart",
    )

    def __init__(self, uart: int, cfg: UartRxConfig) -> None:
        self.uart = uart
        self.cfg = cfg
        lat = cfg.service_latency_s
        self.lossless = cfg.service != "poll" and (
            cfg.trigger_level + math.ceil(lat / cfg.min_pitch_s - 1e-9) - 1 <= cfg.fifo_bytes)
        self.level = 0
        self.t_drain: float | None = None
        self.t_last = -math.inf
        self.ring_fill = 0
        self.bytes_in = 0
        self.overrun_bytes = 0
        self.ring_overflow_bytes = 0
        self.drains = 0
        self.polls: deque[float] = deque()
        self._char_timeout = 4.0 * cfg.min_pitch_s

    def accept(self, now: float, data: bytes, pitch: float) -> bytes:
        """Bytes that survive the FIFO and the ring; the last one completed at ``now``."""
        n = len(data)
        self.bytes_in += n
        if not self.lossless:
            data = self._fifo(now, data, pitch)
            n = len(data)
        room = self.cfg.rx_ring_bytes - self.ring_fill
        if n > room:
            self.ring_overflow_bytes += n - room
            data = data[:max(room, 0)]
            n = len(data)
        self.ring_fill += n
        return data

    def _fifo(self, now: float, data: bytes, pitch: float) -> bytes:
        cfg = self.cfg
        lat = cfg.service_latency_s
        cap = cfg.fifo_bytes
        trig = cfg.trigger_level
        poll = cfg.service == "poll"
        polls = self.polls
        level = self.level
        t_drain = self.t_drain
        t_last = self.t_last
        n = len(data)
        keep = bytearray()
        lost = 0
        for i in range(n):
            t = now - (n - 1 - i) * pitch
            if poll:
                while polls and polls[0] <= t:
                    polls.popleft()
                    if level:
                        level = 0
                        self.drains += 1
            else:
                if t_drain is not None and t_drain <= t:
                    level = 0
                    t_drain = None
                    self.drains += 1
                elif t_drain is None and level and t_last + self._char_timeout + lat <= t:
                    level = 0  # character-timeout interrupt drained the bytes below the trigger level
                    self.drains += 1
            if level >= cap:
                lost += 1
            else:
                level += 1
                keep.append(data[i])
                if not poll and t_drain is None and level >= trig:
                    t_drain = t + lat
            t_last = t
        self.level = level
        self.t_drain = t_drain
        self.t_last = t_last
        if lost:
            self.overrun_bytes += lost
            return bytes(keep)
        return data

    def idle(self) -> None:
        """Bytes arrive while no tick runs: the idle main loop has emptied the ring."""
        self.ring_fill = 0

    def tick(self, t: float) -> None:
        """The main loop ran at ``t``: it empties the ring (and, when polling, the FIFO)."""
        self.ring_fill = 0
        if self.cfg.service == "poll":
            if self.polls and self.polls[-1] > t:
                return
            self.polls.append(t)

    def as_dict(self) -> dict[str, Any]:
        c = self.cfg
        return {"service": c.service, "fifo_bytes": c.fifo_bytes, "trigger_level": c.trigger_level,
                "service_latency_s": c.service_latency_s, "rx_ring_bytes": c.rx_ring_bytes,
                "bytes_in": self.bytes_in, "overrun_bytes": self.overrun_bytes,
                "ring_overflow_bytes": self.ring_overflow_bytes, "lossless_config": self.lossless}


class VirtualDsp:
    """See module docstring.

    Parameters
    ----------
    firmware : the firmware instance the DSP hosts.
    uarts : DSP-side link ends by UART number.
    clock_hz : CPU clock.
    rx : receive-path configuration per UART number (default: on-chip 16550 defaults).
    watchdog : watchdog configuration.
    firmware_factory : builds a fresh firmware after a watchdog reset (None: ``flag`` only).
    """

    def __init__(self, loop: asyncio.AbstractEventLoop, firmware: FirmwareProtocol, uarts: dict[int, Link],
                 clock_hz: float, events: EventSink | None = None, tick_period_s: float = 0.005,
                 rx: dict[int, UartRxConfig] | None = None, watchdog: WatchdogConfig | None = None,
                 firmware_factory: Callable[[], FirmwareProtocol] | None = None) -> None:
        self.loop = loop
        self.fw = firmware
        self.uarts = uarts
        self.clock_hz = clock_hz
        self.events = events or NullEvents()
        self.period = tick_period_s
        self.watchdog = watchdog or WatchdogConfig()
        self.firmware_factory = firmware_factory
        self.busy_until = 0.0
        self.deadline_misses = 0
        #: ticks whose own modelled duration exceeded the IMU period (cycles over the tick budget): the misses the
        #: firmware's cost causes by itself, apart from a late start (a backlog, or in a --split run the DSP
        #: process waking late on the wall clock)
        self.over_budget_ticks = 0
        self.ticks = 0
        self.busy_time = 0.0
        self.max_tick_cycles = 0
        self.watchdog_trips = 0
        self.resets = 0
        self.dropped_while_resetting = 0
        self.outputs_dropped_by_reset = 0
        self._booting_until = -1.0
        #: injected fault (emulator.faults): cycles charged at the start of every tick before the
        #: firmware's own work (a runaway task or an interrupt storm), and the ticks that paid them
        self.extra_cycles_per_tick = 0
        self.extra_load_ticks = 0
        self.extra_cycles_total = 0
        self._tick_queued = False
        self._arrival = 0.0
        self.busy_per_second: dict[int, float] = {}
        #: called with the solar vectors each tick solved (``TickResult.solar_solves``; the recorder's psns.csv)
        self.solar_listeners: list[Callable[[list[SolarSolve]], None]] = []
        rx = rx or {}
        self.rx: dict[int, UartRxModel] = {}
        for n, link in uarts.items():
            cfg = rx.get(n) or UartRxConfig(min_pitch_s=link.line.byte_time)
            self.rx[n] = UartRxModel(n, cfg)
            link.on_receive = self._make_rx(n, link)
        self._rx_models = tuple(self.rx.values())
        #: how the tick after an IMU frame is scheduled: the loop's next callback (``call_soon``), on the emulator's
        #: loop without a handle where that is the same thing (:meth:`emulator.clock.EmulatorLoop.call_next`)
        self._soon: Callable[[Callable[[], None]], object] = getattr(loop, "call_next", loop.call_soon)

    def _account(self, start: float, end: float) -> None:
        """Add the busy interval to per-second bins (for the 1 s CPU-load figure)."""
        while start < end:
            sec = int(start)
            seg_end = min(end, sec + 1.0)
            self.busy_per_second[sec] = self.busy_per_second.get(sec, 0.0) + (seg_end - start)
            start = seg_end

    def cpu_load_pct_max(self) -> float:
        """Worst whole-second CPU load, % (partial first/last seconds included)."""
        return 100.0 * max(self.busy_per_second.values(), default=0.0)

    def _make_rx(self, uart: int, link: Link) -> Callable[[bytes], None]:
        model = self.rx[uart]
        loop = self.loop
        is_imu = uart == UART_IMU

        def rx(data: bytes) -> None:
            now = loop.time()
            if now < self._booting_until:
                self.dropped_while_resetting += len(data)
                link.stats.dropped_in += len(data)
                return
            if now >= self.busy_until:
                model.idle()
            kept = model.accept(now, data, link.last_rx_pitch)
            if len(kept) != len(data):
                link.stats.dropped_in += len(data) - len(kept)
                if not kept:
                    return
            self.fw.receive(uart, kept, now)
            if is_imu and not self._tick_queued:
                self._tick_queued = True
                self._arrival = now
                self._soon(self._run)

        return rx

    def _run(self) -> None:
        self._tick_queued = False
        now = self.loop.time()
        arrival = self._arrival
        wd = self.watchdog
        wd_limit = wd.overrun_multiple * self.period if wd.enabled else math.inf
        for r in self.fw.service():
            start = now if now > self.busy_until else self.busy_until
            for m in self._rx_models:
                m.tick(start)
            extra = self.extra_cycles_per_tick
            cycles = r.cycles
            if extra:
                cycles += extra
                self.extra_load_ticks += 1
                self.extra_cycles_total += extra
            dur = cycles / self.clock_hz
            end = start + dur
            self.ticks += 1
            if cycles > self.max_tick_cycles:
                self.max_tick_cycles = cycles
            if dur > wd_limit:
                self._watchdog(start, r, extra)
                return
            self.busy_until = end
            self.busy_time += dur
            self._account(start, end)
            if dur > self.period:
                self.over_budget_ticks += 1
            if end > arrival + self.period:
                self.deadline_misses += 1
                self.fw.note_deadline_miss()
                self.events.emit(now, "dsp", "deadline_miss", t_fpga_s=r.t_fpga_s, start_s=start, end_s=end,
                                 cycles=cycles)
            for ev in r.events:
                ev = dict(ev)
                kind = ev.pop("event")
                self.events.emit(start, "firmware", kind, **ev)
            if r.solar_solves:
                for cb in self.solar_listeners:
                    cb(r.solar_solves)
            for uart, data, cyc in r.outputs:
                link = self.uarts.get(uart)
                if link is not None:  # the firmware's driver is the UART's only writer, in time order
                    link.send_at(start + (extra + cyc) / self.clock_hz, data, True)
            arrival += self.period

    def _watchdog(self, start: float, r: Any, extra: int = 0) -> None:
        """A tick overran the watchdog period (see module docstring)."""
        wd = self.watchdog
        t_bite = start + wd.overrun_multiple * self.period
        self.watchdog_trips += 1
        reset = wd.action == "reset" and self.firmware_factory is not None
        self.events.emit(t_bite, "dsp", "watchdog", t_fpga_s=r.t_fpga_s, tick_start_s=start,
                         tick_cycles=r.cycles + extra, limit_s=wd.overrun_multiple * self.period,
                         action="reset" if reset else "flag")
        if not reset:
            # flag only: the tick completes late, its outputs leave when produced
            end = start + (r.cycles + extra) / self.clock_hz
            self.busy_until = end
            self.busy_time += end - start
            self._account(start, end)
            self.deadline_misses += 1
            self.fw.note_deadline_miss()
            for uart, data, cyc in r.outputs:
                link = self.uarts.get(uart)
                if link is not None:
                    link.send_at(start + (extra + cyc) / self.clock_hz, data, True)
            return
        # reset: outputs the tick would have produced after the bite never happen
        for uart, data, cyc in r.outputs:
            t_out = start + (extra + cyc) / self.clock_hz
            link = self.uarts.get(uart)
            if t_out <= t_bite and link is not None:
                link.send_at(t_out, data, True)
            else:
                self.outputs_dropped_by_reset += 1
        self.resets += 1
        booted = t_bite + wd.reset_time_s
        self._account(start, booted)
        self.busy_time += booted - start
        self.busy_until = booted
        self._booting_until = booted
        assert self.firmware_factory is not None
        self.fw = self.firmware_factory()
        for m in self._rx_models:
            m.ring_fill = 0
            m.level = 0
            m.t_drain = None
        self.events.emit(booted, "dsp", "firmware_restarted", resets=self.resets)

    def counters(self) -> dict[str, Any]:
        return {"watchdog_trips": self.watchdog_trips, "resets": self.resets,
                "extra_load_ticks": self.extra_load_ticks, "extra_cycles_total": self.extra_cycles_total,
                "dropped_while_resetting": self.dropped_while_resetting,
                "outputs_dropped_by_reset": self.outputs_dropped_by_reset,
                "uarts": {f"uart{n}": m.as_dict() for n, m in self.rx.items()}}
