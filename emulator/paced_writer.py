"""The paced writer: performs writes for real peers at the wall instants their scenario times stand for.

The realtime loop computing ahead (:meth:`emulator.clock.EmulatorLoop.set_lead`, docs/decisions/performance.md
D-10.E6) puts each chunk for a real peer here; a writer process (:mod:`emulator.pacing`, D-10.E11) or a thread writes
it at its instant.
"""

from __future__ import annotations

import contextlib
import os
import sys
import threading
import time as _time
from collections import deque
from collections.abc import Callable, Hashable
from typing import Any

from .errors import LinkConfigError, WriterProcessError
from .pacing import PacedPeer, WriterProcess, ask_rt_priority, set_timer_slack

__all__ = ["WRITER_BACKENDS", "WRITER_ENV", "PacedWriter", "default_writer_backend"]

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
