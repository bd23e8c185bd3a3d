"""The realtime loop computing ahead: a pty's bytes leave at their baud-timed instants although the loop is held up.

A :class:`~emulator.links.pty.PtyLink` at 460 800 baud (8N1) on a realtime loop sends a 109-byte frame every
10 ms (written in slices of 1 ms of wire time); a callback holds the loop (and the GIL) for 8 ms every 50 ms, as
the camera frame and the IMU look-ahead do. Each write to the pty is time-stamped as it happens; its lateness, in
the emulator's clock, is the scenario time of the write minus the scenario time at which the line model says the
slice's last stop bit ends. A reader (a thread) checks that the bytes arrive whole and in order. With the lead
(the paced writer) the hold-ups do not show; without it, the slices due during one leave when it ends.
(The reader's own wake-up on a loaded machine is left out: benchmarks/bench_pty_jitter.py measures it.)
"""

from __future__ import annotations

import os
import select
import statistics
import threading
import time
import tty

import pytest

from emulator.clock import EmulatorLoop
from emulator.links import LineConfig
from emulator.links.pty import PtyLink

pytestmark = [pytest.mark.pty, pytest.mark.realtime]

BAUD = 460800
N_FRAMES = 60
PERIOD_S = 0.01
HOLD_S = 0.008
HOLD_EVERY_S = 0.05
FRAME = 109


def _frame(k: int) -> bytes:
    return bytes([0xA5, k]) + bytes(FRAME - 2)


class _TimedPty(PtyLink):
    """A pty link that time-stamps every write it makes (CLOCK_MONOTONIC, bytes written so far)."""

    def __init__(self, *a, **kw) -> None:
        super().__init__(*a, **kw)
        self.writes: list[tuple[float, int]] = []
        self.written = 0

    def _write_out(self, data: bytes) -> tuple[int, int | None]:
        t = time.monotonic()
        n, err = super()._write_out(data)
        self.written += n
        self.writes.append((t, self.written))
        return n, err


def _steal_ticks() -> int | None:
    """The machine's CPU time stolen by the hypervisor so far (``/proc/stat``, the ``cpu`` line's 8th field, in
    clock ticks of 10 ms), None where there is no such file: on a virtual machine a vCPU the host does not run
    stalls every thread on it, the writer's too, whatever its priority."""
    try:
        with open("/proc/stat", encoding="ascii") as f:
            fields = f.readline().split()
        return int(fields[8])
    except (OSError, IndexError, ValueError):
        return None


def _lateness(tmp_path, lead_s: float, backend: str = "thread",
              info: dict | None = None) -> tuple[list[float], EmulatorLoop, _TimedPty, bytes]:
    """Lateness (ms, scenario time) of each slice's write against the end of its last stop bit; what a reader got.
    With the writer process (``backend="process"``) the child times its writes (``PacedWriter.on_late``).
    ``info`` (if given) receives the writer's summary (backend, policy) and the CPU time stolen during the run."""
    steal0 = _steal_ticks()
    loop = EmulatorLoop("realtime")
    hooked: list[float] = []
    if lead_s:
        loop.set_lead(lead_s, backend)
        assert loop.writer is not None
        loop.writer.on_late = lambda _owner, late_s: hooked.append(late_s * loop.speed * 1e3)
    link = _TimedPty("host", "pty://host", LineConfig(baud=BAUD), loop, target="host", run_dir=tmp_path / "ports")
    got = bytearray()
    stop = threading.Event()

    def reader(path: str) -> None:
        fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
        tty.setraw(fd)
        try:
            while not stop.is_set():
                r, _, _ = select.select([fd], [], [], 0.02)
                if r:
                    got.extend(os.read(fd, 65536))
        finally:
            os.close(fd)

    ends: list[tuple[float, int]] = []  # (scenario time at which a slice's last stop bit ends, bytes so far)

    def hold() -> None:
        t_end = time.monotonic() + HOLD_S
        while time.monotonic() < t_end:  # Python code holding the loop (and the GIL, as the interpreter allows)
            pass

    async def main() -> None:
        import asyncio

        await link.open()
        th = threading.Thread(target=reader, args=(str(link.link_path),), daemon=True)
        th.start()
        while not link.attached:
            await asyncio.sleep(0.005)
        t0 = loop.time() + 0.05
        for j in range(int(N_FRAMES * PERIOD_S / HOLD_EVERY_S) + 1):
            loop.call_at(t0 + 0.009 + j * HOLD_EVERY_S, hold)  # from just before a frame until after its end
        bt = link.line.byte_time

        def send(k: int) -> None:  # a device's frame, due at t0 + k * PERIOD_S (loop.time(): that instant)
            start = loop.time()
            link.send(_frame(k))
            for i in range(0, FRAME, link._slice_bytes):  # the slices the link writes (Link.send)
                n = min(FRAME, i + link._slice_bytes)
                ends.append((start + n * bt, k * FRAME + n))

        for k in range(N_FRAMES):
            loop.call_at(t0 + k * PERIOD_S, send, k)
        await asyncio.sleep(t0 + N_FRAMES * PERIOD_S - loop.time())
        await asyncio.sleep(0.05 + lead_s)
        await link.close()
        stop.set()
        th.join(2.0)

    try:
        loop.run_until_complete(main())
        if info is not None:
            steal1 = _steal_ticks()
            info["writer"] = loop.writer_summary()
            info["steal_ticks"] = None if steal0 is None or steal1 is None else steal1 - steal0
    finally:
        loop.close()
    if lead_s and backend == "process":
        assert not link.writes and len(hooked) == len(ends)  # one write per slice, all by the child
        return hooked, loop, link, bytes(got)
    assert [total for _t, total in link.writes] == [total for _e, total in ends]  # one write per slice
    late = [((t - loop._wall0) * loop.speed - end) * 1e3 for (t, _n), (end, _m) in zip(link.writes, ends)]
    return late, loop, link, bytes(got)


