"""The one link abstraction: line model, fault hooks and statistics, applied once.

A :class:`Link` is one device port's connection to something else: another device port
(``mem://``), a pseudo-terminal for real tools (``pty://``), a real serial device
(``serial://``), zenoh or CAN. The public methods do the shared work (template method, as
python-can's ``BusABC.recv`` / ``_recv_internal``); each transport implements only
:meth:`Link._write_raw` and feeds what it reads from outside into :meth:`Link._input`.

Directions are named from the owning device: ``out`` (device transmits) and ``in`` (device
receives).

The line model (:class:`~emulator.links.line.LineModel`, :mod:`emulator.links.line`) paces every
direction; what does not fit its TX queue is lost and counted (``dropped_out``).

Three ways to transmit:

* :meth:`Link.send` -- a device writes a chunk at once (a sensor's frame, a firmware driver's
  frame). ``atomic=True`` is a driver that drops a whole frame when it does not fit
  (``dropped_chunks_out``), instead of the tail;
* :meth:`Link.forward` -- cut-through forwarding of a chunk that has just arrived on another
  link (the FPGA crossbar): byte ``i`` can leave only once it has arrived, so a fast output
  follows the input's pace and a slow output queues (and overflows) byte by byte;
* transports with a real peer (pty, serial) slice long chunks so that bytes trickle out at the
  line's pace (``slice_s`` of wire time per write) instead of arriving in one burst.

Transports with a real peer write through :meth:`Link._hand_over`: at once, or, when the realtime
loop runs ahead of the wall clock (:meth:`emulator.clock.EmulatorLoop.set_lead`), from the loop's
:class:`~emulator.paced_writer.PacedWriter` at the wall instant of the bytes' scenario time. Fault hooks,
listeners (captures) and statistics stay in the loop, at the bytes' scenario time, either way.

Baud mismatch: when the receiving end's settings differ from the transmitter's beyond the UART
tolerance (:func:`emulator.links.framing.uart_compatible`), the receiver gets what a 16550 would
sample from the transmitter's waveform (:class:`emulator.links.framing.UartReceiver`), with
``framing_errors`` and ``parity_errors`` counted; otherwise a fast path delivers the chunk
unchanged.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import ClassVar, Protocol

from .framing import UartReceiver, uart_compatible
from .line import LineConfig, LineModel, parse_mode

__all__ = [
    "ByteFault",
    "LineConfig",
    "LineModel",
    "Link",
    "LinkListener",
    "LinkStats",
    "parse_mode",
]


@dataclass
class LinkStats:
    """Byte counters of one link end (directions named from the owning device).

    ``bytes_out`` counts what left the line model (and the listeners saw); ``dropped_out`` counts
    both what the TX queue could not hold and what the transport then could not hand over (no
    peer on a pty, a full kernel buffer). ``bytes_in`` counts what reached the device.
    ``no_peer_out`` counts what a pty sent while no peer was attached: not lost on a line, just unheard, so it is
    kept apart from ``dropped_out`` (a ``dropped: max 0`` expectation holds whether or not a tool listens).
    """

    bytes_out: int = 0
    bytes_in: int = 0
    chunks_out: int = 0
    chunks_in: int = 0
    dropped_out: int = 0
    dropped_in: int = 0
    dropped_chunks_out: int = 0
    no_peer_out: int = 0
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
            "no_peer_out": self.no_peer_out,
            "corrupted_bytes": self.corrupted_bytes,
            "framing_errors": self.framing_errors,
            "parity_errors": self.parity_errors,
            "faults": dict(self.faults),
        }


class LinkListener(Protocol):
    """Receives every chunk that crosses a link (recorder captures, statistics, monitor)."""

    def on_link_bytes(self, link: Link, direction: str, t: float, data: bytes) -> None: ...


class ByteFault(Protocol):
    """A fault injector on a link direction: returns the bytes as they arrive (maybe altered)."""

    def apply(self, link: Link, direction: str, t: float, data: bytes) -> bytes: ...


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
    #: The URL syntax this transport accepts, shown in every error about its URL (the one place it is written).
    url_usage: ClassVar[str] = ""
    #: Query options it accepts beyond the common ``baud``, ``mode``, ``queue``.
    url_options: ClassVar[frozenset[str]] = frozenset()
    #: True when bytes arriving from outside are not paced by anyone else (pty, serial, zenoh).
    paces_input: ClassVar[bool] = True
    #: Wire time per write for transports with a real peer (0 = whole chunks).
    slice_s: ClassVar[float] = 0.0
    #: True when the transport writes through :meth:`_hand_over` (:meth:`_write_out` safe to call from the
    #: paced writer's thread), so the realtime loop may run ahead of the wall clock with it open.
    deferred_write: ClassVar[bool] = False

    @classmethod
    def check_target(cls, url: str, target: str) -> None:
        """Raise :class:`~emulator.errors.LinkConfigError` (with :attr:`url_usage`) when ``target``, the part of the
        URL after ``SCHEME://``, is not one this transport can open. Called when a URL is parsed (a scenario is
        validated), so a bad target is refused before anything runs; the default accepts any non-empty target."""

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
        #: counts the peers that went away (a pty's detach): bytes handed to the paced writer for an earlier
        #: peer are not written (:meth:`_hand_over`)
        self.peer_epoch = 0
        #: spacing of the bytes of the last chunk that arrived (s), for cut-through forwarding
        self.last_rx_pitch = line.byte_time
        self._tx_start = 0.0
        self._tx_pitch = line.byte_time
        self._framer: UartReceiver | None = None
        self._framer_timer: asyncio.TimerHandle | None = None
        self._slice_bytes = max(16, int(self.slice_s / line.byte_time)) if self.slice_s > 0 else 0

    # -- configuration ------------------------------------------------------------------
    def set_remote_line(self, tx: LineConfig | None, rx: LineConfig | None = None) -> None:
        """Settings of the transmitter at the far end; a mismatch beyond the UART tolerance
        switches reception to the bit-level receiver model (``None`` = assume matched).

        ``rx`` makes this end's receiver sample with other settings than its own line (a receiver
        at the wrong baud, an injected fault); default: this end's line. The framing and parity
        error counts carry over when the receiver model is replaced.
        """
        rx = rx or self.line
        if tx is None or uart_compatible(tx, rx):
            self._framer = None
        else:
            fr = UartReceiver(tx, rx)
            fr.framing_errors = self.stats.framing_errors
            fr.parity_errors = self.stats.parity_errors
            self._framer = fr

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
        bt = self.out_line._bt
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
        self.loop.call_at(end, self._emit, data, start, self.out_line._bt)
        return accepted

    def forward(self, data: bytes, src: Link) -> int:
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

    def relay(self, data: bytes, start: float, pitch: float) -> None:
        """Transmit, now, a chunk that another link's line model has already paced (its first start bit at
        ``start``, bytes ``pitch`` s apart): a sensor stream bound out to a real port (emulator.assembly.ports,
        ``direction: out | tee``). Counted, seen by the listeners and the output fault hooks, not paced again."""
        if self.closed or not data:
            return
        self._emit(data, start, pitch)

    def busy_until(self) -> float:
        """Scenario time at which the output line becomes idle."""
        return self.out_line.free_at

    # -- shared pipeline ------------------------------------------------------------
    def _emit(self, data: bytes, start: float, pitch: float) -> None:
        if self.closed:
            self.stats.dropped_out += len(data)
            return
        if self.faults_out or self.listeners:
            data = self._through("out", self.faults_out, data)
            if not data:
                return
        else:
            self.stats.bytes_out += len(data)
            self.stats.chunks_out += 1
        self._tx_start = start
        self._tx_pitch = pitch
        self._write_raw(data)

    def _input(self, data: bytes) -> None:
        """Called by the transport with raw bytes from outside; paces them if needed."""
        if self.closed or not data:
            return
        n = len(data)
        if not self.paces_input:
            bt = self.in_line._bt
            self._arrive(data, self.loop.time() - n * bt, bt, self.in_line)
            return
        accepted, start, end = self.in_line.admit(self.loop.time(), n)
        if accepted < n:
            self.stats.dropped_in += n - accepted
            data = data[:accepted]
        if accepted:
            self.loop.call_at(end, self._arrive, data, start, self.in_line._bt, self.in_line)

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

    def _framed(self, fr: UartReceiver, tx_model: LineModel, final_until: float) -> None:
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

    def _through(self, direction: str, faults: list[ByteFault], data: bytes) -> bytes:
        """``data`` through the faults of ``direction`` ("out" or "in"), counted, shown to the listeners.

        Returns what is left (empty when a fault swallowed it all: then nothing is counted or shown).
        """
        if faults:
            t = self.loop.time()
            for f in faults:
                data = f.apply(self, direction, t, data)
            if not data:
                return data
        st = self.stats
        if direction == "out":
            st.bytes_out += len(data)
            st.chunks_out += 1
        else:
            st.bytes_in += len(data)
            st.chunks_in += 1
        if self.listeners:
            t = self.loop.time()
            for lst in self.listeners:
                lst.on_link_bytes(self, direction, t, data)
        return data

    def _deliver(self, data: bytes) -> None:
        if self.faults_in or self.listeners:
            data = self._through("in", self.faults_in, data)
            if not data:
                return
        else:
            self.stats.bytes_in += len(data)
            self.stats.chunks_in += 1
        cb = self.on_receive
        if cb is not None:
            cb(data)

    def deliver_held(self, direction: str, data: bytes) -> None:
        """Pass on bytes that a fault held back (a stalled line), now, without the fault hooks:
        ``"in"`` delivers them to the device as if they had just arrived, ``"out"`` transmits them
        (counted, seen by the listeners) as if the line had just carried them."""
        if self.closed or not data:
            return
        if direction == "in":
            hooks, self.faults_in = self.faults_in, []
            try:
                self._deliver(data)
            finally:
                self.faults_in = hooks
        else:
            hooks, self.faults_out = self.faults_out, []
            try:
                self._emit(data, self.loop.time(), self.out_line._bt)
            finally:
                self.faults_out = hooks

    # -- transport hooks --------------------------------------------------------------
    def _write_raw(self, data: bytes) -> None:
        raise NotImplementedError

    def _hand_over(self, data: bytes) -> None:
        """Write ``data`` (just emitted, at scenario time ``loop.time()``) to the real peer: at once, or, when the
        loop runs ahead (its ``writer`` set), from the writer's thread at the wall instant of that scenario time.
        Failures come back to :meth:`_after_write` in the loop's thread either way. Bytes handed over for a peer
        that has gone by the time they are due (:attr:`peer_epoch` moved on) are not written, only counted as
        unheard (``no_peer_out``): written, they would reach the next peer after a gap."""
        w = getattr(self.loop, "writer", None)
        if w is None:
            self._after_write(len(data), *self._write_out(data))
            return
        w.put_bytes(self.loop.wall_at(self.loop.time()), self, data)  # type: ignore[attr-defined]

    def _write_deferred(self, item: tuple[int, bytes]) -> None:
        """The writer thread's call: write, and pass a failure or a short write back to the loop's thread."""
        epoch, data = item
        if epoch != self.peer_epoch:
            self._report_deferred(epoch, len(data), 0, None)
            return
        n, err = self._write_out(data)
        if n < len(data) or err is not None:
            self._report_deferred(epoch, len(data), n, err)

    def _report_deferred(self, epoch: int, size: int, written: int, err: int | None) -> None:
        """Any thread (the paced writer's, its process backend's reports): the outcome of a deferred write of
        ``size`` bytes for the peer of ``epoch``, passed to :meth:`_after_deferred_write` in the loop's thread."""
        with contextlib.suppress(RuntimeError):  # RuntimeError: the loop is closed, nobody left to count it
            self.loop.call_soon_threadsafe(self._after_deferred_write, epoch, size, written, err)

    def peer_fd(self) -> int | None:
        """The file descriptor the transport writes its peer through (a pty master, a serial device), for the
        paced writer's process backend; None: none (written by :meth:`_write_out` in the writer's thread)."""
        return None

    def _peer_gone(self) -> None:
        """The peer went away: bytes handed over for it and not yet written are not written (:attr:`peer_epoch`)."""
        self.peer_epoch += 1
        w = getattr(self.loop, "writer", None)
        if w is not None:
            w.peer_gone(self)

    def _after_deferred_write(self, epoch: int, size: int, written: int, err: int | None) -> None:
        if epoch != self.peer_epoch:  # for a peer that has gone: unheard, whatever the write said
            self.stats.no_peer_out += size - written
            return
        self._after_write(size, written, err)

    def _write_out(self, data: bytes) -> tuple[int, int | None]:
        """Write to the peer (any thread, no shared state touched): (bytes written, errno or None)."""
        raise NotImplementedError

    def _after_write(self, size: int, written: int, err: int | None) -> None:
        """The outcome of a write of ``size`` bytes (the loop's thread): count a loss, react to an error."""

    def _drain_writes(self) -> None:
        """Before closing the transport: let the paced writer write what it holds for this link."""
        w = getattr(self.loop, "writer", None)
        if w is not None:
            w.drain(self)

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
