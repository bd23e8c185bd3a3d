"""The fast-mode loop's batched iterations run callbacks exactly as asyncio's own iteration does.

:meth:`emulator.clock.EmulatorLoop._run_fast` replaces ``asyncio.BaseEventLoop._run_once`` in fast
mode for speed (the fast path), and its ``call_at`` builds lighter timer handles. The reference here is
the same loop class with both switched off (asyncio's ``_run_once`` and ``call_at``): a random workload of
timers (ties at the
same instant, cancellations, callbacks that schedule more callbacks, ``call_soon`` chains, a
coroutine sleeping) must give the identical trace of (virtual time, callback id), in order.
"""

from __future__ import annotations

import asyncio

import numpy as np
import pytest

from emulator import clock
from emulator.assembly.session import run_scenario
from emulator.clock import FAST_PATH_VERSIONS, EmulatorLoop, fast_path_supported
from emulator.testing import load_test_scenario
from tests.conftest import SCENARIOS


class _ReferenceLoop(EmulatorLoop):
    """asyncio's own iteration and asyncio's own timer handles."""

    def _run_once(self) -> None:
        self._cap = None
        asyncio.SelectorEventLoop._run_once(self)  # type: ignore[attr-defined]

    def call_at(self, when, callback, *args, context=None):  # type: ignore[override]
        return asyncio.SelectorEventLoop.call_at(self, when, callback, *args, context=context)


def _trace(loop_cls: type, seed: int, call_next: bool = False) -> list[tuple[float, int]]:
    """The workload's trace; ``call_next``: its ``call_soon`` chains go through ``EmulatorLoop.call_next``."""
    loop = loop_cls("fast")
    soon = loop.call_next if call_next else loop.call_soon
    rng = np.random.default_rng(seed)
    trace: list[tuple[float, int]] = []
    handles: list[asyncio.TimerHandle] = []
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
def test_fast_path_runs_callbacks_in_asyncio_order(seed: int) -> None:
    ref = _trace(_ReferenceLoop, seed)
    got = _trace(EmulatorLoop, seed)
    assert len(ref) > 500
    assert got == ref


class _CountingLoop(EmulatorLoop):
    """Counts the callbacks ``call_next`` ran after the current one and the ones it queued (as ``call_soon``)."""

    inline = 0
    queued = 0

    def call_exception_handler(self, context):  # type: ignore[override]
        raise AssertionError(context)

    def _run_next(self, res):  # type: ignore[override]
        kept = self._next
        super()._run_next(res)
        r = self._ready
        if r and (r[0]._callback, r[0]._args) == kept:
            type(self).queued += 1
        else:
            type(self).inline += 1


@pytest.mark.parametrize("seed", [1, 2, 3, 4, 5])
def test_call_next_runs_callbacks_in_call_soon_order(seed: int) -> None:
    """``call_next`` on the fast path (the callback run right after the current one where nothing would come
    between, else queued first) gives the trace of ``call_soon`` on asyncio's own iteration, with ties at one
    instant, cancellations and several ``call_soon`` calls in one callback, in any position."""
    ref = _trace(_ReferenceLoop, seed)
    assert _trace(_ReferenceLoop, seed, call_next=True) == ref  # asyncio's own iteration: call_soon
    _CountingLoop.inline = _CountingLoop.queued = 0
    assert _trace(_CountingLoop, seed, call_next=True) == ref
    if EmulatorLoop("fast").fast_path:  # both ways really taken
        assert _CountingLoop.inline > 5 and _CountingLoop.queued > 5, (_CountingLoop.inline, _CountingLoop.queued)


def test_call_next_queues_outside_the_loop_and_in_realtime() -> None:
    for mode in ("fast", "realtime"):
        loop = EmulatorLoop(mode)
        ran: list[int] = []
        try:
            loop.call_next(ran.append, 1)  # the loop is not running: a handle, as call_soon
            assert ran == [] and len(loop._ready) == 1
            loop.run_until_complete(asyncio.sleep(0))
            assert ran == [1]
        finally:
            loop.close()


def test_call_next_reports_an_exception_as_a_handle_does() -> None:
    loop = EmulatorLoop("fast")
    seen: list[BaseException] = []
    loop.set_exception_handler(lambda _loop, ctx: seen.append(ctx["exception"]))

    def boom() -> None:
        raise ValueError("boom")

    try:
        loop.call_at(0.1, loop.call_next, boom)
        loop.run_until_complete(asyncio.sleep(0.2))
    finally:
        loop.close()
    assert len(seen) == 1 and isinstance(seen[0], ValueError)


def test_fast_path_is_taken() -> None:
    """The batched path really runs (else the test above compares asyncio with itself)."""
    calls = []

    class Probe(EmulatorLoop):
        def _run_fast(self, sel):  # type: ignore[override]
            calls.append(1)
            return super()._run_fast(sel)

    loop = Probe("fast")
    if not loop.fast_path:
        loop.close()
        pytest.skip(f"the fast path is used on CPython {sorted(FAST_PATH_VERSIONS)} only")
    try:
        for i in range(100):
            loop.call_at(i * 0.01, lambda: None)
        loop.run_until_complete(asyncio.sleep(1.5))
    finally:
        loop.close()
    assert calls
    assert loop.time() == pytest.approx(1.5)


