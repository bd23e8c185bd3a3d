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
(``dropped_out``), as a real UART driver's ring buffer or an FPGA FIFO overflows. A chunk is
delivered to the far end when its last stop bit has been sent.

Three ways to transmit:

* :meth:`Link.send` -- a device writes a chunk at once (a sensor's frame, a firmware driver's
  frame). ``atomic=True`` is a driver that drops a whole frame when it does not fit
  (``dropped_chunks_out``), instead of the tail;
* :meth:`Link.forward` -- cut-through forwarding of a chunk that has just arrived on another
  link (the FPGA crossbar): byte ``i`` can leave only once it has arrived, so a fast output
  follows the input's pace and a slow output queues (and overflows) byte by byte;
* transports with a real peer (pty, serial) slice long chunks so that bytes trickle out at the
  line's pace (``slice_s`` of wire time per write) instead of arriving in one burst.

Baud mismatch: when the receiving end's settings differ from the transmitter's beyond the UART
tolerance (:func:`emulator.links.framing.uart_compatible`), the receiver gets what a 16550 would
sample from the transmitter's waveform (:class:`emulator.links.framing.UartReceiver`), with
``framing_errors`` and ``parity_errors`` counted; otherwise a fast path delivers the chunk
unchanged.
"""

from __future__ import annotations

import asyncio
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Callable, ClassVar, Protocol

if TYPE_CHECKING:
    from .framing import UartReceiver

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
    """Asynchronous serial line parameters of one link end."""

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
        if self.data_bits not in (5, 6, 7, 8):
            raise ValueError(f"data_bits must be 5..8, got {self.data_bits}")
        if self.parity not in ("N", "E", "O"):
            raise ValueError(f"parity must be N, E or O, got {self.parity!r}")
        if self.stop_bits not in (1.0, 1.5, 2.0):
            raise ValueError(f"stop_bits must be 1, 1.5 or 2, got {self.stop_bits}")

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

    def with_(self, **kw: Any) -> "LineConfig":
        """A copy with some fields changed."""
        d = {"baud": self.baud, "data_bits": self.data_bits, "parity": self.parity,
             "stop_bits": self.stop_bits, "tx_queue_bytes": self.tx_queue_bytes}
        d.update(kw)
        return LineConfig(**d)


class LineModel:
    """Pacing of one direction of a serial line (see module docstring).

    ``free_at`` is the scenario time at which the last admitted byte's stop bit ends.
    """

    __slots__ = ("cfg", "free_at", "_bt", "_q")

    def __init__(self, cfg: LineConfig) -> None:
        self.cfg = cfg
        self.free_at = 0.0
        self._bt = cfg.byte_time
        self._q = cfg.tx_queue_bytes

    def _waiting(self, now: float) -> int:
        """Bytes admitted earlier whose stop bit has not ended by ``now``."""
        fa = self.free_at
        if fa <= now:
            return 0
        return int(math.ceil((fa - now) / self._bt - 1e-9))

    def admit(self, now: float, n: int, atomic: bool = False) -> tuple[int, float, float]:
        """Queue ``n`` bytes written at once at time ``now``.

        Returns ``(accepted, start, end)``: how many bytes fit in the TX queue (all or none when
        ``atomic``), when the first accepted byte starts on the wire and when the last one's stop
        bit ends.
        """
        bt = self._bt
        fa = self.free_at
        if fa > now:
            start = fa
            room = self._q - int(math.ceil((fa - now) / bt - 1e-9))
        else:
            start = now
            room = self._q
        if n <= room:
            accepted = n
        elif atomic or room <= 0:
            accepted = 0
        else:
            accepted = room
        end = start + accepted * bt
        if accepted:
            self.free_at = end
        return accepted, start, end

    def admit_cut_through(self, now: float, n: int, in_pitch: float) -> tuple[int, float, float, float]:
        """Queue ``n`` bytes that arrived one every ``in_pitch`` s, the last one at ``now``.

        Byte ``i`` (available at ``a_i = now - (n - 1 - i) in_pitch``) can start only once it has
        arrived and the line is free. Returns ``(accepted, start, end, pitch)``: bytes kept (the
        queue holds ``tx_queue_bytes``; the excess tail is lost), the first byte's start, the
        last stop bit's end and the mean start-to-start spacing of the bytes on the wire.
        """
        bt = self._bt
        a0 = now - (n - 1) * in_pitch
        prior = self._waiting(now)
        start = self.free_at if self.free_at > a0 else a0
        if bt >= in_pitch or n == 1:
            pitch = bt
            end = start + n * bt
        else:
            end = start + n * bt
            last_ready = now + bt
            if last_ready > end:
                end = last_ready
            pitch = (end - bt - start) / (n - 1)
        # bytes of this chunk still waiting at `now` (not yet started)
        if start <= now:
            started = min(n, int((now - start) / pitch + 1e-9) + 1)
        else:
            started = 0
        waiting = prior + (n - started)
        accepted = n
        if waiting > self._q:
            accepted = max(0, n - (waiting - self._q))
            if accepted < started:
                accepted = started
            if accepted < n:
                end = start + (accepted - 1) * pitch + bt if accepted else start
        if accepted:
            self.free_at = end
        return accepted, start, end, pitch

    def busy_until(self) -> float:
        return self.free_at


@dataclass
class LinkStats:
    """Byte counters of one link end (directions named from the owning device).

    ``bytes_out`` counts what left the line model (and the listeners saw); ``dropped_out`` counts
    both what the TX queue could not hold and what the transport then could not hand over (no
    peer on a pty, a full kernel buffer). ``bytes_in`` counts what reached the device.
    """

    bytes_out: int = 0
    bytes_in: int = 0
    chunks_out: int = 0
    chunks_in: int = 0
    dropped_out: int = 0
    dropped_in: int = 0
    dropped_chunks_out: int = 0
    corrupted_bytes: int = 0
    framing_errors: int = 0
    parity_errors: int = 0
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
            "dropped_chunks_out": self.dropped_chunks_out,
            "corrupted_bytes": self.corrupted_bytes,
            "framing_errors": self.framing_errors,
            "parity_errors": self.parity_errors,
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
        Serial line parameters of this end (both directions).
    loop:
        The emulator's event loop (its ``time()`` is the scenario clock).
    """

    scheme: ClassVar[str] = ""
    #: True when bytes arriving from outside are not paced by anyone else (pty, serial, zenoh).
    paces_input: ClassVar[bool] = True
    #: Wire time per write for transports with a real peer (0 = whole chunks).
    slice_s: ClassVar[float] = 0.0

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
        #: why the transport stopped working (a device that went away), None while it works
        self.error: str | None = None
        #: spacing of the bytes of the last chunk that arrived (s), for cut-through forwarding
        self.last_rx_pitch = line.byte_time
        self._tx_start = 0.0
        self._tx_pitch = line.byte_time
        self._framer: UartReceiver | None = None
        self._framer_timer: asyncio.TimerHandle | None = None
        self._slice_bytes = max(16, int(self.slice_s / line.byte_time)) if self.slice_s > 0 else 0

    # -- configuration ------------------------------------------------------------------
    def set_remote_line(self, tx: LineConfig | None) -> None:
        """Settings of the transmitter at the far end; a mismatch beyond the UART tolerance
        switches reception to the bit-level receiver model (``None`` = assume matched)."""
        from .framing import UartReceiver, uart_compatible

        if tx is None or uart_compatible(tx, self.line):
            self._framer = None
        else:
            self._framer = UartReceiver(tx, self.line)

    # -- device side ----------------------------------------------------------------
    def send(self, data: bytes, atomic: bool = False) -> int:
        """Transmit ``data`` from the owning device; returns the bytes accepted by the TX queue."""
        if self.closed or not data:
            return 0
        n = len(data)
        accepted, start, end = self.out_line.admit(self.loop.time(), n, atomic)
        if accepted < n:
            self.stats.dropped_out += n - accepted
            if not accepted:
                self.stats.dropped_chunks_out += 1
                return 0
            data = data[:accepted]
        sb = self._slice_bytes
        bt = self.out_line._bt  # noqa: SLF001
        if sb and accepted > sb:
            for i in range(0, accepted, sb):
                piece = data[i:i + sb]
                t0 = start + i * bt
                self.loop.call_at(t0 + len(piece) * bt, self._emit, piece, t0, bt)
        else:
            self.loop.call_at(end, self._emit, data, start, bt)
        return accepted

    def send_at(self, t: float, data: bytes, atomic: bool = False) -> int:
        """:meth:`send` as if called at scenario time ``t`` (>= now), decided now.

        Only for a link's sole writer that schedules its chunks in time order (the DSP's
        firmware driver): the queue state at ``t`` is then already known, and one timer (the
        delivery) replaces two.
        """
        if self.closed or not data:
            return 0
        n = len(data)
        accepted, start, end = self.out_line.admit(t, n, atomic)
        if accepted < n:
            self.stats.dropped_out += n - accepted
            if not accepted:
                self.stats.dropped_chunks_out += 1
                return 0
            data = data[:accepted]
        self.loop.call_at(end, self._emit, data, start, self.out_line._bt)  # noqa: SLF001
        return accepted

    def forward(self, data: bytes, src: "Link") -> int:
        """Cut-through transmit of a chunk that has just arrived on ``src`` (see module docstring)."""
        if self.closed or not data:
            return 0
        n = len(data)
        accepted, start, end, pitch = self.out_line.admit_cut_through(self.loop.time(), n, src.last_rx_pitch)
        if accepted < n:
            self.stats.dropped_out += n - accepted
            if not accepted:
                return 0
            data = data[:accepted]
        self.loop.call_at(end, self._emit, data, start, pitch)
        return accepted

    def busy_until(self) -> float:
        """Scenario time at which the output line becomes idle."""
        return self.out_line.free_at

    # -- shared pipeline ------------------------------------------------------------
    def _emit(self, data: bytes, start: float, pitch: float) -> None:
        if self.closed:
            self.stats.dropped_out += len(data)
            return
        if self.faults_out:
            t = self.loop.time()
            for f in self.faults_out:
                data = f.apply(self, "out", t, data)
            if not data:
                return
        st = self.stats
        st.bytes_out += len(data)
        st.chunks_out += 1
        if self.listeners:
            t = self.loop.time()
            for lst in self.listeners:
                lst.on_link_bytes(self, "out", t, data)
        self._tx_start = start
        self._tx_pitch = pitch
        self._write_raw(data)

    def _input(self, data: bytes) -> None:
        """Called by the transport with raw bytes from outside; paces them if needed."""
        if self.closed or not data:
            return
        n = len(data)
        if not self.paces_input:
            bt = self.in_line._bt  # noqa: SLF001
            self._arrive(data, self.loop.time() - n * bt, bt, self.in_line)
            return
        accepted, start, end = self.in_line.admit(self.loop.time(), n)
        if accepted < n:
            self.stats.dropped_in += n - accepted
            data = data[:accepted]
        if accepted:
            self.loop.call_at(end, self._arrive, data, start, self.in_line._bt, self.in_line)  # noqa: SLF001

    def _arrive(self, data: bytes, start: float, pitch: float, tx_model: LineModel) -> None:
        """A chunk whose last stop bit ends now; ``tx_model`` paced it (start, byte spacing)."""
        if self.closed:
            return
        self.last_rx_pitch = pitch
        if self._framer is None:
            self._deliver(data)
            return
        fr = self._framer
        fr.feed(start, data, pitch)
        self._framed(fr, tx_model, self.loop.time())

    def _framed(self, fr: "UartReceiver", tx_model: LineModel, final_until: float) -> None:
        got = fr.decode(final_until)
        self.stats.framing_errors = fr.framing_errors
        self.stats.parity_errors = fr.parity_errors
        if got:
            self._deliver(bytes(b for _t, b in got))
        pend = fr.pending_until()
        if self._framer_timer is not None:
            self._framer_timer.cancel()
            self._framer_timer = None
        if pend is not None and pend > final_until:
            self._framer_timer = self.loop.call_at(pend, self._framer_idle, tx_model, fr.waveform_end)

    def _framer_idle(self, tx_model: LineModel, known_end: float) -> None:
        """A pending byte's samples are due: final if nothing was transmitted since."""
        self._framer_timer = None
        fr = self._framer
        if fr is None or self.closed:
            return
        if tx_model.free_at <= known_end + 1e-12:
            self._framed(fr, tx_model, self.loop.time())

    def _deliver(self, data: bytes) -> None:
        if self.faults_in:
            t = self.loop.time()
            for f in self.faults_in:
                data = f.apply(self, "in", t, data)
            if not data:
                return
        st = self.stats
        st.bytes_in += len(data)
        st.chunks_in += 1
        if self.listeners:
            t = self.loop.time()
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
        if self._framer_timer is not None:
            self._framer_timer.cancel()
            self._framer_timer = None

    def describe(self) -> str:
        """Human-readable endpoint (a path for ptys)."""
        return self.url
