"""The one link abstraction: line model, fault hooks and statistics, applied once.

A :class:`Link` is one device port's connection to something else: another device port
(``mem://``), a pseudo-terminal for real tools (``pty://``), a real serial device
(``serial://``), zenoh or CAN. The public methods do the shared work (template method, as
python-can's ``BusABC.recv`` / ``_recv_internal``); each transport implements only
:meth:`Link._write_raw` and feeds what it reads from outside into :meth:`Link._input`.

Directions are named from the owning device: ``out`` (device transmits) and ``in`` (device
receives).

Line model (per direction, :class:`LineModel`): an asynchronous serial line at ``baud`` with
``data_bits``, parity and ``stop_bits`` takes ``(1 + data + parity + stop) / baud`` seconds per
byte, so a 40-byte 8N1 frame occupies the line 400/baud s. Bytes written while the line is
busy wait in a bounded TX queue of ``tx_queue_bytes``; what does not fit is lost and counted
(``dropped``), as a real UART driver's ring buffer overflows. Chunks are delivered to the far
end when their last stop bit has been sent.
"""

from __future__ import annotations

import asyncio
import math
from dataclasses import dataclass, field
from typing import Callable, ClassVar, Protocol

__all__ = [
    "LineConfig",
    "LineModel",
    "LinkStats",
    "LinkListener",
    "ByteFault",
    "Link",
    "parse_mode",
]


def parse_mode(mode: str) -> tuple[int, str, float]:
    """Parse a ``"8N1"``-style frame format into (data bits, parity, stop bits)."""
    m = mode.strip().upper()
    if len(m) < 3 or m[0] not in "5678" or m[1] not in "NEO" or m[2:] not in ("1", "1.5", "2"):
        raise ValueError(f"bad serial mode {mode!r}; expected e.g. 8N1, 8E1, 7O2")
    return int(m[0]), m[1], float(m[2:])


@dataclass(frozen=True)
class LineConfig:
    """Asynchronous serial line parameters of one link."""

    baud: int = 115200
    data_bits: int = 8
    parity: str = "N"
    stop_bits: float = 1.0
    tx_queue_bytes: int = 4096

    def __post_init__(self) -> None:
        if self.baud <= 0:
            raise ValueError(f"baud must be > 0, got {self.baud}")
        if self.tx_queue_bytes < 1:
            raise ValueError("tx_queue_bytes must be >= 1")

    @property
    def bits_per_byte(self) -> float:
        """Bits on the wire per byte: start + data + parity + stop."""
        return 1 + self.data_bits + (0 if self.parity == "N" else 1) + self.stop_bits

    @property
    def byte_time(self) -> float:
        """Seconds per byte on the wire."""
        return self.bits_per_byte / self.baud

    @property
    def bytes_per_second(self) -> float:
        return self.baud / self.bits_per_byte

    @property
    def mode(self) -> str:
        stop = "1.5" if self.stop_bits == 1.5 else str(int(self.stop_bits))
        return f"{self.data_bits}{self.parity}{stop}"


class LineModel:
    """Pacing of one direction of a serial line (see module docstring)."""

    __slots__ = ("cfg", "free_at", "_byte_time")

    def __init__(self, cfg: LineConfig) -> None:
        self.cfg = cfg
        self.free_at = 0.0
        self._byte_time = cfg.byte_time

    def admit(self, now: float, n: int) -> tuple[int, float, float]:
        """Queue ``n`` bytes at time ``now``.

        Returns ``(accepted, start, end)``: how many bytes fit in the TX queue, when the first
        accepted byte starts on the wire and when the last one's stop bit ends.
        """
        bt = self._byte_time
        start = self.free_at if self.free_at > now else now
        backlog = (start - now) / bt  # bytes queued ahead of us, not yet on the wire
        room = self.cfg.tx_queue_bytes - int(math.ceil(backlog - 1e-9))
        accepted = n if n <= room else max(room, 0)
        end = start + accepted * bt
        if accepted:
            self.free_at = end
        return accepted, start, end

    def busy_until(self) -> float:
        return self.free_at


