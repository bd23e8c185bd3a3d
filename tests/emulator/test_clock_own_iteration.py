"""The loop's own iterations run callbacks exactly as asyncio's own iteration does.

:class:`emulator.clock.EmulatorLoop` keeps its timers and ready callbacks in structures of its own and runs asyncio's
iteration steps on them from the selector's ``select`` (D-10.E22). The reference here is asyncio's own loop on a
virtual clock, built from public API only (:class:`_AsyncioReference`): its ``time()`` is a virtual clock, and each
wait asyncio asks of its selector moves that clock to the earliest live timer. A random workload of timers (ties at
the same instant, cancellations, callbacks that schedule more callbacks, ``call_soon`` chains, a coroutine sleeping)
must give the identical trace of (virtual time, callback id), in order; a scenario run must write the same files.
"""

from __future__ import annotations

import asyncio
import selectors
import time
from typing import Any

import numpy as np
import pytest

from emulator.assembly import session
from emulator.assembly.session import run_scenario
from emulator.clock import EmulatorLoop, LoopCall
from emulator.testing import load_test_scenario
from tests.conftest import SCENARIOS


class _JumpingSelector(selectors.DefaultSelector):  # type: ignore[misc,valid-type]
    """The real selector; a wait asyncio asks for (the time to its earliest timer) jumps the virtual clock there."""

    def __init__(self, loop: Any) -> None:
        super().__init__()
        self.loop = loop

    def select(self, timeout: float | None = None) -> list[tuple[selectors.SelectorKey, int]]:
        loop = self.loop
        if timeout:  # asyncio's earliest live timer is `timeout` s ahead: the clock jumps to its deadline
            live = [h for h in loop.timers if not h.cancelled() and h.when() > loop.now]
            loop.now = min(h.when() for h in live)
            loop.timers = [h for h in live if h.when() > loop.now]
        return super().select(0)


class _AsyncioReference(EmulatorLoop):
    """asyncio's own iteration and timer handles on a virtual clock, through public API only: ``call_at``,
    ``call_later`` and ``call_soon`` are asyncio's (``asyncio.SelectorEventLoop``'s), ``call_next`` is ``call_soon``,
    the selector jumps the clock. Fast mode only; a restart of the clock with timers pending is refused."""

    def __init__(self, mode: str = "fast", speed: float = 1.0) -> None:
        assert mode == "fast"
        self.now = 0.0
        self.timers: list[asyncio.TimerHandle] = []
        asyncio.SelectorEventLoop.__init__(self, selector=_JumpingSelector(self))
        self.mode, self.speed, self.writer, self.lead_s = mode, speed, None, 0.0
        self._wall0 = time.monotonic()  # EmulatorLoop's wall origin (wall_elapsed)

    def time(self) -> float:
        return self.now

    def call_at(self, when, callback, *args, context=None):  # type: ignore[override]
        h = asyncio.SelectorEventLoop.call_at(self, when, callback, *args, context=context)
        self.timers.append(h)
        return h

    def call_later(self, delay, callback, *args, context=None):  # type: ignore[override]
        return asyncio.SelectorEventLoop.call_later(self, delay, callback, *args, context=context)

    def call_soon(self, callback, *args, context=None):  # type: ignore[override]
        return asyncio.SelectorEventLoop.call_soon(self, callback, *args, context=context)

    def call_next(self, callback, *args):  # type: ignore[override]
        self.call_soon(callback, *args)

    def stop(self) -> None:
        asyncio.SelectorEventLoop.stop(self)

    def set_debug(self, enabled: bool) -> None:
        asyncio.SelectorEventLoop.set_debug(self, enabled)

    def close(self) -> None:
        asyncio.SelectorEventLoop.close(self)

    def restart_clock(self) -> None:
        assert not [h for h in self.timers if not h.cancelled()], "the reference cannot shift asyncio's timers"
        self.now = 0.0


def _trace(loop_cls: type, seed: int, call_next: bool = False) -> list[tuple[float, int]]:
    """The workload's trace; ``call_next``: its ``call_soon`` chains go through ``EmulatorLoop.call_next``."""
    loop = loop_cls("fast")
    soon = loop.call_next if call_next else loop.call_soon
    rng = np.random.default_rng(seed)
    trace: list[tuple[float, int]] = []
    handles: list[Any] = []
    counter = [0]

    def cb(ident: int, depth: int) -> None:
        trace.append((loop.time(), ident))
        if depth < 3:
            for _ in range(int(rng.integers(0, 3))):
                counter[0] += 1
                k = int(rng.integers(0, 4))
                if k == 0:  # same instant (a tie)
                    handles.append(loop.call_at(loop.time(), cb, counter[0], depth + 1))
                elif k == 1:
                    soon(cb, counter[0], depth + 1)
                else:  # on a coarse grid: many ties between unrelated timers
                    handles.append(loop.call_at(loop.time() + float(rng.integers(1, 20)) * 0.001, cb, counter[0],
                                                depth + 1))
        if handles and rng.random() < 0.2:
            handles[int(rng.integers(0, len(handles)))].cancel()

    async def sleeper() -> None:
        for i in range(50):
            await asyncio.sleep(0.0025)
            trace.append((loop.time(), -1 - i))

    try:
        asyncio.set_event_loop(loop)
        for _i in range(300):
            counter[0] += 1
            handles.append(loop.call_at(float(rng.integers(0, 100)) * 0.001, cb, counter[0], 0))
        loop.run_until_complete(asyncio.gather(sleeper(), asyncio.sleep(0.5)))
    finally:
        asyncio.set_event_loop(None)
        loop.close()
    return trace


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_own_iteration_runs_callbacks_in_asyncio_order(seed: int) -> None:
    ref = _trace(_AsyncioReference, seed)
    got = _trace(EmulatorLoop, seed)
    assert len(ref) > 500
    assert got == ref


