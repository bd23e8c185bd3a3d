"""One conformance suite that every link transport passes.

``check_link_pair(make_pair, mode)`` runs every check on a fresh :class:`EmulatorLoop`.
``make_pair(loop, line_a, line_b)`` is an async factory returning ``(a, b, cleanup)``: two
opened link ends joined by the transport under test (bytes sent on ``a`` reach ``b`` and back),
ready to carry data, and an async ``cleanup()``. All waits use the emulator's clock.

Checks (each names what a transport must do):

* integrity: chunks of 1..2000 bytes (seeded random content) arrive complete, in order, in both
  directions; the byte counters of both ends agree and nothing is dropped;
* pacing: a chunk is not delivered before its last stop bit has left (``n * bits / baud`` after
  it was sent), and not unreasonably later;
* overflow: a burst far beyond a small TX queue on a slow line keeps the queue's worth, counts
  the rest as dropped, and the far end receives exactly what was kept;
* listeners: a tap on each end sees the ``out`` and ``in`` chunks with non-decreasing times;
* close: a closed end accepts nothing and the far end receives nothing more.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import Awaitable, Callable

import numpy as np

from emulator.clock import EmulatorLoop
from emulator.links import LineConfig, Link

MakePair = Callable[[EmulatorLoop, LineConfig, LineConfig], Awaitable[tuple[Link, Link, Callable[[], Awaitable[None]]]]]


class _Rx:
    """Collects what a link end delivers to its device, with times."""

    def __init__(self, link: Link) -> None:
        self.data = bytearray()
        self.times: list[float] = []
        self.link = link
        self.changed = asyncio.Event()
        link.on_receive = self._on

    def _on(self, data: bytes) -> None:
        self.data += data
        self.times.append(self.link.loop.time())
        self.changed.set()

    async def wait_len(self, n: int, timeout: float) -> None:
        loop = asyncio.get_running_loop()
        deadline = loop.time() + timeout
        while len(self.data) < n:
            left = deadline - loop.time()
            if left <= 0:
                raise AssertionError(f"{self.link.name}: got {len(self.data)} of {n} bytes within {timeout} s")
            self.changed.clear()
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(self.changed.wait(), left)


class _Tap:
    def __init__(self) -> None:
        self.seen: list[tuple[str, str, float, int]] = []

    def on_link_bytes(self, link: Link, direction: str, t: float, data: bytes) -> None:
        self.seen.append((link.name, direction, t, len(data)))


async def _integrity(make_pair: MakePair, rng: np.random.Generator, slack: float) -> None:
    line = LineConfig(baud=460800)
    a, b, cleanup = await make_pair(asyncio.get_running_loop(), line, line)
    try:
        ra, rb = _Rx(a), _Rx(b)
        ta, tb = _Tap(), _Tap()
        a.listeners.append(ta)
        b.listeners.append(tb)
        sizes = [1, 7, 40, 109, 300, 2000]
        sent_ab = bytearray()
        sent_ba = bytearray()
        for n in sizes:
            chunk = rng.integers(0, 256, n, dtype=np.uint8).tobytes()
            assert a.send(chunk) == n
            sent_ab += chunk
            back = rng.integers(0, 256, n, dtype=np.uint8).tobytes()
            assert b.send(back) == n
            sent_ba += back
        total_time = len(sent_ab) * line.byte_time
        await rb.wait_len(len(sent_ab), 2 * total_time + slack)
        await ra.wait_len(len(sent_ba), 2 * total_time + slack)
        assert bytes(rb.data) == bytes(sent_ab), "a -> b bytes differ"
        assert bytes(ra.data) == bytes(sent_ba), "b -> a bytes differ"
        for x in (a, b):
            assert x.stats.dropped == 0, f"{x.name}: dropped {x.stats.dropped}"
            assert x.stats.framing_errors == 0
        assert a.stats.bytes_out == b.stats.bytes_in == len(sent_ab)
        assert b.stats.bytes_out == a.stats.bytes_in == len(sent_ba)
        # listeners: both directions tapped, times non-decreasing per direction
        for tap, name in ((ta, a.name), (tb, b.name)):
            for d in ("out", "in"):
                ts = [t for (nm, dd, t, _n) in tap.seen if dd == d and nm == name]
                assert ts, f"{name}: listener saw no {d!r} chunks"
                assert ts == sorted(ts), f"{name}: {d!r} chunk times go backwards"
            assert sum(n for (_nm, dd, _t, n) in tap.seen if dd == "out") == (
                len(sent_ab) if tap is ta else len(sent_ba))
    finally:
        await cleanup()


async def _pacing(make_pair: MakePair, slack: float) -> None:
    line = LineConfig(baud=115200)
    a, b, cleanup = await make_pair(asyncio.get_running_loop(), line, line)
    try:
        rb = _Rx(b)
        loop = asyncio.get_running_loop()
        n = 1000
        t0 = loop.time()
        assert a.send(bytes(range(256)) * 3 + bytes(232)) == n
        wire = n * line.byte_time  # 86.8 ms at 115200 8N1
        await rb.wait_len(n, 2 * wire + slack)
        assert rb.times[-1] - t0 >= wire * (1 - 1e-9), (
            f"delivered after {rb.times[-1] - t0:.6f} s, the line needs {wire:.6f} s")
        assert rb.times[-1] - t0 <= 2 * wire + slack
        # the first piece cannot arrive before its own bytes have crossed the line
        first_len = len(rb.data) if len(rb.times) == 1 else None
        assert rb.times[0] - t0 >= (first_len or 1) * line.byte_time * (1 - 1e-9)
    finally:
        await cleanup()


async def _overflow(make_pair: MakePair, slack: float) -> None:
    slow = LineConfig(baud=9600, tx_queue_bytes=256)
    a, b, cleanup = await make_pair(asyncio.get_running_loop(), slow, slow)
    try:
        rb = _Rx(b)
        offered = 0
        accepted = 0
        for _ in range(20):
            accepted += a.send(b"\x55" * 100)
            offered += 100
        assert accepted == 256, f"a 256-byte queue kept {accepted} bytes"
        assert a.stats.dropped_out == offered - accepted
        await rb.wait_len(accepted, 2 * accepted * slow.byte_time + slack)
        await asyncio.sleep(0.05)
        assert len(rb.data) == accepted, "the far end must get exactly what the queue kept"
        # the queue drains: after the line is idle, a new chunk is accepted whole
        await asyncio.sleep(max(0.0, a.busy_until() - asyncio.get_running_loop().time()) + 0.001)
        assert a.send(b"\xaa" * 100) == 100
    finally:
        await cleanup()


async def _close(make_pair: MakePair, slack: float) -> None:
    line = LineConfig(baud=460800)
    a, b, cleanup = await make_pair(asyncio.get_running_loop(), line, line)
    try:
        rb = _Rx(b)
        assert a.send(b"hello") == 5
        await rb.wait_len(5, slack + 0.01)
        await a.close()
        assert a.send(b"more") == 0
        await asyncio.sleep(0.05 + slack / 4)
        assert bytes(rb.data) == b"hello"
    finally:
        await cleanup()


def check_link_pair(make_pair: MakePair, mode: str = "fast", seed: int = 7) -> None:
    """Run every conformance check for one transport (see module docstring).

    ``mode``: ``fast`` for in-process transports, ``realtime`` for transports with real file
    descriptors (their bytes move in wall time, so virtual time must not run ahead of them).
    """
    slack = 0.0 if mode == "fast" else 1.0
    for check in (_integrity, _pacing, _overflow, _close):
        loop = EmulatorLoop(mode)
        try:
            if check is _integrity:
                loop.run_until_complete(check(make_pair, np.random.default_rng(seed), slack))
            else:
                loop.run_until_complete(check(make_pair, slack))
        finally:
            loop.close()
