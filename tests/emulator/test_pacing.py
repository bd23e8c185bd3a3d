"""The paced writer's process backend (emulator/pacing.py) and its place behind
:class:`emulator.paced_writer.PacedWriter`.

A real child process writes to real descriptors (pipes, a pty with a reader process); deadlines are
``CLOCK_MONOTONIC`` instants a few ms ahead, lateness is what the child measured after each ``os.write``
(asserted generously: a loaded 2-core CI machine).
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import select
import signal
import statistics
import subprocess
import sys
import time

import pytest

from emulator.clock import EmulatorLoop
from emulator.errors import EmulatorError, LinkConfigError, WriterProcessError
from emulator.links import LineConfig
from emulator.links.base import Link
from emulator.paced_writer import WRITER_ENV, PacedWriter, default_writer_backend
from emulator.pacing import (
    DATA,
    DRAINED,
    DROPPED,
    FLUSH,
    OPEN,
    RECORD,
    STARTED,
    WROTE,
    WriterProcess,
)

pytestmark = pytest.mark.skipif(not sys.platform.startswith("linux"), reason="the writer process is Linux's")


class _Peer:
    """What a link gives the writer (:class:`emulator.pacing.PacedPeer`), writing to a pipe; records the outcomes
    reported back (epoch, size, written, errno)."""

    def __init__(self, fd: int) -> None:
        self.fd = fd
        self.peer_epoch = 0
        self.reports: list[tuple[int, int, int, int | None]] = []
        self.thread_writes: list[bytes] = []

    def peer_fd(self) -> int | None:
        return self.fd

    def _write_deferred(self, item: tuple[int, bytes]) -> None:  # the thread backend's call
        self.thread_writes.append(item[1])
        os.write(self.fd, item[1])

    def _report_deferred(self, epoch: int, size: int, written: int, err: int | None) -> None:
        self.reports.append((epoch, size, written, err))


def _read_all(fd: int, timeout: float = 0.2) -> bytes:
    """What the pipe holds (waiting up to ``timeout`` s for more after each read)."""
    out = bytearray()
    while select.select([fd], [], [], timeout)[0]:
        chunk = os.read(fd, 65536)
        if not chunk:
            break
        out += chunk
    return bytes(out)


def _wait(cond, timeout: float = 5.0) -> bool:
    t_end = time.monotonic() + timeout
    while not cond():
        if time.monotonic() > t_end:
            return False
        time.sleep(0.005)
    return True


@pytest.fixture
def pipe():
    r, w = os.pipe()
    os.set_blocking(w, False)
    yield r, w
    for fd in (r, w):
        with contextlib.suppress(OSError):
            os.close(fd)


@pytest.fixture
def wp():
    """A writer process, closed after the test."""
    writer = WriterProcess()
    yield writer
    writer.close()


def test_the_record_layout_round_trips():
    assert RECORD.size == 24
    cases = [
        (DATA, 0, 0, 0, 0, 0, 0),
        (DATA, 0, 0xFFFF, 0xFFFFFFFF, 2**63 - 1, 2**32 - 1, 0),  # the extremes of each field
        (WROTE, 5, 3, 7, -1_500, 109, 46),  # lateness may be negative in principle (i64)
        (FLUSH, 0, 1, 2, 0, 0, 0), (OPEN, 0, 2, 0, 0, 0, 0), (DROPPED, 0, 1, 1, 0, 327, 3),
        (DRAINED, 0, 1, 0, 0, 0, 0), (STARTED, 1, 0, 0, 0, 0, 4242),
    ]
    for rec in cases:
        assert RECORD.unpack(RECORD.pack(*rec)) == rec
    # little-endian, in the declared order: kind, err, slot, epoch, t_ns, size, count
    raw = RECORD.pack(DATA, 0, 0x0102, 0x03040506, 0x0708090A0B0C0D0E, 0x0F101112, 0x13141516)
    assert raw == bytes([1, 0, 2, 1, 6, 5, 4, 3, 14, 13, 12, 11, 10, 9, 8, 7, 0x12, 0x11, 0x10, 0x0F,
                         0x16, 0x15, 0x14, 0x13])


def test_the_child_writes_the_bytes_in_order_at_their_instants(pipe):
    r, w = pipe
    late: list[tuple[object, float]] = []
    wp = WriterProcess(on_late=lambda owner, s: late.append((owner, s)))
    try:
        assert wp.policy is not None  # reported at start-up: SCHED_FIFO 1 as root, else SCHED_OTHER and why
        peer = _Peer(w)
        payloads = [bytes([k]) * (1 + k % 7) for k in range(60)]
        t0 = time.monotonic() + 0.03
        for k, p in enumerate(payloads):
            wp.put(t0 + k * 0.002, peer, p, w)
        assert wp.drain(peer, timeout=5.0)
        assert _read_all(r) == b"".join(payloads)  # byte-identical, in order
        assert wp.pending() == 0 and wp.writes == len(payloads) and not peer.reports  # nothing lost
        assert len(late) == len(payloads) and all(o is peer for o, _s in late)
        lat_ms = [s * 1e3 for _o, s in late]
        assert min(lat_ms) >= 0.0  # never before its instant
        assert statistics.median(lat_ms) < 1.0, lat_ms  # typically 0.03-0.1 ms; generous for a busy CI machine
    finally:
        wp.close()
    assert wp.proc.returncode == 0


def test_a_long_chunk_goes_as_several_records(pipe, wp):
    r, w = pipe
    peer = _Peer(w)
    data = bytes(range(256)) * 200  # 51 200 B > MAX_PAYLOAD; fits the pipe's 64 KiB
    wp.put(time.monotonic(), peer, data, w)
    assert wp.drain(peer)
    assert _read_all(r) == data and not peer.reports


def test_a_flush_drops_what_is_queued_for_the_peer_that_left(pipe, wp):
    r, w = pipe
    peer = _Peer(w)
    t0 = time.monotonic() + 0.3
    for k in range(5):
        wp.put(t0 + k * 0.001, peer, b"old%d" % k, w)
    peer.peer_epoch += 1  # the peer went away (a pty's detach) ...
    wp.flush(peer)  # ... the link tells the writer, in order with the data
    wp.put(t0 + 0.01, peer, b"new", w)
    assert wp.drain(peer)
    assert _read_all(r) == b"new"
    assert peer.reports == [(0, 20, 0, None)]  # the old epoch's 5 items, 20 bytes: unheard (no_peer_out)
    assert wp.pending() == 0


def test_drain_waits_for_the_writes_and_lets_go_of_the_descriptor(pipe, wp):
    r, w = pipe
    peer = _Peer(w)
    t0 = time.monotonic()
    wp.put(t0 + 0.15, peer, b"abc", w)
    assert wp.pending(peer) == 1
    assert wp.drain(peer, timeout=5.0)
    assert time.monotonic() - t0 >= 0.15  # not before the item's instant
    assert os.read(r, 10) == b"abc"
    os.close(w)  # the link closes its descriptor: the child's copy is closed already, so the reader sees EOF
    assert select.select([r], [], [], 2.0)[0] and os.read(r, 10) == b""
    # a later put sends the descriptor again (a link that writes after a drain)
    r2, w2 = os.pipe()
    peer.fd = w2
    wp.put(time.monotonic(), peer, b"again", w2)
    assert wp.drain(peer) and os.read(r2, 10) == b"again"
    os.close(r2)
    os.close(w2)


def test_a_write_that_fails_is_reported_with_its_errno(pipe, wp):
    r, w = pipe
    peer = _Peer(w)
    os.close(r)  # no reader: EPIPE
    wp.put(time.monotonic(), peer, b"xyz", w)
    assert wp.drain(peer)
    assert _wait(lambda: len(peer.reports) == 1)
    assert peer.reports == [(0, 3, 0, 32)]  # errno 32: EPIPE (the child ignores SIGPIPE as Python does)
    assert wp.failures == 1


def test_a_full_peer_buffer_is_a_short_write_not_an_error(pipe, wp):
    r, w = pipe
    peer = _Peer(w)
    big = b"z" * (1 << 20)  # more than the pipe holds: the non-blocking write takes what fits
    wp.put(time.monotonic(), peer, big, w)
    assert wp.drain(peer)
    assert _wait(lambda: bool(peer.reports))
    written = len(_read_all(r, 0.05))
    assert 0 < written < len(big)
    lost = sum(size - wr for _e, size, wr, _err in peer.reports)
    assert written + lost == len(big) and all(err is None for *_x, err in peer.reports)


def test_a_killed_child_is_an_error_and_the_thread_takes_over(pipe):
    r, w = pipe
    pw = PacedWriter("process")
    try:
        wp = pw.process
        assert wp is not None
        peer = _Peer(w)
        pw.put_bytes(time.monotonic() + 10.0, peer, b"lost!")  # far ahead: still queued in the child
        assert _wait(lambda: wp.pending(peer) == 1)
        os.kill(wp.pid, signal.SIGKILL)
        assert _wait(lambda: pw.error is not None)
        assert isinstance(pw.error, WriterProcessError) and isinstance(pw.error, EmulatorError)
        assert f"pid {wp.pid}" in str(pw.error) and "5 bytes" in str(pw.error)
        assert pw.process is None and pw.last_error == str(pw.error)
        assert peer.reports == [(0, 5, 0, None)]  # counted as lost on the line (dropped_out), not silently gone
        t = time.monotonic()
        assert pw.drain(peer, timeout=5.0) and time.monotonic() - t < 1.0  # no hang
        pw.put_bytes(time.monotonic() + 0.01, peer, b"thread")  # the fallback
        assert pw.drain(peer, timeout=5.0)
        assert peer.thread_writes == [b"thread"] and _read_all(r) == b"thread"
    finally:
        pw.close()


def test_ctrl_c_leaves_the_child_to_the_parent(pipe):
    r, w = pipe
    wp = WriterProcess()
    try:
        os.kill(wp.pid, signal.SIGINT)  # what a terminal's Ctrl-C sends the whole process group
        time.sleep(0.2)
        assert wp.proc.poll() is None and wp.alive
        peer = _Peer(w)
        wp.put(time.monotonic(), peer, b"still here", w)
        assert wp.drain(peer) and _read_all(r) == b"still here"
    finally:
        wp.close()
    assert wp.proc.returncode == 0


def test_end_of_file_on_its_input_makes_the_child_write_what_it_holds_and_exit(pipe):
    r, w = pipe
    wp = WriterProcess()
    peer = _Peer(w)
    t0 = time.monotonic()
    wp.put(t0 + 0.1, peer, b"last", w)
    wp.close()  # shuts its input down; the child writes at the instant, then exits
    assert wp.proc.returncode == 0 and time.monotonic() - t0 >= 0.1
    assert _read_all(r) == b"last"


def test_the_backend_is_chosen_by_argument_environment_or_platform(monkeypatch):
    monkeypatch.delenv(WRITER_ENV, raising=False)
    assert default_writer_backend() == "process"  # Linux (the module is skipped elsewhere)
    monkeypatch.setattr(sys, "platform", "darwin")
    assert default_writer_backend() == "thread"
    monkeypatch.setenv(WRITER_ENV, "thread")
    assert default_writer_backend() == "thread"
    monkeypatch.setenv(WRITER_ENV, "bogus")
    with pytest.raises(LinkConfigError, match=WRITER_ENV):  # a ValueError too
        default_writer_backend()
    with pytest.raises(ValueError):
        PacedWriter("fork")
    w = PacedWriter("thread")
    try:
        assert w.process is None and w.backend == "thread"
    finally:
        w.close()


class _PipeLink(Link):
    """A link whose peer is the write end of a pipe (what a pty master is to the writer)."""

    scheme = "pipe"
    deferred_write = True

    def __init__(self, *a, fd: int) -> None:
        super().__init__(*a)
        self.fd = fd

    def peer_fd(self) -> int | None:
        return self.fd

    def _write_raw(self, data: bytes) -> None:
        self._hand_over(data)

    def _write_out(self, data: bytes) -> tuple[int, int | None]:  # the thread backend's write
        return os.write(self.fd, data), None


def test_a_link_whose_peer_left_counts_the_flushed_bytes_as_unheard(pipe):
    """Link._hand_over -> the child; Link._peer_gone -> FLUSH; the DROPPED report -> no_peer_out, in the loop."""
    r, w = pipe
    loop = EmulatorLoop("realtime")
    loop.set_lead(0.02, "process")
    assert loop.writer is not None and loop.writer.process is not None
    link = _PipeLink("p", "pipe://p", LineConfig(baud=460800), loop, fd=w)

    async def main() -> None:
        link.send(b"old")
        end = link.busy_until()
        loop.call_at(end + 0.001, link._peer_gone)  # 19 ms before the bytes are due
        await asyncio.sleep(end + 0.002 - loop.time())
        link.send(b"new")
        await asyncio.sleep(0.05)
        link._drain_writes()
        await asyncio.sleep(0.01)  # the reports' callbacks (call_soon_threadsafe) run

    try:
        loop.run_until_complete(main())
    finally:
        loop.close()
    assert _read_all(r) == b"new"
    assert link.stats.no_peer_out == 3 and link.stats.bytes_out == 6 and link.stats.dropped_out == 0


_PTY_READER = r"""
import os, select, sys, time, tty
fd = os.open(sys.argv[1], os.O_RDWR | os.O_NOCTTY)
tty.setraw(fd)
print("ready", flush=True)
got = bytearray()
while len(got) < int(sys.argv[2]):
    if not select.select([fd], [], [], 5.0)[0]:
        break
    got += os.read(fd, 65536)
