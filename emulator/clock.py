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
    happens that much early; what leaves for a real peer is handed to a
    :class:`~emulator.paced_writer.PacedWriter`, which performs each write at the wall instant its scenario
    time stands for (:meth:`EmulatorLoop.wall_at`): from a writer process (:mod:`emulator.pacing`, D-10.E11)
    for ptys and serial devices on Linux, else from a thread. A callback that holds the loop for a few ms then no longer
    delays the bytes; what the outside sends is stamped on arrival with the loop's (early) clock,
    so it takes effect up to ``lead_s`` later than without the lead.

Own timers and callbacks (docs/decisions/performance-windows.md D-10.E22). The loop keeps its timers in a heap of
its own and its ready callbacks in a queue of its own (:class:`LoopCall`): ``call_at``, ``call_later`` and
``call_soon`` put them there. asyncio's own iteration then holds nothing but the callbacks of file descriptors,
other threads and signals; each time it asks the selector to wait, the loop runs its own iterations there
(:meth:`EmulatorLoop._iterate`: asyncio's steps, in asyncio's order, on the loop's data) -- in fast mode up to
:attr:`EmulatorLoop.ITERATIONS_PER_POLL` of them, the clock jumping to each next timer, before the self-pipe is
polled; in realtime mode one, after the wait. No private field of asyncio is read or written (a test greps every
module for them), so the same loop runs on every Python the project supports. Where an iteration also has
callbacks of file descriptors, the loop's own run first (asyncio's order is the reverse; such runs are not
repeatable anyway).

