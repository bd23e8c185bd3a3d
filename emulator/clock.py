"""The emulator's event loop and its two time modes.

One asyncio event loop drives everything (docs/architecture.md, section "Time"). Its ``time()`` is the
scenario clock in seconds since scenario start.

``fast``
    Virtual time. When every task waits and no I/O is ready, the clock jumps straight to the
    next timer, so a run is as fast as the CPU allows. With ``mem://`` links and a seed it is
    bit-for-bit deterministic. Real file descriptors (ptys, sockets) are still polled without
    blocking on every iteration; with none registered, the loop's own self-pipe (signals,
    ``call_soon_threadsafe``) is polled every 64 iterations. Real peers move in wall time while
    virtual time races ahead, so runs with ``pty``/``serial`` endpoints use ``realtime``.
``realtime``
    The clock follows the wall clock, scaled by ``speed`` (2.0 runs twice as fast as real
    time). Select timeouts are divided by ``speed``. Each loop iteration runs at one instant, read
    once when the selector returns: when timers are due, only the earliest due instant runs, and
    ``time()`` reads that instant while its callbacks run (logical time); otherwise ``time()``
    reads the moment the selector returned, for the whole iteration. So late events keep their
    order and spacing and the loop catches up (asyncio alone would run every overdue timer in one
    batch, and a sensor datagram scheduled during the batch would land after the FPGA's timeout
    for it), and a timer's callback always sees its own instant, however long the callbacks
    before it took (D-7.7, D-10.E12).

    **Compute ahead** (:meth:`EmulatorLoop.set_lead`, docs/decisions/performance.md D-10.E6): the
    clock may run ``lead_s`` (wall seconds) ahead of the outside world. Everything inside the loop
    happens that much early; what leaves for a real peer is handed to a :class:`PacedWriter`, which
    performs each write at the wall instant its scenario time stands for (:meth:`EmulatorLoop.wall_at`):
    from a writer process (:mod:`emulator.pacing`, D-10.E11) for ptys and serial devices on Linux, else
    from a thread. A callback that holds the loop for a few ms then no longer
    delays the bytes; what the outside sends is stamped on arrival with the loop's (early) clock,
    so it takes effect up to ``lead_s`` later than without the lead.

Fast path. In fast mode with no file descriptor of its own, the loop runs batches of iterations
(:meth:`EmulatorLoop._run_fast`) instead of asyncio's ``BaseEventLoop._run_once``, and ``call_at``
builds lighter timer handles: both re-implement asyncio steps on CPython's private fields
(``_scheduled``, ``_ready``, the timer handles' slots). They are used only on the CPython versions in
:data:`FAST_PATH_VERSIONS`, where those fields were checked, and only when the fields are really there
(:func:`fast_path_supported`); elsewhere the loop runs asyncio's own iteration and ``call_at``, with the
same results, more slowly. (The virtual clock itself needs only the timer heap, ``_scheduled``, and its
handles' ``_when``, which every asyncio since 3.4 has.)

Devices use only ``loop.time()`` and ``loop.call_at()`` / ``asyncio.sleep``, so the same code
runs in both modes. :func:`sleep_until` waits for an absolute scenario time without the drift
that repeated relative sleeps accumulate.
"""

from __future__ import annotations

import asyncio
import contextlib
import heapq
import os
import selectors
import sys
import threading
import time as _time
from asyncio import events as _events
from asyncio.format_helpers import _format_callback_source
from collections import deque
from collections.abc import Callable, Hashable
from contextvars import copy_context as _copy_context
from typing import TYPE_CHECKING, Any

from .errors import LinkConfigError, WriterProcessError
from .pacing import TIMER_SLACK_NS, PacedPeer, WriterProcess, ask_rt_priority, set_timer_slack

__all__ = ["FAST_PATH_VERSIONS", "TIMER_SLACK_NS", "WRITER_BACKENDS", "EmulatorLoop", "PacedWriter",
           "default_writer_backend", "fast_path_supported", "new_loop", "set_timer_slack", "sleep_until"]