sys.stdout.write(got.hex() + "\n")
"""


@pytest.mark.pty
@pytest.mark.realtime
def test_a_pty_read_by_another_process_gets_the_bytes_whole_and_on_time(tmp_path):
    from emulator.links.pty import PtyLink

    n_frames, period, frame_len = 40, 0.01, 109
    frames = [bytes([0xA5, k]) + bytes(range(frame_len - 2)) for k in range(n_frames)]
    loop = EmulatorLoop("realtime")
    loop.set_lead(0.02, "process")
    w = loop.writer
    assert w is not None and w.process is not None
    late: list[float] = []
    w.on_late = lambda _owner, s: late.append(s * 1e3)
    link = PtyLink("host", "pty://host", LineConfig(baud=460800), loop, target="host", run_dir=tmp_path / "ports")
    out: list[str] = []

    async def main() -> None:
        await link.open()
        proc = await asyncio.create_subprocess_exec(sys.executable, "-c", _PTY_READER, str(link.link_path),
                                                    str(n_frames * frame_len), stdout=subprocess.PIPE)
        assert proc.stdout is not None
        await proc.stdout.readline()
        while not link.attached:
            await asyncio.sleep(0.005)
        t0 = loop.time() + 0.05
        for k, f in enumerate(frames):
            loop.call_at(t0 + k * period, link.send, f)
        await asyncio.sleep(t0 + n_frames * period + 0.05 - loop.time())
        text, _ = await proc.communicate()
        out.append(text.decode().strip())
        await link.close()

    try:
        loop.run_until_complete(main())
    finally:
        loop.close()
    assert bytes.fromhex(out[0]) == b"".join(frames)  # byte-identical and in order
    assert link.stats.dropped_out == 0 and link.stats.no_peer_out == 0
    assert len(late) == n_frames * 3  # 109 B at 460 800 baud in 1 ms slices: 3 writes a frame, all by the child
    assert min(late) >= 0.0 and statistics.median(late) < 1.0, late