Devices use only ``loop.time()`` and ``loop.call_at()`` / ``asyncio.sleep``, so the same code
runs in both modes. :func:`sleep_until` waits for an absolute scenario time without the drift
that repeated relative sleeps accumulate.
"""

from __future__ import annotations

import asyncio
import heapq
import logging
import reprlib
import selectors
import time as _time
from collections import deque
from collections.abc import Callable
from contextvars import Context, copy_context
from typing import Any

from .paced_writer import PacedWriter
from .pacing import TIMER_SLACK_NS, set_timer_slack

__all__ = ["CLOCK_RESOLUTION_S", "TIMER_SLACK_NS", "EmulatorLoop", "LoopCall", "new_loop", "set_timer_slack",
           "sleep_until"]

#: the clock resolution (s) an iteration adds to "now" when it decides which timers are due: asyncio takes the
#: monotonic clock's, 1 ns on Linux; the virtual clock has none, so the same 1 ns everywhere
CLOCK_RESOLUTION_S = 1e-9
#: asyncio's rule for its timer heap (``BaseEventLoop``): rebuilt without its cancelled timers when it holds more than
#: this many and more than this fraction of them is cancelled, else only the cancelled ones at its head dropped. The
#: loop's own heap follows the same rule, so timers with equal deadlines pop in asyncio's order.
HEAP_REBUILD_MIN = 100
HEAP_REBUILD_FRACTION = 0.5
#: the longest wait (s) asyncio asks of a selector (its ``MAXIMUM_SELECT_TIMEOUT``)
_MAX_WAIT_S = 24 * 3600.0
_asyncio_log = logging.getLogger("asyncio")


class LoopCall:
    """A callback the loop runs: at a deadline (what :meth:`EmulatorLoop.call_at` and ``call_later`` return) or
    in its next iteration (``call_soon``). The methods asyncio's handles offer: :meth:`when`, :meth:`cancel`,
    :meth:`cancelled`, :meth:`get_context`. The loop's timer heap orders calls by deadline alone, as asyncio's
    orders its ``TimerHandle`` objects, so calls with equal deadlines leave the heap in the order its operations
    give, the same order as asyncio's (docs/decisions/performance-windows.md D-10.E22). The heap holds
    ``(deadline, call)`` pairs: the pairs compare as the calls do (equal deadlines fall through to
    :meth:`__lt__`, which says False both ways), with the deadlines compared in C (D-10.E23)."""

    __slots__ = ("args", "callback", "context", "deadline", "in_heap", "is_cancelled", "loop")

    def __init__(self, deadline: float, callback: Callable[..., object], args: tuple[Any, ...], context: Context,
                 loop: EmulatorLoop) -> None:
        self.deadline = deadline  # scenario time (s) it is due at (call_soon: the fast clock when made)
        self.callback: Callable[..., object] | None = callback
        self.args: tuple[Any, ...] | None = args
        self.context = context
        self.loop = loop
        self.is_cancelled = False
        self.in_heap = False

    def __lt__(self, other: LoopCall) -> bool:
        return self.deadline < other.deadline

    def when(self) -> float:
        """The scenario time (s) the call is due at."""
        return self.deadline

    def cancel(self) -> None:
        """Do not run it; the callback and its arguments are released. A cancelled timer stays in the heap until
        it reaches the head, or until more than half the heap is cancelled (asyncio's rule)."""
        if self.is_cancelled:
            return
        self.is_cancelled = True
        if self.in_heap:
            self.loop.cancelled_in_heap += 1
        self.callback = None
        self.args = None

    def cancelled(self) -> bool:
        return self.is_cancelled

    def get_context(self) -> Context:
        return self.context

    def describe(self) -> str:
        """The callback and its arguments, as asyncio's messages name a handle's callback."""
        return _describe(self.callback, self.args or ())

    def __repr__(self) -> str:
        state = " cancelled" if self.is_cancelled else ""
        return f"<LoopCall{state} when={self.deadline!r} {self.describe()}>"


def _describe(callback: Callable[..., object] | None, args: tuple[Any, ...]) -> str:
    """``name(arg, ...)`` of a callback, for the exception handler's message (long arguments shortened, as asyncio
    shortens them)."""
    name = getattr(callback, "__qualname__", None) or repr(callback)
    return f"{name}({', '.join(map(reprlib.repr, args))})"


class _ClockSelector(selectors.BaseSelector):
    """The real selector, wrapped: each ``select`` asyncio's iteration makes is where :class:`EmulatorLoop` runs its
    own iterations (its timers and callbacks) on its clock, then polls or waits for file descriptors."""

    def __init__(self, loop: EmulatorLoop) -> None:
        self.real = selectors.DefaultSelector()
        self._loop = loop
        #: file descriptors registered (asyncio's self-pipe is the first)
        self.nfds = 0

    # delegation ------------------------------------------------------------------
    def register(self, fileobj: Any, events: int, data: Any = None) -> selectors.SelectorKey:
        key = self.real.register(fileobj, events, data)
        self.nfds += 1
        return key

    def unregister(self, fileobj: Any) -> selectors.SelectorKey:
        key = self.real.unregister(fileobj)
        self.nfds -= 1
        return key

    def modify(self, fileobj: Any, events: int, data: Any = None) -> selectors.SelectorKey:
        return self.real.modify(fileobj, events, data)

    def get_key(self, fileobj: Any) -> selectors.SelectorKey:
        return self.real.get_key(fileobj)

    def get_map(self) -> Any:
        return self.real.get_map()

    def close(self) -> None:
        self.real.close()

    def select(self, timeout: float | None = None) -> list[tuple[selectors.SelectorKey, int]]:
        loop = self._loop
        if loop.mode == "fast":
            return loop._select_fast(timeout)
        return loop._select_realtime(timeout)


class EmulatorLoop(asyncio.SelectorEventLoop):
    """Selector event loop whose clock is the scenario clock (s since scenario start).

    Its timers and callbacks are its own (:class:`LoopCall`, a heap and a queue): ``call_at``, ``call_later`` and
    ``call_soon`` put them there, and each of asyncio's iterations runs the loop's own iterations from the
    selector's ``select`` (module docstring), so no private field of asyncio is read or written.

    Parameters
    ----------
    mode:
        ``"fast"`` (virtual time) or ``"realtime"`` (wall clock times ``speed``).
    speed:
        Real-time scale factor; only used in realtime mode.
    """

    #: fast mode, no file descriptor but asyncio's self-pipe: the loop's iterations run per ``select`` at most
    #: before the self-pipe (signals, ``call_soon_threadsafe``) is polled
    ITERATIONS_PER_POLL = 64
    #: realtime: waits shorter than this are slept precisely (epoll has 1 ms resolution)
    FINE_S = 0.0015

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
        #: the timer heap (``(deadline, call)`` pairs, ordered as the calls by deadline) and the calls ready to run,
        #: in order
        self._timer_heap: list[tuple[float, LoopCall]] = []
        self._ready_calls: deque[LoopCall] = deque()
        #: cancelled timers still in the heap (asyncio's rule for rebuilding it)
        self.cancelled_in_heap = 0
        self._stop_asked = False
        self._shut = False
        self._debug_on = False
        #: inside the loop's own iterations in fast mode, where :meth:`call_next` may keep a callback to run after
        #: the current one
        self._inline_ok = False
        self._next: tuple[Callable[..., object], tuple[Any, ...]] | None = None
        self._clock_selector = _ClockSelector(self)
        super().__init__(selector=self._clock_selector)

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

    # -- scheduling ---------------------------------------------------------------------
    def call_at(self, when: float, callback: Callable[..., object], *args: Any,  # type: ignore[override]
                context: Context | None = None) -> LoopCall:
        """Run ``callback(*args)`` at scenario time ``when`` (s); the returned :class:`LoopCall` cancels it."""
        if self._shut:
            raise RuntimeError("Event loop is closed")
        if when is None:
            raise TypeError("when cannot be None")
        call = LoopCall(when, callback, args, copy_context() if context is None else context, self)
        heapq.heappush(self._timer_heap, (when, call))
        call.in_heap = True
        return call

    def call_soon(self, callback: Callable[..., object], *args: Any,  # type: ignore[override]
                  context: Context | None = None) -> LoopCall:
        """Run ``callback(*args)`` in the loop's next iteration, after the calls already queued."""
        if self._shut:
            raise RuntimeError("Event loop is closed")
        call = LoopCall(self._now, callback, args, copy_context() if context is None else context, self)
        self._ready_calls.append(call)
        return call

    def call_next(self, callback: Callable[..., object], *args: Any) -> None:
        """``call_soon(callback, *args)``, for a callback that uses no context variables; in fast mode it is run
        right after the current callback instead, without a :class:`LoopCall` and an iteration, where that is the
        same thing.

        ``call_soon`` queues a call for the next iteration; when nothing else is queued, it is that iteration's
        first callback. Where that iteration would run nothing else before it -- nothing else queued since, no
        timer due within the clock resolution (they would come after it, and the clock does not move while
        something is queued), the loop not stopping -- the callback runs at once after the current one
        (:meth:`_run_next`), at the same ``time()``, and what it schedules is scheduled in the same order;
        otherwise it is queued where ``call_soon`` would have queued it (first). Exceptions reach the exception
        handler as from a call. Elsewhere (realtime, debug, file descriptors polled, outside the loop, something
        already queued, a second call within one callback): ``call_soon``. The DSP's tick after each IMU frame
        (one per 5 ms tick) is the user (D-10.E7); ``tests/emulator/test_clock_own_iteration.py`` compares the traces.
        """
        if self._inline_ok and self._next is None and not self._ready_calls:
            self._next = (callback, args)
        else:
            self.call_soon(callback, *args)

    def call_later(self, delay: float, callback: Callable[..., object], *args: Any,  # type: ignore[override]
                   context: Context | None = None) -> LoopCall:
        """Run ``callback(*args)`` ``delay`` s (scenario time) from now."""
        if delay is None:
            raise TypeError("delay must not be None")
        return self.call_at(self.time() + delay, callback, *args, context=context)

    def stop(self) -> None:
        self._stop_asked = True
        super().stop()

    def set_debug(self, enabled: bool) -> None:
        self._debug_on = bool(enabled)
        super().set_debug(enabled)

    def close(self) -> None:
        if self.writer is not None:
            self.writer.close()
            self.writer = None
        super().close()
        self._shut = True
        self._timer_heap.clear()
        self._ready_calls.clear()
        self.cancelled_in_heap = 0

    # -- the loop's own iteration --------------------------------------------------------
    def _drop_cancelled(self) -> None:
        """asyncio's clean-up of its timer heap, on the loop's own: rebuilt without the cancelled timers when
        :meth:`_rebuild_due`, else the cancelled ones at its head popped."""
        if not self._rebuild_due():
            self._pop_cancelled_head()
            return
        kept = []
        for entry in self._timer_heap:
            call = entry[1]
            if call.is_cancelled:
                call.in_heap = False
            else:
                kept.append(entry)
        heapq.heapify(kept)
        self._timer_heap = kept
        self.cancelled_in_heap = 0

    def _rebuild_due(self) -> bool:
        """asyncio's rule: more than :data:`HEAP_REBUILD_MIN` timers in the heap and more than
        :data:`HEAP_REBUILD_FRACTION` of them cancelled."""
        n = len(self._timer_heap)
        return n > HEAP_REBUILD_MIN and self.cancelled_in_heap / n > HEAP_REBUILD_FRACTION

    def _pop_cancelled_head(self) -> None:
        heap = self._timer_heap
        while heap and heap[0][1].is_cancelled:
            self.cancelled_in_heap -= 1
            heapq.heappop(heap)[1].in_heap = False

    def _iterate(self, jump: bool) -> bool:
        """One iteration, asyncio's steps on the loop's own heap and queue: drop cancelled timers (asyncio's rule);
        with nothing queued and ``jump`` (fast mode, asyncio holding nothing of its own), move the clock to the
        earliest timer; queue, in heap order, every timer due within :data:`CLOCK_RESOLUTION_S`; run exactly the
        calls queued at that moment (what they queue runs in the next iteration). False, having done nothing, when
        nothing is queued or scheduled: only a file descriptor or another thread can bring work then."""
        if self.cancelled_in_heap:  # (else there is nothing to drop)
            self._drop_cancelled()
        heap = self._timer_heap
        ready = self._ready_calls
        if not ready:
            if not heap:
                return False
            if jump:
                when = heap[0][0]
                if when > self._now:
                    self._now = when
        end = self.time() + CLOCK_RESOLUTION_S
        heappop = heapq.heappop
        while heap and heap[0][0] < end:
            call = heappop(heap)[1]
            call.in_heap = False
            ready.append(call)
        debug = self._debug_on
        for _i in range(len(ready)):
            call = ready.popleft()
            if call.is_cancelled:
                continue
            t0 = _time.monotonic() if debug else 0.0
            try:
                call.context.run(call.callback, *call.args)  # type: ignore[arg-type,misc]
            except (SystemExit, KeyboardInterrupt):
                raise
            except BaseException as exc:
                self.call_exception_handler({"message": f"Exception in callback {call.describe()}",
                                             "exception": exc, "handle": call})
            if debug:
                took = _time.monotonic() - t0
                if took >= self.slow_callback_duration:
                    _asyncio_log.warning("Executing %r took %.3f seconds", call, took)
            while self._next is not None:  # (the kept callback may keep another)
                self._run_next()
        return True

    def _run_next(self) -> None:
        """Run (or queue first) the callback :meth:`call_next` kept during the callback that just ended."""
        callback, args = self._next  # type: ignore[misc]
        self._next = None
        if not (self._ready_calls or self._stop_asked or self._clock_selector.nfds > 1
                or (self.cancelled_in_heap and self._rebuild_due())):
            # the next iteration's first steps, in its order (the heap's order of equal deadlines depends on the
            # sequence of its operations): drop the cancelled timers at the head; then a due timer would run after
            # the callback, so the callback waits for the iteration
            if self.cancelled_in_heap:
                self._pop_cancelled_head()
            heap = self._timer_heap
            if not (heap and heap[0][0] < self._now + CLOCK_RESOLUTION_S):
                try:
                    callback(*args)
                except (SystemExit, KeyboardInterrupt):
                    raise
                except BaseException as exc:  # as a call's failure is reported
                    self.call_exception_handler({"message": f"Exception in callback {_describe(callback, args)}",
                                                 "exception": exc})
                return
        self._ready_calls.appendleft(LoopCall(self._now, callback, args, copy_context(), self))

    def _select_fast(self, timeout: float | None) -> list[tuple[selectors.SelectorKey, int]]:
        """Fast mode: asyncio's iteration asks to wait ``timeout`` (0: it holds callbacks of its own -- from a file
        descriptor, another thread, a signal -- or is stopping; None: nothing). The loop runs its iterations here,
        the clock jumping to each next timer, and returns what the real selector has ready."""
        sel = self._clock_selector
        real = sel.real
        if timeout == 0:
            events = real.select(0)
            self._iterate(jump=False)
            return events
        self._stop_asked = False  # asyncio asks for a wait only when it is not stopping
        if sel.nfds > 1:  # a real file descriptor: polled on every iteration; with events, the clock stays
            events = real.select(0)
            if events:
                self._iterate(jump=False)
                return events
            if self._iterate(jump=True):
                return []
            return real.select(timeout)
        self._inline_ok = not self._debug_on
        try:
            for _i in range(self.ITERATIONS_PER_POLL):
                if not self._iterate(jump=True):
                    return real.select(timeout)  # only the self-pipe can bring work now
                if self._stop_asked or sel.nfds > 1:  # stopping, or a descriptor to poll
                    break
        finally:
            self._inline_ok = False
        return real.select(0)

    def _select_realtime(self, timeout: float | None) -> list[tuple[selectors.SelectorKey, int]]:
        """Realtime: wait (scaled by ``speed``) for the earliest timer or a file descriptor; one reading of the
        clock then decides the iteration's instant (D-7.7, D-10.E12): the earliest timer's own deadline when it is
        due, else this moment. The loop's iteration runs here; callbacks of file descriptors after it (asyncio runs
        them when this returns)."""
        self._cap = None
        if timeout != 0:
            self._stop_asked = False  # asyncio asks for a wait only when it is not stopping
        self._drop_cancelled()
        heap = self._timer_heap
        if timeout == 0 or self._ready_calls:
            wait: float | None = 0.0
        elif heap:
            wait = min(max(0.0, heap[0][0] - self.time()), _MAX_WAIT_S)
        else:
            wait = None
        events = self._wait_scaled(self._clock_selector.real, wait)
        # time() reads the cap until the iteration ends, so the test of which timers are due (time() + resolution)
        # agrees with this one, and every timer's callback sees exactly its own instant. (Read twice, a timer
        # falling due between the two readings ran at the second one, behind the callbacks already queued -- a
        # DSP tick of 0.3-0.7 ms -- and what it sent took that late instant as its own.)
        now = self.time()
        self._cap = heap[0][0] if heap and heap[0][0] <= now else now
        self._iterate(jump=False)
        return events

    def _wait_scaled(self, real: selectors.BaseSelector,
                     wait: float | None) -> list[tuple[selectors.SelectorKey, int]]:
        if wait is None or wait <= 0:
            return real.select(wait)
        wait = wait / self.speed
        if wait > self.FINE_S:
            # epoll rounds its timeout up to whole milliseconds: wake a bit early and let the next iteration sleep
            # the rest precisely
            return real.select(wait - self.FINE_S)
        events = real.select(0)
        if not events:
            _time.sleep(wait)  # sub-millisecond precision; no I/O for < FINE_S
            events = real.select(0)
        return events

    def restart_clock(self) -> None:
        """Make the current instant scenario time 0 (realtime) or reset virtual time to 0 (fast).

        Timers already scheduled keep their remaining delay (their deadlines move with the
        origin), so a pty's attach poll set up before the restart still runs 20 ms later.
        """
        delta = self.time()
        for i, (when, call) in enumerate(self._timer_heap):  # a uniform shift keeps the heap ordered
            call.deadline = when - delta
            self._timer_heap[i] = (call.deadline, call)
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