#: CPython versions whose asyncio internals the fast path was checked against (the steps of
#: ``BaseEventLoop._run_once``, the fields of ``TimerHandle``); 3.11 is the version the project is tested on.
FAST_PATH_VERSIONS: frozenset[tuple[int, int]] = frozenset({(3, 11)})
#: private loop fields the fast path reads and writes
_LOOP_FIELDS = ("_scheduled", "_ready", "_stopping", "_timer_cancelled_count", "_clock_resolution", "_debug", "_closed")
#: private timer-handle fields :class:`_Timer` sets and the fast path reads
_HANDLE_FIELDS = ("_context", "_loop", "_callback", "_args", "_cancelled", "_repr", "_source_traceback", "_when",
                  "_scheduled")


def fast_path_supported(loop: asyncio.AbstractEventLoop) -> bool:
    """True when ``loop`` may take the fast path: a CPython version of :data:`FAST_PATH_VERSIONS` whose
    event loop and timer handles have the private fields the fast path uses."""
    if sys.implementation.name != "cpython" or sys.version_info[:2] not in FAST_PATH_VERSIONS:
        return False
    slots: set[str] = set()
    for cls in _events.TimerHandle.__mro__:
        s = cls.__dict__.get("__slots__", ())
        slots.update((s,) if isinstance(s, str) else s)
    return (callable(getattr(asyncio.BaseEventLoop, "_run_once", None))
            and all(f in slots for f in _HANDLE_FIELDS)
            and all(hasattr(loop, f) for f in _LOOP_FIELDS))


#: the paced writer's backends: ``process`` (a writer process, :mod:`emulator.pacing`) for links whose peer is a file
#: descriptor on Linux, the ``thread`` for the rest; ``thread`` only: the thread for every link
WRITER_BACKENDS = ("process", "thread")
#: the environment variable that chooses the backend (``process`` | ``thread``; unset: :func:`default_writer_backend`)
WRITER_ENV = "PSNS_PACED_WRITER"


def default_writer_backend() -> str:
    """The backend a :class:`PacedWriter` takes when none is given: :data:`WRITER_ENV` if set, else ``process`` on
    Linux and ``thread`` elsewhere (docs/decisions/performance.md D-10.E11)."""
    env = os.environ.get(WRITER_ENV, "").strip().lower()
    if env:
        if env not in WRITER_BACKENDS:
            raise LinkConfigError(f"{WRITER_ENV}={env!r}: expected one of {', '.join(WRITER_BACKENDS)}")
        return env
    return "process" if sys.platform.startswith("linux") else "thread"