#: attempts of the on-time test; the first that meets the bounds ends it (see the test's comment)
ATTEMPTS = 3


@pytest.mark.parametrize("backend", ["thread", "process"])
def test_slices_leave_at_their_instants_while_the_loop_is_held_up(tmp_path, backend):
    # The bytes and their order are checked on every attempt; so is "never early". Timeliness is a property of the
    # machine as much as of the code: on this 2-core virtual machine a CI run had 31 of 180 slices late from the
    # process backend (2026-12-03) when 45 runs before had 0-2, a stall of about 100 ms that no priority inside the
    # guest can prevent (a vCPU the host does not run). So the timeliness bounds must hold on one of ATTEMPTS runs,
    # and a failure lists every attempt with its writer policy and the CPU time stolen meanwhile. A broken lead
    # still fails: without it every run has 36 of 180 slices late (next test).
    tries: list[dict] = []
    share = 0.05 if backend == "process" else 0.1
    for attempt in range(ATTEMPTS):
        info: dict = {}
        late, _loop, link, got = _lateness(tmp_path / f"lead{attempt}", 0.02, backend, info)
        assert got == b"".join(_frame(k) for k in range(N_FRAMES))  # whole, in order, nothing stale or lost
        assert link.stats.bytes_out == N_FRAMES * FRAME and link.stats.dropped_out == 0
        # never early: each slice is written once its last stop bit has ended (the scenario clock runs 20 ms ahead)
        assert min(late) >= 0.0
        n_late = sum(x > 3.0 for x in late)
        tries.append({"median_ms": round(statistics.median(late), 3), "over_3ms": n_late, "slices": len(late),
                      "max_ms": round(max(late), 2), "steal_ticks_10ms": info.get("steal_ticks"),
                      "policy": (info.get("writer") or {}).get("policy"),
                      "writing": (info.get("writer") or {}).get("writing")})
        # on time although the loop was held for 8 ms every 50 ms: without the lead a fifth of the slices are 3-8 ms
        # late (next test: 36 of 180 on every run). The process backend writes from its own interpreter: under 5 %.
        # The thread backend (the fallback) must take the GIL from the held loop and wake from its timed wait: on
        # this 2-core machine 0-12 of 180 slices were over 3 ms late (45 quiet runs and a CI run, 2026-12-03; fewer
        # with the other core busy), so it must at least halve the hold-ups' share (under 10 %)
        if statistics.median(late) < 0.3 and n_late < share * len(late):
            return
    pytest.fail(f"{backend} backend: late on each of {ATTEMPTS} attempts (bounds: median < 0.3 ms, under "
                f"{share:.0%} of the slices over 3 ms): {tries}")


def test_without_the_lead_the_same_hold_ups_delay_the_slices(tmp_path):
    late, _loop, _link, got = _lateness(tmp_path / "nolead", 0.0)
    assert got == b"".join(_frame(k) for k in range(N_FRAMES))
    # the slices due while the loop was held leave when it lets go: the hold-up shows (what the lead removes)
    assert sum(x > 3.0 for x in late) > 0.1 * len(late), late


def test_bytes_handed_over_for_a_peer_that_left_are_not_written_to_the_next():
    import asyncio

    from emulator.links.base import Link

    class _Rec(Link):
        scheme = "rec"
        deferred_write = True

        def __init__(self, *a) -> None:
            super().__init__(*a)
            self.out: list[bytes] = []

        def _write_raw(self, data: bytes) -> None:
            self._hand_over(data)

        def _write_out(self, data: bytes) -> tuple[int, int | None]:
            self.out.append(data)
            return len(data), None

    loop = EmulatorLoop("realtime")
    loop.set_lead(0.02)
    link = _Rec("r", "rec://r", LineConfig(baud=BAUD), loop)

    def peer_leaves() -> None:  # what PtyLink._detach does, between the hand-over and the bytes' instant
        link.peer_epoch += 1

    async def main() -> None:
        link.send(b"old")
        end = link.busy_until()
        loop.call_at(end + 0.001, peer_leaves)  # 1 ms after the hand-over: 19 ms before the bytes are due
        await asyncio.sleep(end + 0.002 - loop.time())
        link.send(b"new")
        await asyncio.sleep(0.03 + 0.02)

    try:
        loop.run_until_complete(main())
    finally:
        loop.close()
    assert link.out == [b"new"]
    assert link.stats.no_peer_out == 3 and link.stats.bytes_out == 6 and link.stats.dropped_out == 0
