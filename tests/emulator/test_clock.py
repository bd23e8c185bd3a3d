"""Virtual time jumps when everything waits; realtime follows the wall clock."""

import asyncio
import time

import pytest

from emulator.clock import EmulatorLoop, sleep_until


def run(loop, coro):
    try:
        return loop.run_until_complete(coro)
    finally:
        loop.close()


def test_fast_mode_sixty_virtual_seconds_take_no_wall_time():
    loop = EmulatorLoop("fast")
    seen = []

    async def main():
        for k in range(1, 61):
            await sleep_until(float(k))
            seen.append(loop.time())

    t0 = time.perf_counter()
    run(loop, main())
    assert time.perf_counter() - t0 < 1.0
    assert seen == [float(k) for k in range(1, 61)]


def test_fast_mode_orders_timers_by_time():
    loop = EmulatorLoop("fast")
    order = []

    async def main():
        lp = asyncio.get_running_loop()
        for t in (0.3, 0.1, 0.2):
            lp.call_at(t, order.append, t)
        await asyncio.sleep(1.0)

    run(loop, main())
    assert order == [0.1, 0.2, 0.3]


@pytest.mark.realtime
def test_realtime_speed_scales_the_clock():
    loop = EmulatorLoop("realtime", speed=20.0)

    async def main():
        lp = asyncio.get_running_loop()
        t0w = time.perf_counter()
        await sleep_until(lp.time() + 1.0)  # one scenario second = 50 ms of wall time
        return time.perf_counter() - t0w

    wall = run(loop, main())
    assert 0.04 < wall < 0.5


@pytest.mark.realtime
def test_realtime_timer_sees_its_own_instant_behind_a_long_callback():
    """D-10.E12: the iteration's instant is read once, and the same reading decides which timers are due. A timer
    that falls due while a 2 ms callback that was already queued runs (the DSP tick after an IMU frame) runs after
    it, and its callback sees exactly its own instant -- not the moment it got to run."""
    loop = EmulatorLoop("realtime")
    seen: dict[str, float] = {}
    order: list[str] = []

    def busy():  # ready before the timer falls due; runs 2 ms
        order.append("busy")
        t_end = time.monotonic() + 0.002
        while time.monotonic() < t_end:
            pass

    def first():
        seen["first"] = loop.time()
        loop.call_soon(busy)

    def second():
        order.append("second")
        seen["second"] = loop.time()

    async def main():
        lp = asyncio.get_running_loop()
        t0 = lp.time() + 0.02
        lp.call_at(t0, first)
        lp.call_at(t0 + 0.0005, second)  # falls due while busy runs
        await asyncio.sleep(0.03)
        return t0

    t0 = run(loop, main())
    assert order == ["busy", "second"]
    assert seen == {"first": t0, "second": t0 + 0.0005}  # exactly: each callback at its own instant