class PacedWriter:
    """Performs writes at given ``CLOCK_MONOTONIC`` instants, in the order they were put.

    The realtime loop running ahead (:meth:`EmulatorLoop.set_lead`) puts each chunk for a real peer here
    (:meth:`put_bytes`) with the wall instant its scenario time stands for. Two backends behind one API
    (docs/decisions/performance.md D-10.E11):

    ``process``
        A writer process (:class:`emulator.pacing.WriterProcess`) writes the chunks of links whose peer is a
        file descriptor (``Link.peer_fd``: a pty master, a serial device): its own interpreter, so a loop busy in
        Python cannot hold its writes up. Started with the writer; when it dies, :attr:`error` holds the
        :class:`~emulator.errors.WriterProcessError`, what it held is counted as lost, and the thread takes over.
    ``thread``
        A thread that sleeps until each instant (timer slack :data:`TIMER_SLACK_NS`) and calls the transport's
        write (:meth:`put`: any callable). While it waits for a deadline it holds no lock and not the GIL; to get
        the GIL back promptly from a loop busy in Python code, the interpreter's switch interval is lowered to
        :attr:`SWITCH_INTERVAL_S` while the thread runs (restored by :meth:`close`). Always there: for callables,
        links without a descriptor, other OSes, and after the process died.

    Items are written in the order put; the loop puts them in scenario-time order, so that is deadline order.
    ``owner`` groups items (a link): :meth:`drain` waits until an owner's items are written, before the
    owner closes its file descriptor. :attr:`on_late` (class or instance attribute) gets each write's lateness
    against its instant, from either backend (the benchmark's emulator-side lateness).
    """

    #: the interpreter's switch interval while the writer's thread runs (s; CPython's default is 5 ms)
    SWITCH_INTERVAL_S = 2e-4
    #: the real-time priority (``SCHED_FIFO``) the thread and the process ask for, so that a CPU busy with other work
    #: does not delay their wake-ups: this, or one above the loop's thread when that runs with a real-time priority
    #: itself (``chrt``: the writer must still preempt it). Where that is not allowed (no root, no ``RLIMIT_RTPRIO``,
    #: another OS) they keep the normal policy. None: do not ask. Both sleep between writes: no starving the machine.
    RT_PRIORITY: int | None = 1
    #: ``on_late(owner, late_s)``: each write's lateness against its instant (s), called in the writer's thread or
    #: the process backend's report thread; None: not measured
    on_late: Callable[[Hashable, float], None] | None = None

    def __init__(self, backend: str | None = None) -> None:
        self._items: deque[tuple[float, Callable[[Any], object], Any, Hashable]] = deque()
        self._cv = threading.Condition()
        self._pending: dict[Hashable, int] = {}
        self._thread: threading.Thread | None = None
        self._stop = False
        self._switch0: float | None = None
        self._loop_priority = _own_priority()
        self.backend = backend or default_writer_backend()
        if self.backend not in WRITER_BACKENDS:
            raise ValueError(f"backend must be one of {', '.join(WRITER_BACKENDS)}, got {backend!r}")
        #: the scheduling policy the thread runs with (``SCHED_FIFO 1``, or ``SCHED_OTHER`` and why), once started
        self.policy: str | None = None
        #: writes that raised (the transport's write is expected to catch its own errors), and the last one
        self.failures = 0
        self.last_error: str | None = None
        self.writes = 0
        #: why the process backend stopped (it died, or could not start), None while it works or was not asked for
        self.error: WriterProcessError | None = None
        self._proc: WriterProcess | None = None
        if self.backend == "process":
            try:
                self._proc = WriterProcess(self.RT_PRIORITY, self._loop_priority, on_late=self._late,
                                           on_death=self._proc_died)
            except WriterProcessError as exc:
                self._proc_died(exc)

    @property
    def process(self) -> WriterProcess | None:
        """The writer process while it works (None: the thread writes everything)."""
        p = self._proc
        return p if p is not None and p.alive else None

    def put(self, at: float, write: Callable[[Any], object], data: Any, owner: Hashable) -> None:
        """Call ``write(data)`` in the writer's thread at ``CLOCK_MONOTONIC`` instant ``at`` (s), at once if past."""
        with self._cv:
            if self._thread is None:
                self._start()
            self._items.append((at, write, data, owner))
            self._pending[owner] = self._pending.get(owner, 0) + 1
            self._cv.notify_all()

    def put_bytes(self, at: float, peer: PacedPeer, data: bytes) -> None:
        """Write ``data`` to ``peer`` (a link) at ``CLOCK_MONOTONIC`` instant ``at`` (s), unless its peer has gone
        by then (``peer_epoch``); the outcome of a failed or short write reaches ``peer._after_deferred_write`` in the
        loop's thread. The process writes it when it works and the link has a descriptor, else the thread."""
        p = self.process
        if p is not None:
            fd = peer.peer_fd()
            if fd is not None:
                try:
                    p.put(at, peer, data, fd)
                    return
                except WriterProcessError:
                    pass  # died (on_death has run): the thread takes this one
        self.put(at, peer._write_deferred, (peer.peer_epoch, data), peer)

    def peer_gone(self, peer: PacedPeer) -> None:
        """``peer``'s peer went away (its ``peer_epoch`` has just moved on): what is queued for it is not written
        (the thread checks the epoch at each write; the process is told, in order with the data)."""
        p = self.process
        if p is not None:
            with contextlib.suppress(WriterProcessError):
                p.flush(peer)

    def drain(self, owner: Hashable, timeout: float = 5.0) -> bool:
        """Wait until every item of ``owner`` put so far is written (and the process let go of its descriptor);
        False on timeout (wall s)."""
        t_end = _time.monotonic() + timeout
        p = self._proc
        ok = p.drain(owner, timeout) if p is not None else True
        with self._cv:
            return self._cv.wait_for(lambda: not self._pending.get(owner) or self._thread is None,
                                     max(0.0, t_end - _time.monotonic())) and ok

    def pending(self, owner: Hashable | None = None) -> int:
        """Items not written yet (of ``owner``, or all)."""
        p = self._proc
        n = p.pending(owner) if p is not None else 0
        with self._cv:
            return n + (len(self._items) if owner is None else self._pending.get(owner, 0))

    def close(self, timeout: float = 5.0) -> None:
        """Write what is queued (each at its instant), stop the process and the thread, restore the switch
        interval."""
        p, self._proc = self._proc, None
        if p is not None:
            p.close(timeout)
            self.writes += p.writes
            self.failures += p.failures
        with self._cv:
            th = self._thread
            self._stop = True
            self._cv.notify_all()
        if th is not None:
            th.join(timeout)
        with self._cv:
            self._thread = None
            self._cv.notify_all()
        if self._switch0 is not None:
            sys.setswitchinterval(self._switch0)
            self._switch0 = None

    def _late(self, owner: Hashable, late_s: float) -> None:
        hook = self.on_late
        if hook is not None:
            hook(owner, late_s)

    def _proc_died(self, exc: WriterProcessError) -> None:
        if self.error is exc:
            return
        self.error = exc
        self.failures += 1
        self.last_error = str(exc)

    def _start(self) -> None:
        self._stop = False
        self._switch0 = sys.getswitchinterval()
        sys.setswitchinterval(min(self._switch0, self.SWITCH_INTERVAL_S))
        self._thread = threading.Thread(target=self._run, name="psns-paced-writer", daemon=True)
        self._thread.start()

    def _run(self) -> None:
        set_timer_slack()
        self.policy = ask_rt_priority(self.RT_PRIORITY, self._loop_priority)[1]
        items, cv, mono, sleep = self._items, self._cv, _time.monotonic, _time.sleep
        while True:
            with cv:
                while not items and not self._stop:
                    cv.wait()
                if not items:
                    return
                at, write, data, owner = items[0]
            delay = at - mono()
            if delay > 0:
                sleep(delay)  # later items are due later: nothing to wake up for
            self._write(at, write, data)
            hook = self.on_late
            if hook is not None:
                hook(owner, mono() - at)
            with cv:
                items.popleft()
                left = self._pending[owner] - 1
                if left:
                    self._pending[owner] = left
                else:
                    del self._pending[owner]
                    cv.notify_all()

    def _write(self, at: float, write: Callable[[Any], object], data: Any) -> None:
        """One write, due at ``at``."""
        try:
            write(data)
        except Exception as exc:  # the transport catches its own errors; keep the thread alive regardless
            self.failures += 1
            self.last_error = repr(exc)
        self.writes += 1