def test_heap_rebuild_keeps_asyncios_order() -> None:
    """Over 100 timers with most cancelled: both heaps are rebuilt (asyncio's rule, HEAP_REBUILD_MIN), and the ties
    left still pop in asyncio's order."""
    traces = []
    for cls in (_AsyncioReference, EmulatorLoop):
        loop = cls("fast")
        trace: list[tuple[float, int]] = []
        try:
            hs = [loop.call_at(0.001 * (i % 7), lambda i=i, tr=trace, lp=loop: tr.append((lp.time(), i)))
                  for i in range(400)]
            for h in hs[::3] + hs[1::3]:
                h.cancel()
            loop.run_until_complete(asyncio.sleep(0.01))
        finally:
            loop.close()
        traces.append(trace)
    assert len(traces[0]) == 133 and traces[1] == traces[0]


def test_heap_of_pairs_pops_in_the_order_of_a_heap_of_calls() -> None:
    """The timer heap holds ``(deadline, call)`` pairs (D-10.E23): the same random pushes and pops, most of them ties,
    pop the calls in the same order as a heap of the calls themselves (ordered by deadline alone, as asyncio's
    handles), because a pair's tie falls through to ``LoopCall.__lt__``, False both ways."""
    import heapq

    loop = EmulatorLoop("fast")
    rng = np.random.default_rng(7)
    try:
        a, b = (LoopCall(1.0, print, (), None, loop) for _ in range(2))  # type: ignore[arg-type]
        assert not (1.0, a) < (1.0, b) and not (1.0, b) < (1.0, a) and (0.5, b) < (1.0, a)
        calls: list[LoopCall] = []
        pairs: list[tuple[float, LoopCall]] = []
        popped_calls, popped_pairs = [], []
        for _ in range(5000):
            if calls and rng.random() < 0.45:
                popped_calls.append(heapq.heappop(calls))
                popped_pairs.append(heapq.heappop(pairs)[1])
            else:
                call = LoopCall(float(rng.integers(0, 6)) * 0.005, print, (), None, loop)  # type: ignore[arg-type]
                heapq.heappush(calls, call)
                heapq.heappush(pairs, (call.deadline, call))
        assert len(popped_calls) > 1500
        assert popped_pairs == popped_calls
    finally:
        loop.close()


class _CountingLoop(EmulatorLoop):
    """Counts the callbacks ``call_next`` ran after the current one and the ones it queued (as ``call_soon``)."""

    inline = 0
    queued = 0

    def call_exception_handler(self, context):  # type: ignore[override]
        raise AssertionError(context)

    def _run_next(self) -> None:
        kept = self._next
        super()._run_next()
        r = self._ready_calls
        if r and (r[0].callback, r[0].args) == kept:
            type(self).queued += 1
        else:
            type(self).inline += 1


@pytest.mark.parametrize("seed", [1, 2, 3, 4, 5])
def test_call_next_runs_callbacks_in_call_soon_order(seed: int) -> None:
    """``call_next`` in fast mode (the callback run right after the current one where nothing would come between,
    else queued first) gives the trace of ``call_soon`` on asyncio's own iteration, with ties at one instant,
    cancellations and several ``call_soon`` calls in one callback, in any position."""
    ref = _trace(_AsyncioReference, seed)
    assert _trace(_AsyncioReference, seed, call_next=True) == ref  # asyncio's own iteration: call_soon
    _CountingLoop.inline = _CountingLoop.queued = 0
    assert _trace(_CountingLoop, seed, call_next=True) == ref
    assert _CountingLoop.inline > 5 and _CountingLoop.queued > 5, (_CountingLoop.inline, _CountingLoop.queued)


def test_call_next_queues_outside_the_loop_and_in_realtime() -> None:
    for mode in ("fast", "realtime"):
        loop = EmulatorLoop(mode)
        ran: list[int] = []
        try:
            loop.call_next(ran.append, 1)  # the loop is not running: queued, as call_soon
            assert ran == [] and len(loop._ready_calls) == 1
            loop.run_until_complete(asyncio.sleep(0))
            assert ran == [1]
        finally:
            loop.close()


