"""The virtual TMS320C6747: UARTs, the firmware host, and cycles turned into time.

UART0-2 are the C6747's on-chip 16550-style UARTs and UART3 is the FPGA's UART core read over
EMIFA (DESIGN.md section 2). Bytes arriving on a UART go to the firmware's ring buffers
(:meth:`firmware_model.Firmware.receive`); an IMU frame on UART1 starts the cyclic executive.

Time: the firmware charges cycles; at ``clock_hz`` a tick that starts at ``t_start`` and
charges ``c`` cycles ends at ``t_start + c / clock_hz``, and each output leaves its UART at the
moment the firmware produced it (``t_start + cycles_at_emit / clock_hz``). A tick that cannot
start before the next IMU frame is due (its deadline, one IMU period after its frame arrived)
or does not finish by then is a counted deadline miss.
"""

from __future__ import annotations

import asyncio

from firmware_model import UART_IMU, Firmware

from ..links.base import Link
from .base import EventSink, NullEvents

__all__ = ["VirtualDsp"]


class VirtualDsp:
    """See module docstring.

    Parameters
    ----------
    uarts : DSP-side link ends by UART number.
    """

    def __init__(self, loop: asyncio.AbstractEventLoop, firmware: Firmware, uarts: dict[int, Link],
                 clock_hz: float, events: EventSink | None = None, tick_period_s: float = 0.005) -> None:
        self.loop = loop
        self.fw = firmware
        self.uarts = uarts
        self.clock_hz = clock_hz
        self.events = events or NullEvents()
        self.period = tick_period_s
        self.busy_until = 0.0
        self.deadline_misses = 0
        self.ticks = 0
        self.busy_time = 0.0
        self.max_tick_cycles = 0
        self._scheduled = False
        self._arrival = 0.0
        self.busy_per_second: dict[int, float] = {}
        for n, link in uarts.items():
            link.on_receive = self._make_rx(n)

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

    def _make_rx(self, uart: int):  # noqa: ANN202
        def rx(data: bytes) -> None:
            self.fw.receive(uart, data, self.loop.time())
            if uart == UART_IMU and not self._scheduled:
                self._scheduled = True
                self._arrival = self.loop.time()
                self.loop.call_soon(self._run)

        return rx

    def _run(self) -> None:
        self._scheduled = False
        now = self.loop.time()
        arrival = self._arrival
        for r in self.fw.service():
            start = max(now, self.busy_until)
            dur = r.cycles / self.clock_hz
            end = start + dur
            self.busy_until = end
            self.busy_time += dur
            self._account(start, end)
            self.ticks += 1
            self.max_tick_cycles = max(self.max_tick_cycles, r.cycles)
            if end > arrival + self.period:
                self.deadline_misses += 1
                self.fw.note_deadline_miss()
                self.events.emit(now, "dsp", "deadline_miss", t_fpga_s=r.t_fpga_s, start_s=start, end_s=end,
                                 cycles=r.cycles)
            for ev in r.events:
                ev = dict(ev)
                kind = ev.pop("event")
                self.events.emit(start, "firmware", kind, **ev)
            for uart, data, cyc in r.outputs:
                link = self.uarts.get(uart)
                if link is not None:
                    self.loop.call_at(start + cyc / self.clock_hz, link.send, data)
            arrival += self.period