def _own_priority() -> int:
    """The calling thread's (the loop's) real-time priority, 0 when it has none."""
    try:
        return int(os.sched_getparam(0).sched_priority)
    except (AttributeError, OSError):
        return 0


class _ClockSelector(selectors.BaseSelector):
    """Selector wrapper that implements virtual or scaled time for :class:`EmulatorLoop`."""

    #: In fast mode with no file descriptor but the loop's own self-pipe registered, poll that
    #: pipe (signals, call_soon_threadsafe) only every this many iterations: nothing else can
    #: become ready, and the syscall is a large share of an iteration's cost.
    SELF_PIPE_POLL_EVERY = 64
    #: realtime: waits shorter than this are slept precisely (epoll has 1 ms resolution)
    FINE_S = 0.0015

    def __init__(self, loop: EmulatorLoop) -> None:
        self._real = selectors.DefaultSelector()
        self._loop = loop
        self._nfds = 0
        self._skipped = 0

    # delegation ------------------------------------------------------------------
    def register(self, fileobj: Any, events: int, data: Any = None) -> selectors.SelectorKey:
        key = self._real.register(fileobj, events, data)
        self._nfds += 1
        return key

    def unregister(self, fileobj: Any) -> selectors.SelectorKey:
        key = self._real.unregister(fileobj)
        self._nfds -= 1
        return key

    def modify(self, fileobj: Any, events: int, data: Any = None) -> selectors.SelectorKey:
        return self._real.modify(fileobj, events, data)

    def get_key(self, fileobj: Any) -> selectors.SelectorKey:
        return self._real.get_key(fileobj)

    def get_map(self) -> Any:
        return self._real.get_map()

    def close(self) -> None:
        self._real.close()

    # the clock -------------------------------------------------------------------
    def select(self, timeout: float | None = None) -> list[tuple[selectors.SelectorKey, int]]:
        loop = self._loop
        if loop.mode == "fast":
            sched = loop._scheduled
            if self._nfds > 1 or self._skipped >= self.SELF_PIPE_POLL_EVERY or not sched:
                self._skipped = 0
                events = self._real.select(0)
                if events:
                    return events
            else:
                self._skipped += 1
                events = []
            if timeout == 0:
                return events
            if sched:
                when = sched[0]._when
                if when > loop._now:
                    loop._now = when
                return events
            # Nothing scheduled and nothing ready: only I/O or another thread can wake us.
            return self._real.select(timeout)
        if timeout is not None and timeout > 0:
            timeout = timeout / loop.speed
            if timeout > self.FINE_S:
                # epoll rounds its timeout up to whole milliseconds: wake a bit early and let
                # the next iteration sleep the rest precisely
                events = self._real.select(timeout - self.FINE_S)
            else:
                events = self._real.select(0)
                if not events:
                    _time.sleep(timeout)  # sub-millisecond precision; no I/O for < FINE_S
                    events = self._real.select(0)
        else:
            events = self._real.select(timeout)
        # One reading of the clock decides the iteration's instant (D-7.7, D-10.E12): the earliest timer's own when it
        # is due, else this moment; time() reads it until the iteration ends, so asyncio's test of which timers are
        # due (time() + resolution) agrees with this one, and every timer's callback sees exactly its own instant.
        # (Read twice, a timer falling due between the two readings ran at the second one, behind the callbacks
        # already ready -- a DSP tick of 0.3-0.7 ms -- and what it sent took that late instant as its own.)
        now = loop.time()
        sched = loop._scheduled
        loop._cap = sched[0]._when if sched and sched[0]._when <= now else now
        return events