def test_call_next_reports_an_exception_as_a_call_does() -> None:
    loop = EmulatorLoop("fast")
    seen: list[dict[str, Any]] = []
    loop.set_exception_handler(lambda _loop, ctx: seen.append(ctx))

    def boom() -> None:
        raise ValueError("boom")

    try:
        loop.call_at(0.1, loop.call_next, boom)
        loop.run_until_complete(asyncio.sleep(0.2))
    finally:
        loop.close()
    assert len(seen) == 1 and isinstance(seen[0]["exception"], ValueError)
    assert seen[0]["message"] == ("Exception in callback "
                                  "test_call_next_reports_an_exception_as_a_call_does.<locals>.boom()")


def test_a_failing_callback_is_reported_and_the_loop_goes_on() -> None:
    """A callback that raises reaches the exception handler with asyncio's message ("Exception in callback"
    and the callback with its arguments), the exception and the call as ``handle``; the loop goes on."""
    def boom(x: int) -> None:
        raise ValueError(f"boom {x}")

    loop = EmulatorLoop("fast")
    seen: list[dict[str, Any]] = []
    loop.set_exception_handler(lambda _loop, ctx: seen.append(ctx))
    after: list[float] = []
    try:
        h = loop.call_at(0.1, boom, 7)
        loop.call_at(0.15, lambda: after.append(loop.time()))
        loop.run_until_complete(asyncio.sleep(0.2))
    finally:
        loop.close()
    assert len(seen) == 1 and seen[0]["handle"] is h and after == [0.15]
    assert str(seen[0]["exception"]) == "boom 7"
    assert seen[0]["message"].startswith("Exception in callback ") and seen[0]["message"].endswith("boom(7)")


def test_cancel_counts_a_timer_in_the_heap_once() -> None:
    """``LoopCall.cancel`` as asyncio's ``TimerHandle.cancel``: counted once per timer still in the heap (the heap's
    rebuild rule), not for one already out of it, not twice; the callback and its arguments released."""
    loop = EmulatorLoop("fast")
    try:
        a, b = loop.call_at(1.0, print, 1), loop.call_at(2.0, print, 2)
        assert isinstance(a, LoopCall) and a.when() == 1.0
        loop.run_until_complete(asyncio.sleep(1.5))  # a ran: out of the heap
        for h in (a, b, b):
            h.cancel()
        assert loop.cancelled_in_heap == 1
        assert b.cancelled() and b.callback is None and b.args is None
        loop.run_until_complete(asyncio.sleep(1.0))  # the cancelled b dropped from the head
        assert loop.cancelled_in_heap == 0 and loop.time() == pytest.approx(2.5)
    finally:
        loop.close()


def test_debug_mode_warns_of_a_slow_callback(caplog: pytest.LogCaptureFixture) -> None:
    loop = EmulatorLoop("fast")
    loop.set_debug(True)
    loop.slow_callback_duration = 0.0
    try:
        loop.call_at(0.1, lambda: None)
        with caplog.at_level("WARNING", logger="asyncio"):
            loop.run_until_complete(asyncio.sleep(0.2))
    finally:
        loop.set_debug(False)
        loop.close()
    assert any("Executing <LoopCall" in r.getMessage() for r in caplog.records)


def test_scenario_run_writes_the_same_files_as_on_asyncios_own_iteration(tmp_path, monkeypatch) -> None:
    """A scenario run on the loop's own iterations writes the same files, byte for byte, as on asyncio's own
    iteration (:class:`_AsyncioReference`)."""
    scn = load_test_scenario(SCENARIOS / "quickstart.yaml", {"duration_s": 5.0})
    s_own = run_scenario(scn, tmp_path / "own")
    monkeypatch.setattr(session, "EmulatorLoop", _AsyncioReference)
    s_ref = run_scenario(scn, tmp_path / "ref")
    for name in ("capture.psnscap", "nav.csv", "truth.csv", "events.jsonl", "timeline.csv", "filter_state.csv"):
        assert (tmp_path / "own" / name).read_bytes() == (tmp_path / "ref" / name).read_bytes(), name
    wall = {"wall_s", "realtime_factor", "run_dir"}
    assert {k: v for k, v in s_own.items() if k not in wall} == {k: v for k, v in s_ref.items() if k not in wall}
    assert s_own["nav_frames"] > 400


def test_a_failing_callbacks_long_arguments_are_shortened_in_the_message() -> None:
    """A chunk of 10 000 bytes does not make a 10 000-character message (asyncio shortens with ``reprlib`` too)."""
    def fail(_data: bytes) -> None:
        raise ValueError("bad chunk")

    loop = EmulatorLoop("fast")
    seen: list[dict[str, Any]] = []
    loop.set_exception_handler(lambda _loop, ctx: seen.append(ctx))
    try:
        loop.call_at(0.1, fail, b"x" * 10_000)
        loop.run_until_complete(asyncio.sleep(0.2))
    finally:
        loop.close()
    assert len(seen) == 1 and "fail(b'xxx" in seen[0]["message"] and len(seen[0]["message"]) < 200