@dataclass
class LinkStats:
    """Byte counters of one link end (directions named from the owning device)."""

    bytes_out: int = 0
    bytes_in: int = 0
    chunks_out: int = 0
    chunks_in: int = 0
    dropped_out: int = 0
    dropped_in: int = 0
    corrupted_bytes: int = 0
    faults: dict[str, int] = field(default_factory=dict)

    @property
    def dropped(self) -> int:
        return self.dropped_out + self.dropped_in

    def as_dict(self) -> dict[str, object]:
        return {
            "bytes_out": self.bytes_out,
            "bytes_in": self.bytes_in,
            "chunks_out": self.chunks_out,
            "chunks_in": self.chunks_in,
            "dropped_out": self.dropped_out,
            "dropped_in": self.dropped_in,
            "corrupted_bytes": self.corrupted_bytes,
            "faults": dict(self.faults),
        }


class LinkListener(Protocol):
    """Receives every chunk that crosses a link (recorder captures, statistics, monitor)."""

    def on_link_bytes(self, link: "Link", direction: str, t: float, data: bytes) -> None: ...


class ByteFault(Protocol):
    """A fault injector on a link direction: returns the bytes as they arrive (maybe altered)."""

    def apply(self, link: "Link", direction: str, t: float, data: bytes) -> bytes: ...


class Link:
    """Base of every transport. Subclasses implement :meth:`_write_raw` (and open/close).

    Parameters
    ----------
    name:
        Port name (``gyro``, ``uart1``, ...), used in statistics and captures.
    url:
        The URL the link was opened with.
    line:
        Serial line parameters (both directions).
    loop:
        The emulator's event loop (its ``time()`` is the scenario clock).
    """

    scheme: ClassVar[str] = ""
    #: True when bytes arriving from outside are not paced by anyone else (pty, serial, zenoh).
    paces_input: ClassVar[bool] = True

    def __init__(self, name: str, url: str, line: LineConfig, loop: asyncio.AbstractEventLoop) -> None:
        self.name = name
        self.url = url
        self.line = line
        self.loop = loop
        self.out_line = LineModel(line)
        self.in_line = LineModel(line)
        self.stats = LinkStats()
        self.listeners: list[LinkListener] = []
        self.faults_out: list[ByteFault] = []
        self.faults_in: list[ByteFault] = []
        self.on_receive: Callable[[bytes], None] | None = None
        self.closed = False

    # -- device side ----------------------------------------------------------------
    def send(self, data: bytes) -> int:
        """Transmit ``data`` from the owning device; returns the bytes accepted by the TX queue."""
        if self.closed or not data:
            return 0
        now = self.loop.time()
        accepted, _start, end = self.out_line.admit(now, len(data))
        if accepted < len(data):
            self.stats.dropped_out += len(data) - accepted
            data = data[:accepted]
        if not accepted:
            return 0
        self.loop.call_at(end, self._emit, data)
        return accepted

    def busy_until(self) -> float:
        """Scenario time at which the output line becomes idle."""
        return self.out_line.busy_until()

    # -- shared pipeline ------------------------------------------------------------
    def _emit(self, data: bytes) -> None:
        t = self.loop.time()
        for f in self.faults_out:
            data = f.apply(self, "out", t, data)
        if not data:
            return
        self.stats.bytes_out += len(data)
        self.stats.chunks_out += 1
        for lst in self.listeners:
            lst.on_link_bytes(self, "out", t, data)
        self._write_raw(data)

    def _input(self, data: bytes) -> None:
        """Called by the transport with raw bytes from outside; paces them if needed."""
        if self.closed or not data:
            return
        if not self.paces_input:
            self._deliver(data)
            return
        now = self.loop.time()
        accepted, _start, end = self.in_line.admit(now, len(data))
        if accepted < len(data):
            self.stats.dropped_in += len(data) - accepted
            data = data[:accepted]
        if accepted:
            self.loop.call_at(end, self._deliver, data)

    def _deliver(self, data: bytes) -> None:
        t = self.loop.time()
        for f in self.faults_in:
            data = f.apply(self, "in", t, data)
        if not data:
            return
        self.stats.bytes_in += len(data)
        self.stats.chunks_in += 1
        for lst in self.listeners:
            lst.on_link_bytes(self, "in", t, data)
        cb = self.on_receive
        if cb is not None:
            cb(data)

    # -- transport hooks --------------------------------------------------------------
    def _write_raw(self, data: bytes) -> None:
        raise NotImplementedError

    async def open(self) -> None:
        """Acquire the transport (create the pty, open the device...)."""

    async def close(self) -> None:
        self.closed = True

    def describe(self) -> str:
        """Human-readable endpoint (a path for ptys)."""
        return self.url