class _Timer(_events.TimerHandle):
    """A :class:`asyncio.TimerHandle` built and compared with less work (fast-mode hot path).

    The same fields and behaviour (``cancel``, ``when``, ``_run`` are inherited); the constructor sets the
    fields directly (no debug-mode source traceback: the loop uses it only when debug is off) and ``<``
    compares the deadlines without the type check (the timer heap holds only timer handles).
    """

    __slots__ = ()
    if TYPE_CHECKING:
        _when: float

    def __init__(self, when: float, callback: Any, args: Any, loop: Any, context: Any = None) -> None:
        self._context = _copy_context() if context is None else context
        self._loop = loop
        self._callback = callback
        self._args = args
        self._cancelled = False
        self._repr = None
        self._source_traceback = None
        self._when = when
        self._scheduled = False

    def __lt__(self, other: _Timer) -> bool:  # type: ignore[override]  # the heap holds timer handles only
        return self._when < other._when

    def cancel(self) -> None:
        """:meth:`asyncio.TimerHandle.cancel` in one frame when the loop is not in debug mode (the fast path's
        handles: made only then): the loop's count of cancelled scheduled timers (``_timer_handle_cancelled``),
        the flag, the callback and its arguments released; in debug mode asyncio's own (it keeps a repr)."""
        if self._cancelled:
            return
        loop = self._loop
        if loop._debug:
            super().cancel()
            return
        if self._scheduled:
            loop._timer_cancelled_count += 1
        self._cancelled = True
        self._callback = None
        self._args = None  # type: ignore[assignment]  # as asyncio.Handle.cancel does


