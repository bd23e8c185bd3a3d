"""The fast-mode loop's batched iterations run callbacks exactly as asyncio's own iteration does.

:meth:`emulator.clock.EmulatorLoop._run_fast` replaces ``asyncio.BaseEventLoop._run_once`` in fast
mode for speed (issue 10), and its ``call_at`` builds lighter timer handles. The reference here is the
same loop class with both switched off (asyncio's ``_run_once`` and ``call_at``): a random workload of timers (ties at the
same instant, cancellations, callbacks that schedule more callbacks, ``call_soon`` chains, a
coroutine sleeping) must give the identical trace of (virtual time, callback id), in order.
"""

from __future__ import annotations

import asyncio

import numpy as np
import pytest

from emulator.clock import EmulatorLoop


class _ReferenceLoop(EmulatorLoop):
    """asyncio's own iteration and asyncio's own timer handles."""

    def _run_once(self) -> None:
        self._cap = None
        asyncio.SelectorEventLoop._run_once(self)  # type: ignore[attr-defined]

    def call_at(self, when, callback, *args, context=None):  # type: ignore[override]
        return asyncio.SelectorEventLoop.call_at(self, when, callback, *args, context=context)


def _trace(loop_cls: type, seed: int) -> list[tuple[float, int]]:
    loop = loop_cls("fast")
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
                    loop.call_soon(cb, counter[0], depth + 1)
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
        for i in range(300):
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


def test_fast_path_is_taken() -> None:
    """The batched path really runs (else the test above compares asyncio with itself)."""
    calls = []

    class Probe(EmulatorLoop):
        def _run_fast(self, sel):  # type: ignore[override]
            calls.append(1)
            return super()._run_fast(sel)

    loop = Probe("fast")
    try:
        for i in range(100):
            loop.call_at(i * 0.01, lambda: None)
        loop.run_until_complete(asyncio.sleep(1.5))
    finally:
        loop.close()
    assert calls
    assert loop.time() == pytest.approx(1.5)
