"""The realtime loop's lead, the paced writer and the timer slack (emulator/clock.py)."""

from __future__ import annotations

import asyncio
import statistics
import sys
import threading
import time
from pathlib import Path

import pytest

from emulator.assembly.session import REALTIME_LEAD_S, realtime_lead_s
from emulator.clock import TIMER_SLACK_NS, EmulatorLoop, set_timer_slack
from emulator.paced_writer import PacedWriter

LINUX = sys.platform.startswith("linux")
_SLACK = Path("/proc/self/timerslack_ns")  # the main thread's slack (the thread the tests run in)


def _slack_ns() -> int:
    return int(_SLACK.read_text())


@pytest.mark.skipif(not LINUX or not _SLACK.exists(),
                    reason="PR_SET_TIMERSLACK and /proc/PID/timerslack_ns are Linux's")
def test_realtime_loop_lowers_the_timer_slack_and_fast_mode_leaves_it():
    before = set_timer_slack(50_000)  # the kernel's default, whatever an earlier test set
    assert before == 50_000 == _slack_ns()
    fast = EmulatorLoop("fast")
    try:
        assert fast.timer_slack_ns is None and _slack_ns() == 50_000
    finally:
        fast.close()
    loop = EmulatorLoop("realtime")
    try:
        assert loop.timer_slack_ns == TIMER_SLACK_NS == _slack_ns()  # read back through /proc, not the call
    finally:
        loop.close()
        set_timer_slack(50_000)


def test_timer_slack_is_a_no_op_off_linux(monkeypatch):
    monkeypatch.setattr(sys, "platform", "darwin")
    assert set_timer_slack() is None


def _writer_run(n: int, step_s: float, hold_s: float = 0.0) -> tuple[list[float], list[int]]:
    """Put ``n`` writes ``step_s`` apart; return their lateness (ms) and the order they were written in."""
    w = PacedWriter("thread")
    late: list[float] = []
    order: list[int] = []
    t0 = time.monotonic() + 0.02
    for k in range(n):
        at = t0 + k * step_s

        def write(data: bytes, at: float = at) -> None:
            late.append((time.monotonic() - at) * 1e3)
            order.append(data[0])

        w.put(at, write, bytes([k]), owner="a")
    if hold_s:  # the putting thread busy in Python code meanwhile (the GIL)
        end = time.monotonic() + hold_s
        while time.monotonic() < end:
            pass
    assert w.drain("a", timeout=5.0)
    w.close()
    return late, order


@pytest.mark.realtime  # wall-clock lateness: its own CI step, not beside `make test`'s xdist workers
def test_writer_writes_in_order_at_the_instants():
    late, order = _writer_run(40, 0.002)
    assert order == list(range(40))
    assert min(late) >= 0.0  # never before its instant
    assert statistics.median(late) < 0.5


@pytest.mark.realtime  # wall-clock lateness: its own CI step, not beside `make test`'s xdist workers
def test_writer_gets_the_gil_from_a_busy_thread():
    switch0 = sys.getswitchinterval()
    late, order = _writer_run(40, 0.002, hold_s=0.1)  # every write falls while this thread runs Python
    assert order == list(range(40))
    # the lowered switch interval (0.2 ms instead of 5 ms) bounds the wait for the GIL; tolerance for a loaded CI
    assert statistics.median(late) < 1.0, late
    assert sys.getswitchinterval() == switch0  # restored by close()


def test_writer_drain_pending_and_a_failing_write():
    w = PacedWriter("thread")
    got: list[bytes] = []

    def bad(_data: bytes) -> None:
        raise OSError("gone")

    now = time.monotonic()
    w.put(now + 0.03, got.append, b"a", owner="x")
    w.put(now + 0.03, bad, b"b", owner="y")
    w.put(now + 0.04, got.append, b"c", owner="x")
    assert w.pending() == 3 and w.pending("x") == 2
    assert w.drain("x", timeout=5.0)
    assert got == [b"a", b"c"] and w.pending() == 0
    assert w.failures == 1 and "gone" in (w.last_error or "") and w.writes == 3
    w.close()
    assert not any(t.name == "psns-paced-writer" for t in threading.enumerate())


def test_lead_runs_the_clock_ahead_and_maps_scenario_time_to_the_wall():
    with pytest.raises(ValueError):
        EmulatorLoop("fast").set_lead(0.02)
    loop = EmulatorLoop("realtime", speed=2.0)
    try:
        loop.set_lead(0.02)
        assert isinstance(loop.writer, PacedWriter)

        async def main() -> float:
            return loop.time() - (time.monotonic() - loop._wall0) * loop.speed

        ahead = loop.run_until_complete(main())
        assert ahead == pytest.approx(0.02 * 2.0, abs=2e-3)  # the lead is wall s: 40 ms of scenario time at x2
        assert loop.wall_at(3.0) == pytest.approx(loop._wall0 + 1.5)
        loop.set_lead(0.0)
        assert loop.writer is None and loop.lead_s == 0.0
    finally:
        loop.close()


class _L:
    def __init__(self, scheme: str, deferred: bool) -> None:
        self.scheme = scheme
        self.deferred_write = deferred


def test_the_lead_is_taken_only_when_every_real_port_writes_through_the_writer():
    from emulator.links.mem import MemLink
    from emulator.links.pty import PtyLink
    from emulator.links.serial import SerialLink
    from emulator.links.zenoh import ZenohLink

    assert PtyLink.deferred_write and SerialLink.deferred_write and not ZenohLink.deferred_write
    assert not MemLink.deferred_write
    assert realtime_lead_s([_L("mem", False), _L("pty", True), _L("serial", True)]) == REALTIME_LEAD_S > 0
    assert realtime_lead_s([_L("mem", False), _L("pty", True), _L("zenoh", False)]) == 0.0
    assert realtime_lead_s([_L("can", False)]) == 0.0
    assert realtime_lead_s([_L("mem", False), _L("mem", False)]) == 0.0  # nobody outside to be on time for


@pytest.mark.realtime
def test_a_realtime_loop_with_a_lead_closes_its_writer():
    loop = EmulatorLoop("realtime")
    loop.set_lead(0.01)
    w = loop.writer
    assert w is not None
    got: list[bytes] = []

    async def main() -> None:
        w.put(loop.wall_at(loop.time()), got.append, b"z", owner="o")
        await asyncio.sleep(0.0)

    loop.run_until_complete(main())
    loop.close()  # writes what it holds, then stops the thread
    assert got == [b"z"] and loop.writer is None