class EmulatorLoop(asyncio.SelectorEventLoop):
    """Selector event loop whose clock is the scenario clock (s since scenario start).

    Parameters
    ----------
    mode:
        ``"fast"`` (virtual time) or ``"realtime"`` (wall clock times ``speed``).
    speed:
        Real-time scale factor; only used in realtime mode.
    """

    if TYPE_CHECKING:  # asyncio's private fields the clock and the fast path use (see the module docstring)
        _scheduled: list[Any]  # asyncio.TimerHandle, read through its private _when / _scheduled
        _ready: deque[Any]
        _stopping: bool
        _timer_cancelled_count: int
        _clock_resolution: float
        _debug: bool
        _closed: bool
        _selector: _ClockSelector

    def __init__(self, mode: str = "fast", speed: float = 1.0) -> None:
        if mode not in ("fast", "realtime"):
            raise ValueError(f"mode must be 'fast' or 'realtime', got {mode!r}")
        if speed <= 0:
            raise ValueError(f"speed must be > 0, got {speed}")
        self.mode = mode
        self.speed = float(speed)
        self._now = 0.0
        self._wall0 = _time.monotonic()
        self._cap: float | None = None  # realtime: the instant this iteration runs (set when the selector returns)
        #: realtime: how far (wall s) the clock runs ahead of the outside world (:meth:`set_lead`)
        self.lead_s = 0.0
        #: realtime with a lead: the thread that writes to real peers at their instants, else None
        self.writer: PacedWriter | None = None
        #: realtime: the timer slack in force for the loop's thread (ns; None where it cannot be set)
        self.timer_slack_ns = set_timer_slack() if mode == "realtime" else None
        self.fast_path = False  # decided below, once asyncio has set up its fields
        #: inside :meth:`_run_fast`, where :meth:`call_next` may keep a callback to run after the current one
        self._inline_ok = False
        self._next: tuple[Callable[..., object], tuple[Any, ...]] | None = None
        super().__init__(selector=_ClockSelector(self))
        self._clock_resolution = 1e-9
        #: the fast path (batched iterations, light timer handles) is used: see :func:`fast_path_supported`
        self.fast_path = fast_path_supported(self)

    def time(self) -> float:
        if self.mode == "fast":
            return self._now
        cap = self._cap
        if cap is not None:
            return cap
        return (_time.monotonic() - self._wall0 + self.lead_s) * self.speed

    def set_lead(self, lead_s: float, writer_backend: str | None = None) -> None:
        """Realtime: run the clock ``lead_s`` wall seconds ahead of the outside world (module docstring;
        docs/decisions/performance.md D-10.E6). Transports with a real peer then hand their writes to
        :attr:`writer`, which performs each at :meth:`wall_at` of its scenario time. 0 turns it off (the
        writer, if any, is closed after writing what it holds). ``writer_backend``: the writer's backend
        (:data:`WRITER_BACKENDS`; None: :func:`default_writer_backend`)."""
        if self.mode != "realtime":
            raise ValueError("a lead applies to the realtime mode only")
        if lead_s < 0:
            raise ValueError(f"lead_s must be >= 0, got {lead_s}")
        if lead_s > 0 and self.writer is None:
            self.writer = PacedWriter(writer_backend)
        elif lead_s == 0 and self.writer is not None:
            self.writer.close()
            self.writer = None
        self.lead_s = float(lead_s)

    def writer_summary(self) -> dict[str, Any] | None:
        """The paced writer's state for a run's summary (None without one): the backend asked for, the one that
        writes (``process`` until it died), the scheduling policy, writes, failures and the error, if any."""
        w = self.writer
        if w is None:
            return None
        p = w.process
        return {"backend": w.backend, "writing": "process" if p is not None else "thread",
                "policy": p.policy if p is not None else w.policy,
                "writes": w.writes + (p.writes if p is not None else 0),
                "failures": w.failures + (p.failures if p is not None else 0),
                "error": None if w.error is None else str(w.error)}

    def wall_at(self, t: float) -> float:
        """The ``CLOCK_MONOTONIC`` instant (s) that scenario time ``t`` stands for in the outside world
        (realtime; the clock itself runs :attr:`lead_s` ahead of it)."""
        return self._wall0 + t / self.speed

    def close(self) -> None:
        if self.writer is not None:
            self.writer.close()
            self.writer = None
        super().close()

    def _run_once(self) -> None:
        self._cap = None
        sel = self._selector
        if self.mode != "fast" or self._debug or not self.fast_path or sel._nfds > 1:
            super()._run_once()  # type: ignore[misc]
            return
        self._run_fast(sel)

    #: fast mode: loop iterations run per call of :meth:`_run_once` at most
    FAST_BATCH = 256

    def _run_fast(self, sel: _ClockSelector) -> None:
        """Fast mode, no file descriptor but the self-pipe: up to :attr:`FAST_BATCH` iterations of
        :meth:`asyncio.BaseEventLoop._run_once` in one call, step for step the same (cancelled-timer
        clean-up, the virtual clock's jump to the earliest timer, every timer due within the clock
        resolution made ready in heap order, then exactly the callbacks ready at that moment), without
        the per-iteration selector call, timeout arithmetic and method lookups. Every
        ``SELF_PIPE_POLL_EVERY``-th iteration, and any iteration with nothing scheduled (which
        must block in the real selector), goes through the ordinary path, which polls the self-pipe."""
        self._inline_ok = True
        try:
            self._run_fast_batch(sel)
        finally:
            self._inline_ok = False
            if self._next is not None:  # a callback of asyncio's own iteration (below) kept one: queue it
                callback, args = self._next
                self._next = None
                self._ready.appendleft(_events.Handle(callback, args, self))

    def _run_fast_batch(self, sel: _ClockSelector) -> None:
        ready = self._ready
        heappop = heapq.heappop
        res = self._clock_resolution
        every = sel.SELF_PIPE_POLL_EVERY
        for _ in range(self.FAST_BATCH):
            if sel._skipped >= every or sel._nfds > 1:
                super()._run_once()  # type: ignore[misc]
                return
            sched = self._scheduled
            n_sched = len(sched)
            if n_sched > 100 and self._timer_cancelled_count / n_sched > 0.5:
                super()._run_once()  # type: ignore[misc]  # the rare full clean-up
                return
            while sched and sched[0]._cancelled:
                self._timer_cancelled_count -= 1
                heappop(sched)._scheduled = False
            if not ready and not self._stopping:
                if not sched:
                    super()._run_once()  # type: ignore[misc]  # waits in the real selector
                    return
                when = sched[0]._when
                if when > self._now:
                    self._now = when
            sel._skipped += 1
            end_time = self._now + res
            while sched and sched[0]._when < end_time:
                h = heappop(sched)
                h._scheduled = False
                ready.append(h)
            for _i in range(len(ready)):
                h = ready.popleft()
                if h._cancelled:
                    continue
                try:  # asyncio.Handle._run, without its frame
                    h._context.run(h._callback, *h._args)
                except (SystemExit, KeyboardInterrupt):
                    raise
                except BaseException as exc:
                    self._handle_failed(h, exc)
                while self._next is not None:  # (the kept callback may keep another)
                    self._run_next(res)
            h = None
            if self._stopping:
                return

    def _handle_failed(self, h: Any, exc: BaseException) -> None:
        """A handle's callback raised ``exc`` (the fast path runs handles inline): reported as
        :meth:`asyncio.Handle._run` reports it (the same message and context)."""
        cb = _format_callback_source(h._callback, h._args)
        context: dict[str, Any] = {"message": f"Exception in callback {cb}", "exception": exc, "handle": h}
        if h._source_traceback:
            context["source_traceback"] = h._source_traceback
        self.call_exception_handler(context)

    def call_next(self, callback: Callable[..., object], *args: Any) -> None:
        """``call_soon(callback, *args)``, for a callback that uses no context variables; on the fast path it is
        run right after the current callback instead, without a handle and a loop iteration, where that is the
        same thing.

        ``call_soon`` makes a handle that runs in a later iteration; when nothing was ready when it was called,
        it is that iteration's first callback. Where that iteration would run nothing else before it -- nothing
        else made ready since, no timer due within the clock resolution (they would come after it, and the clock
        does not move while something is ready), the loop not stopping -- the callback runs at once after the
        current one (:meth:`_run_next`), at the same ``time()``, and what it schedules is scheduled in the same
        order; otherwise the handle is put where ``call_soon`` would have put it (first). Exceptions reach the
        exception handler as from a handle. Outside the fast path (realtime, debug, outside the loop, something
        already ready, a second call within one callback): ``call_soon``. The DSP's tick after each IMU frame
        (one per 5 ms tick) is the user; ``tests/emulator/test_clock_fast_path.py`` compares the traces.
        """
        if self._inline_ok and self._next is None and not self._ready:
            self._next = (callback, args)
        else:
            self.call_soon(callback, *args)

    def _run_next(self, res: float) -> None:
        """Run (or queue first) the callback :meth:`call_next` kept during the callback that just ended."""
        callback, args = self._next  # type: ignore[misc]
        self._next = None
        sched = self._scheduled
        n_sched = len(sched)
        if not (self._ready or self._stopping or self._selector._nfds > 1
                or (n_sched > 100 and self._timer_cancelled_count / n_sched > 0.5)):
            # the next iteration's first steps, in its order (the heap's order of equal deadlines depends on the
            # sequence of its operations): drop the cancelled timers at the head; then a due timer would run after
            # the callback, so the callback waits for the iteration
            while sched and sched[0]._cancelled:
                self._timer_cancelled_count -= 1
                heapq.heappop(sched)._scheduled = False
            if not (sched and sched[0]._when < self._now + res):
                try:
                    callback(*args)
                except (SystemExit, KeyboardInterrupt):
                    raise
                except BaseException as exc:  # as asyncio.Handle._run reports it
                    self.call_exception_handler({"message": f"Exception in callback {callback!r}{args!r}",
                                                 "exception": exc})
                return
        self._ready.appendleft(_events.Handle(callback, args, self))  # where call_soon put it

    def call_at(self, when: float, callback: Any, *args: Any, context: Any = None) -> asyncio.TimerHandle:  # type: ignore[override]
        """:meth:`asyncio.BaseEventLoop.call_at` without its debug-mode checks (when debug is off, on the fast
        path)."""
        if self._debug or when is None or not self.fast_path:
            return super().call_at(when, callback, *args, context=context)
        if self._closed:
            raise RuntimeError("Event loop is closed")
        timer = _Timer(when, callback, args, self, context)
        heapq.heappush(self._scheduled, timer)
        timer._scheduled = True
        return timer

    def restart_clock(self) -> None:
        """Make the current instant scenario time 0 (realtime) or reset virtual time to 0 (fast).

        Timers already scheduled keep their remaining delay (their deadlines move with the
        origin), so a pty's attach poll set up before the restart still runs 20 ms later.
        """
        delta = self.time()
        for h in self._scheduled:  # a uniform shift keeps the heap ordered
            h._when -= delta
        self._cap = None
        self._wall0 = _time.monotonic()
        self._now = 0.0

    def wall_elapsed(self) -> float:
        """Wall-clock seconds since the clock was (re)started (the outside world's clock: without the lead)."""
        return _time.monotonic() - self._wall0

    @property
    def wall_origin(self) -> float:
        """``time.monotonic()`` (CLOCK_MONOTONIC, s, one per host) of scenario time 0 as the outside world sees it:
        in realtime mode a byte of scenario time ``t`` reaches a real port at ``wall_origin + t / speed``."""
        return self._wall0


def new_loop(mode: str = "fast", speed: float = 1.0) -> EmulatorLoop:
    """Create an :class:`EmulatorLoop` (not set as the current loop)."""
    return EmulatorLoop(mode, speed)


async def sleep_until(when: float) -> None:
    """Sleep until scenario time ``when`` (s), exactly, in either mode."""
    loop = asyncio.get_running_loop()
    fut = loop.create_future()
    handle = loop.call_at(when, _set_done, fut)
    try:
        await fut
    finally:
        handle.cancel()


def _set_done(fut: asyncio.Future[None]) -> None:
    if not fut.done():
        fut.set_result(None)