def test_fast_path_is_used_on_the_tested_python_versions() -> None:
    loop = EmulatorLoop("fast")
    try:
        import sys

        assert loop.fast_path == fast_path_supported(loop)
        if sys.implementation.name == "cpython" and sys.version_info[:2] in FAST_PATH_VERSIONS:
            assert loop.fast_path  # the private fields it needs are there
    finally:
        loop.close()


def _untested_python(monkeypatch: pytest.MonkeyPatch) -> None:
    """Make this interpreter a Python version the fast path was not tested on."""
    monkeypatch.setattr(clock, "FAST_PATH_VERSIONS", frozenset())


def test_fallback_runs_asyncios_own_iteration(monkeypatch: pytest.MonkeyPatch) -> None:
    """On an untested Python version: asyncio's ``_run_once`` and ``call_at``, never the batched path."""
    _untested_python(monkeypatch)
    calls = []

    class Probe(EmulatorLoop):
        def _run_fast(self, sel):  # type: ignore[override]
            calls.append(1)
            return super()._run_fast(sel)

    loop = Probe("fast")
    try:
        assert not loop.fast_path
        h = loop.call_at(0.5, lambda: None)
        assert type(h) is asyncio.TimerHandle
        loop.run_until_complete(asyncio.sleep(1.5))
    finally:
        loop.close()
    assert not calls
    assert loop.time() == pytest.approx(1.5)


@pytest.mark.parametrize("seed", [1, 2])
def test_fallback_gives_the_same_callback_trace(monkeypatch: pytest.MonkeyPatch, seed: int) -> None:
    fast = _trace(EmulatorLoop, seed)
    _untested_python(monkeypatch)
    assert _trace(EmulatorLoop, seed) == fast


def test_fallback_gives_the_same_run_output(tmp_path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A scenario run on asyncio's own loop writes the same files, byte for byte, as on the fast path."""
    scn = load_test_scenario(SCENARIOS / "quickstart.yaml", {"duration_s": 5.0})
    s_fast = run_scenario(scn, tmp_path / "fast")
    _untested_python(monkeypatch)
    s_stock = run_scenario(scn, tmp_path / "stock")
    for name in ("capture.psnscap", "nav.csv", "truth.csv", "events.jsonl", "timeline.csv", "filter_state.csv"):
        assert (tmp_path / "fast" / name).read_bytes() == (tmp_path / "stock" / name).read_bytes(), name
    wall = {"wall_s", "realtime_factor", "run_dir"}
    assert {k: v for k, v in s_fast.items() if k not in wall} == {k: v for k, v in s_stock.items() if k not in wall}
    assert s_fast["nav_frames"] > 400


def test_fast_path_reports_a_callback_exception_as_asyncio_does() -> None:
    """The fast path runs handles inline (no ``Handle._run`` frame: performance.md 5.7, D-10.E10); a callback that
    raises reaches the exception handler with asyncio's message and context (the handle included), and the loop
    goes on."""
    def boom(x: int) -> None:
        raise ValueError(f"boom {x}")

    contexts = {}
    for cls in (_ReferenceLoop, EmulatorLoop):
        loop = cls("fast")
        seen: list[dict] = []
        loop.set_exception_handler(lambda _loop, ctx, seen=seen: seen.append(ctx))
        after: list[float] = []
        try:
            h = loop.call_at(0.1, boom, 7)
            loop.call_at(0.15, lambda after=after, loop=loop: after.append(loop.time()))
            loop.run_until_complete(asyncio.sleep(0.2))
        finally:
            loop.close()
        assert len(seen) == 1 and seen[0]["handle"] is h and after == [0.15]
        contexts[cls] = {k: (str(v) if k == "exception" else v) for k, v in seen[0].items() if k != "handle"}
    assert contexts[EmulatorLoop] == contexts[_ReferenceLoop]
    assert contexts[EmulatorLoop]["message"].startswith("Exception in callback ")


def test_timer_cancel_is_asyncios_cancel() -> None:
    """``_Timer.cancel`` (one frame instead of asyncio's three: D-10.E10) leaves the handle and the loop's count of
    cancelled scheduled timers as asyncio's ``TimerHandle.cancel`` does: once per scheduled timer, not for one
    already out of the heap, not twice; in debug mode asyncio's own (the repr kept)."""
    for cls in (_ReferenceLoop, EmulatorLoop):
        loop = cls("fast")
        try:
            a, b = loop.call_at(1.0, print, 1), loop.call_at(2.0, print, 2)
            b._scheduled = False  # as when the loop has popped it
            for h in (a, a, b):
                h.cancel()
            assert loop._timer_cancelled_count == 1
            assert a.cancelled() and b.cancelled() and a._callback is None and a._args is None
            c = loop.call_at(3.0, print, 3)  # made outside debug mode (a fast-path handle), cancelled in it
            loop.set_debug(True)
            c.cancel()
            assert c._repr is not None and loop._timer_cancelled_count == 2
            if cls is EmulatorLoop and loop.fast_path:
                assert type(c).cancel is not asyncio.TimerHandle.cancel  # the one-frame cancel was tested
        finally:
            loop.set_debug(False)
            loop.close()
