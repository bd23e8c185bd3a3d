"""Writing to real peers at their instants: the OS helpers and the paced writer's process backend.

The realtime loop computing ahead (:meth:`emulator.clock.EmulatorLoop.set_lead`, docs/decisions/performance.md
D-10.E6) hands each chunk for a real peer to :class:`emulator.paced_writer.PacedWriter`, which writes it at the
``CLOCK_MONOTONIC`` instant its scenario time stands for. Its thread backend shares the interpreter (the GIL) with
the loop, busy in Python and numpy: woken on time, it may still wait for the lock (D-10.E11). This module holds the
other backend, a **writer process**: a small child (``python -m emulator.pacing``, importing only this module and
:mod:`emulator.errors`) that owns a duplicate of each link's file descriptor (a pty master, a serial device) and
sleeps, with its own interpreter, until each record's deadline.

Parent and child talk over one ``AF_UNIX`` ``SOCK_SEQPACKET`` socket pair (message boundaries kept; a descriptor
travels with its ``OPEN`` record, ``SCM_RIGHTS``). Every message is one or more :data:`RECORD` s (a ``DATA``
record's payload follows it in the same message). The child

* queues ``DATA`` records (deadline order: the loop puts them in scenario-time order), and ``select`` s on its
  input with the time to the next deadline as timeout (microsecond resolution, timer slack
  :data:`TIMER_SLACK_NS`, ``SCHED_FIFO`` where allowed), so new records are read while it waits;
* writes each payload with ``os.write`` on the non-blocking descriptor: a short write, ``EAGAIN`` (counted as 0
  bytes written) or an error (``EIO``: the pty's peer left) is reported, never retried -- the link counts the
  rest as lost (``Link._after_write``), exactly as with the thread backend;
* on ``FLUSH`` (the link's peer went away: its ``peer_epoch`` moved on) drops the slot's queued items of earlier
  epochs and reports their bytes (``DROPPED``: counted as unheard, ``no_peer_out``); the record travels in the
  same stream as the data, so what was put before the peer left is what is dropped;
* on ``DRAIN`` writes the slot's queued items at their instants, closes its copy of the descriptor (so closing the
  link really hangs up the pty) and answers ``DRAINED``;
* reports every write (``WROTE``: bytes written, errno, lateness against its deadline, ns) in batches, at once
  after a failure, and exits on end of file on its input once its queue is written.

The parent side, :class:`WriterProcess`, sends the records from the loop's thread and reads the reports in a
thread of its own (not time-critical: the lateness samples and the losses reach the links a few ms late). When
the child dies, :class:`~emulator.errors.WriterProcessError` says so, what it held is counted as lost
(``dropped_out``), and :class:`~emulator.paced_writer.PacedWriter` falls back to its thread.
"""

from __future__ import annotations

import contextlib
import ctypes
import errno
import logging
import os
import select
import signal
import socket
import struct
import subprocess
import sys
import threading
import time
from collections import deque
from collections.abc import Callable, Hashable
from pathlib import Path
from typing import Protocol

from .errors import WriterProcessError

__all__ = ["CPUS_ENV", "DATA", "DRAIN", "DRAINED", "DROPPED", "FLUSH", "OPEN", "RECORD", "STARTED", "TIMER_SLACK_NS",
           "WROTE", "PacedPeer", "WriterProcess", "ask_rt_priority", "child_main", "set_timer_slack"]

log = logging.getLogger(__name__)

#: realtime: the kernel's timer slack asked for (ns) for the loop's thread and the writer's; Linux's default of
#: 50 us lets every precise sleep and epoll wake-up overshoot by up to that much
TIMER_SLACK_NS = 1000
_PR_SET_TIMERSLACK = 29  # linux/prctl.h
_PR_GET_TIMERSLACK = 30


def set_timer_slack(ns: int = TIMER_SLACK_NS) -> int | None:
    """Set the calling thread's timer slack to ``ns`` nanoseconds (``prctl(PR_SET_TIMERSLACK)``, Linux only;
    threads it starts afterwards inherit it). Returns the slack in force afterwards (``PR_GET_TIMERSLACK``), or
    None where there is no such call (another OS, no libc): harmless there, nothing changes."""
    if not sys.platform.startswith("linux"):
        return None
    try:
        prctl = ctypes.CDLL(None, use_errno=True).prctl
    except (OSError, AttributeError):
        return None
    prctl.restype = ctypes.c_int
    prctl.argtypes = [ctypes.c_int, ctypes.c_ulong, ctypes.c_ulong, ctypes.c_ulong, ctypes.c_ulong]
    if prctl(_PR_SET_TIMERSLACK, max(1, int(ns)), 0, 0, 0) != 0:
        return None
    got = prctl(_PR_GET_TIMERSLACK, 0, 0, 0, 0)
    return int(got) if got >= 0 else None


def ask_rt_priority(prio: int | None, above: int = 0) -> tuple[int, str]:
    """Ask ``SCHED_FIFO`` priority ``max(prio, above + 1)`` for the calling thread (Linux: pid 0 is the calling
    thread), ``above`` being the priority of a thread it must still preempt (the loop's, under ``chrt``).
    Returns (the priority granted, 0 for none; a description: ``"SCHED_FIFO 2"``, or ``"SCHED_OTHER (why)"``)."""
    if prio is None or not hasattr(os, "sched_setscheduler"):
        return 0, "SCHED_OTHER"
    prio = max(prio, above + 1)
    try:
        os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(prio))
    except (OSError, ValueError) as exc:
        return 0, f"SCHED_OTHER ({exc.strerror if isinstance(exc, OSError) else exc})"
    return prio, f"SCHED_FIFO {prio}"


# -- the record layout (both directions) -----------------------------------------------------------------------
#: one record, little-endian, 24 bytes: ``kind`` (u8), ``err`` (u8: errno of a failed write, reports only),
#: ``slot`` (u16: the link), ``epoch`` (u32: the link's ``peer_epoch``), ``t_ns`` (i64: DATA: deadline,
#: ``CLOCK_MONOTONIC`` ns; WROTE: lateness, ns; STARTED: the ``SCHED_FIFO`` priority granted), ``size`` (u32:
#: DATA: payload bytes, which follow the record; WROTE / DROPPED: bytes of the item(s)), ``count`` (u32: WROTE: bytes
#: written; DROPPED: items; STARTED: the child's pid)
RECORD = struct.Struct("<BBHIqII")
# parent -> child
DATA, FLUSH, OPEN, DRAIN = 1, 2, 3, 4
# child -> parent
WROTE, DROPPED, DRAINED, STARTED = 16, 17, 18, 19
#: largest payload of one DATA record (bytes; longer chunks go as several records with the same deadline)
MAX_PAYLOAD = 32768
#: the child sends its reports at least this often (s) while it has any, and at once after a failed write
REPORT_EVERY_S = 0.05
#: ... or when this many are waiting
REPORT_BATCH = 128
#: ... and wait for the parent to take them when this many are waiting (one message: 96 KiB, within the socket's
#: buffer)
REPORT_MAX = 4096
#: the environment variable with the CPUs the writer process is pinned to (``"1"``, ``"2,3"``; unset: those of the
#: emulator, which it inherits)
CPUS_ENV = "PSNS_PACED_WRITER_CPUS"
#: the parent waits this long (s) for the child to report that it runs
START_TIMEOUT_S = 5.0
#: the parent's send gives up (the child is stuck) after this long (s)
SEND_TIMEOUT_S = 2.0


def child_main(sock_fd: int, rt_priority: int | None, above: int) -> int:
    """The writer process's loop (module docstring): read records from the socket ``sock_fd``, write each payload
    to its slot's descriptor at its deadline, report. Returns the exit status (0: end of file on the input)."""
    # Ctrl-C reaches the whole process group: the parent ends the run and closes the socket (EOF), and the child
    # writes what it holds and exits then, instead of dying mid-queue with a traceback
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    set_timer_slack()
    cpus = {int(c) for c in os.environ.get(CPUS_ENV, "").split(",") if c.strip()}
    if cpus and hasattr(os, "sched_setaffinity"):  # a core of its own (docs/performance.md 5.8)
        os.sched_setaffinity(0, cpus)
    prio, _policy = ask_rt_priority(rt_priority, above)
    sock = socket.socket(fileno=sock_fd)
    pack, unpack_from, size = RECORD.pack, RECORD.unpack_from, RECORD.size
    mono = time.monotonic_ns
    fd_space = socket.CMSG_SPACE(4 * 4)  # room for the descriptors of one record (one is sent)
    fds: dict[int, int] = {}
    epochs: dict[int, int] = {}
    pending: dict[int, int] = {}
    draining: set[int] = set()
    queue: deque[tuple[int, int, int, bytes]] = deque()  # (deadline ns, slot, epoch, payload)
    reports: list[bytes] = [pack(STARTED, 0 if prio else errno.EPERM, 0, 0, prio, 0, os.getpid())]
    report_due = mono()
    eof = False

    def send_reports(block: bool) -> bool:
        """Send what is waiting; False when the parent has gone."""
        nonlocal reports
        if not reports:
            return True
        if len(reports) >= REPORT_MAX:  # one message must fit the socket's buffer: wait for the parent
            block = True
        try:
            sock.send(b"".join(reports), 0 if block else socket.MSG_DONTWAIT)
        except BlockingIOError:
            return True  # the parent is behind: keep them for the next try
        except OSError:
            return False
        reports = []
        return True

    def drained(slot: int) -> None:
        nonlocal report_due
        fd = fds.pop(slot, None)
        if fd is not None:
            os.close(fd)
        draining.discard(slot)
        pending.pop(slot, None)
        epochs.pop(slot, None)
        reports.append(pack(DRAINED, 0, slot, 0, 0, 0, 0))
        report_due = 0  # the parent waits for it

    def handle(msg: bytes, got_fds: list[int]) -> None:
        nonlocal queue, report_due
        kind, _err, slot, epoch, t_ns, n, _count = unpack_from(msg)
        if kind == DATA:
            if epochs.get(slot, epoch) != epoch:  # for a peer already flushed
                reports.append(pack(DROPPED, 0, slot, epoch, 0, n, 1))
                report_due = 0
                return
            queue.append((t_ns, slot, epoch, msg[size:size + n]))
            pending[slot] = pending.get(slot, 0) + 1
        elif kind == OPEN:
            old = fds.pop(slot, None)
            if old is not None:
                os.close(old)
            if got_fds:
                fds[slot] = got_fds.pop(0)
            epochs[slot] = epoch
        elif kind == FLUSH:
            epochs[slot] = epoch
            keep: deque[tuple[int, int, int, bytes]] = deque()
            gone: dict[int, list[int]] = {}
            for it in queue:
                if it[1] == slot and it[2] != epoch:
                    g = gone.setdefault(it[2], [0, 0])
                    g[0] += len(it[3])
                    g[1] += 1
                else:
                    keep.append(it)
            queue = keep
            for ep, (nb, ni) in gone.items():
                pending[slot] -= ni
                reports.append(pack(DROPPED, 0, slot, ep, 0, nb, ni))
                report_due = 0  # the link counts them now
        elif kind == DRAIN:
            if pending.get(slot, 0):
                draining.add(slot)
            else:
                drained(slot)
        for fd in got_fds:  # descriptors no record claimed
            os.close(fd)

    while True:
        now = mono()
        while queue and queue[0][0] <= now:  # everything due
            deadline, slot, epoch, payload = queue.popleft()
            fd = fds.get(slot)
            err = 0
            written = 0
            if fd is None:
                err = errno.EBADF
            else:
                try:
                    written = os.write(fd, payload)
                except BlockingIOError:
                    pass  # the peer's buffer is full: nothing written, the link counts the loss
                except OSError as exc:
                    err = exc.errno or errno.EIO
            now = mono()
            if not reports:
                report_due = now + int(REPORT_EVERY_S * 1e9)
            reports.append(pack(WROTE, min(err, 255), slot, epoch, now - deadline, len(payload), written))
            if err or written < len(payload):
                report_due = now
            left = pending[slot] - 1
            pending[slot] = left
            if not left and slot in draining:
                drained(slot)
                report_due = now
        if reports and (now >= report_due or len(reports) >= REPORT_BATCH or eof) and not send_reports(block=eof):
            return 0  # the parent has gone
        if eof and not queue:
            send_reports(block=True)
            return 0
        wake = queue[0][0] if queue else None
        if reports:
            wake = report_due if wake is None else min(wake, report_due)
        timeout = None if wake is None else max(0, wake - mono()) / 1e9
        if eof:
            time.sleep(timeout or 0.0)
            continue
        ready, _, _ = select.select([sock], [], [], timeout)
        if not ready:
            continue
        while True:  # every record waiting
            got: list[int] = []
            try:  # (socket.recv_fds ignores its flags: recvmsg itself)
                msg, anc, _flags, _addr = sock.recvmsg(size + MAX_PAYLOAD, fd_space, socket.MSG_DONTWAIT)
            except BlockingIOError:
                break
            except OSError:
                msg, anc = b"", []
            for level, typ, cdata in anc:
                if level == socket.SOL_SOCKET and typ == socket.SCM_RIGHTS:
                    got.extend(int.from_bytes(cdata[i:i + 4], sys.byteorder)
                               for i in range(0, len(cdata) - len(cdata) % 4, 4))
            if not msg:
                for fd in got:
                    os.close(fd)
                eof = True
                break
            handle(msg, got)


class PacedPeer(Protocol):
    """What the paced writer needs of a link (``emulator.links.base.Link``) to write for it."""

    peer_epoch: int

    def __hash__(self) -> int: ...

    def peer_fd(self) -> int | None: ...

    def _write_deferred(self, item: tuple[int, bytes]) -> None: ...

    def _report_deferred(self, epoch: int, size: int, written: int, err: int | None) -> None: ...


class _Slot:
    __slots__ = ("bytes", "done", "id", "items", "peer")

    def __init__(self, sid: int, peer: PacedPeer) -> None:
        self.id = sid
        self.peer = peer
        self.items = 0
        self.bytes = 0
        self.done = threading.Event()


class WriterProcess:
    """The parent's side of the writer process (module docstring): start it, send records, read its reports.

    ``on_late(owner, late_s)`` (optional) gets each write's lateness against its deadline (s), in the reports'
    thread; ``on_death(error)`` is called once when the child dies unasked.
    """

    def __init__(self, rt_priority: int | None = 1, above: int = 0,
                 on_late: Callable[[Hashable, float], None] | None = None,
                 on_death: Callable[[WriterProcessError], None] | None = None) -> None:
        self.on_late = on_late
        self.on_death = on_death
        self._lock = threading.Lock()
        self._slots: dict[Hashable, _Slot] = {}
        self._by_id: dict[int, _Slot] = {}
        self._next_id = 0
        self._closing = False
        #: set when the child died unasked (and the backend stopped)
        self.error: WriterProcessError | None = None
        #: the child's scheduling policy once it reported (``SCHED_FIFO 2``, or ``SCHED_OTHER (errno text)``)
        self.policy: str | None = None
        self.writes = 0
        self.failures = 0
        self.started = threading.Event()
        parent, child = socket.socketpair(socket.AF_UNIX, socket.SOCK_SEQPACKET)
        # SO_SNDTIMEO: a stuck child makes a send fail after SEND_TIMEOUT_S instead of blocking the loop for good
        sec = int(SEND_TIMEOUT_S)
        parent.setsockopt(socket.SOL_SOCKET, socket.SO_SNDTIMEO,
                          struct.pack("ll", sec, int((SEND_TIMEOUT_S - sec) * 1e6)))
        self._sock = parent
        root = str(Path(__file__).resolve().parents[1])  # the tree this module comes from: the child imports the same
        env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in (root, os.environ.get("PYTHONPATH")) if p))
        try:
            self.proc = subprocess.Popen(
                [sys.executable, "-m", "emulator.pacing", str(child.fileno()),
                 "none" if rt_priority is None else str(rt_priority), str(above)],
                pass_fds=[child.fileno()], stdin=subprocess.DEVNULL, env=env)
        except OSError as exc:
            parent.close()
            raise WriterProcessError(f"cannot start the paced writer process: {exc}") from exc
        finally:
            child.close()
        self._reader = threading.Thread(target=self._read_reports, name="psns-writer-reports", daemon=True)
        self._reader.start()
        # up before the first deadline (an interpreter starts in ~0.1 s): the loop's clock starts after this
        if not self.started.wait(START_TIMEOUT_S) and self.error is None:
            self.proc.kill()
            self._died(f"did not start within {START_TIMEOUT_S:g} s")
        if self.error is not None:
            raise self.error

    @property
    def pid(self) -> int:
        return self.proc.pid

    @property
    def alive(self) -> bool:
        return self.error is None and not self._closing

    # -- the loop's thread ----------------------------------------------------------------------------------
    def put(self, at: float, peer: PacedPeer, data: bytes, fd: int) -> None:
        """Have ``data`` written to ``fd`` (``peer``'s descriptor) at ``CLOCK_MONOTONIC`` instant ``at`` (s).
        Raises :class:`WriterProcessError` when the child cannot take it (then the backend is dead)."""
        slot = self._slots.get(peer)
        if slot is None:
            slot = self._open(peer, fd)
        epoch = peer.peer_epoch & 0xFFFFFFFF
        t_ns = round(at * 1e9)
        with self._lock:
            slot.items += (len(data) + MAX_PAYLOAD - 1) // MAX_PAYLOAD
            slot.bytes += len(data)
        for i in range(0, len(data), MAX_PAYLOAD):
            piece = data[i:i + MAX_PAYLOAD]
            self._send([RECORD.pack(DATA, 0, slot.id, epoch, t_ns, len(piece), 0), piece])

    def flush(self, peer: PacedPeer) -> None:
        """``peer``'s peer has gone (its ``peer_epoch`` moved on): drop what is queued for the earlier ones."""
        slot = self._slots.get(peer)
        if slot is not None and self.alive:
            self._send([RECORD.pack(FLUSH, 0, slot.id, peer.peer_epoch & 0xFFFFFFFF, 0, 0, 0)])

    def drain(self, owner: Hashable, timeout: float = 5.0) -> bool:
        """Wait until every item of ``owner`` sent so far is written, and the child has closed its copy of the
        descriptor (a later :meth:`put` sends it again); False on timeout (wall s)."""
        slot = self._slots.get(owner)
        if slot is None:
            return True
        if self.alive:
            with contextlib.suppress(WriterProcessError):  # dead: slot.done is set
                self._send([RECORD.pack(DRAIN, 0, slot.id, 0, 0, 0, 0)])
        ok = slot.done.wait(timeout)
        with self._lock:
            if self._slots.get(owner) is slot:
                del self._slots[owner]
                self._by_id.pop(slot.id, None)
        return ok

    def pending(self, owner: Hashable | None = None) -> int:
        """Items not reported written yet (of ``owner``, or all)."""
        with self._lock:
            if owner is not None:
                s = self._slots.get(owner)
                return s.items if s is not None else 0
            return sum(s.items for s in self._slots.values())

    def close(self, timeout: float = 5.0) -> None:
        """End of file on the child's input: it writes what it holds (each at its instant) and exits."""
        if self._closing:
            return
        self._closing = True
        with contextlib.suppress(OSError):
            self._sock.shutdown(socket.SHUT_WR)
        try:
            self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()
        self._reader.join(timeout)
        self._sock.close()

    # -- internals ------------------------------------------------------------------------------------------
    def _open(self, peer: PacedPeer, fd: int) -> _Slot:
        with self._lock:
            while self._next_id in self._by_id:
                self._next_id = (self._next_id + 1) & 0xFFFF
            slot = _Slot(self._next_id, peer)
            self._next_id = (self._next_id + 1) & 0xFFFF
            self._slots[peer] = slot
            self._by_id[slot.id] = slot
        try:
            socket.send_fds(self._sock, [RECORD.pack(OPEN, 0, slot.id, peer.peer_epoch & 0xFFFFFFFF, 0, 0, 0)], [fd])
        except OSError as exc:
            self._died(f"took no descriptor ({exc})")
            raise self.error or WriterProcessError(str(exc)) from exc
        return slot

    def _send(self, parts: list[bytes]) -> None:
        if not self.alive:
            raise self.error or WriterProcessError("the paced writer process is closed")
        try:
            self._sock.sendmsg(parts)
        except OSError as exc:  # BrokenPipe: it died; BlockingIOError after SO_SNDTIMEO: it is stuck
            if isinstance(exc, BlockingIOError):
                self.proc.kill()
            self._died(f"took no record ({exc.__class__.__name__}: {exc})")
            raise self.error or WriterProcessError(str(exc)) from exc

    def _read_reports(self) -> None:
        unpack_from, size = RECORD.unpack_from, RECORD.size
        while True:
            try:
                msg = self._sock.recv(65536)
            except OSError:
                msg = b""
            if not msg:
                break
            for off in range(0, len(msg) - size + 1, size):
                kind, err, sid, epoch, t_ns, n, count = unpack_from(msg, off)
                if kind == STARTED:
                    self.policy = f"SCHED_FIFO {t_ns}" if t_ns else f"SCHED_OTHER ({os.strerror(err)})"
                    self.started.set()
                    continue
                with self._lock:
                    slot = self._by_id.get(sid)
                    if slot is None:
                        continue
                    if kind == WROTE:
                        slot.items -= 1
                        slot.bytes -= n
                        self.writes += 1
                    elif kind == DROPPED:
                        slot.items -= count
                        slot.bytes -= n
                if kind == DRAINED:
                    slot.done.set()
                    continue
                if kind == WROTE:
                    if err or count < n:
                        if err:
                            self.failures += 1
                        slot.peer._report_deferred(epoch, n, count, err or None)
                    hook = self.on_late
                    if hook is not None:
                        hook(slot.peer, t_ns * 1e-9)
                elif kind == DROPPED:
                    slot.peer._report_deferred(epoch, n, 0, None)
        if not self._closing:
            try:
                code = self.proc.wait(1.0)
            except subprocess.TimeoutExpired:
                code = None
            self._died(f"exited (status {code})" if code is not None else "closed its socket")

    def _died(self, how: str) -> None:
        """The child died unasked: the error, its writes counted as lost, the drain waiters released."""
        with self._lock:
            if self.error is not None or self._closing:
                return
            slots = list(self._slots.values())
            lost = [(s, s.bytes) for s in slots]
            items = sum(s.items for s in slots)
            self.error = WriterProcessError(
                f"the paced writer process (pid {self.proc.pid}) {how}: {items} queued writes "
                f"({sum(b for _s, b in lost)} bytes) lost; writing from the paced writer's thread from now on")
            for s in slots:
                s.items = 0
                s.bytes = 0
        log.error("%s", self.error)
        for s, nbytes in lost:
            if nbytes:  # not written: lost on the line, as a failed write would be (dropped_out)
                s.peer._report_deferred(s.peer.peer_epoch, nbytes, 0, None)
            s.done.set()
        if self.on_death is not None:
            self.on_death(self.error)


if __name__ == "__main__":  # the writer process: python -m emulator.pacing SOCKET_FD PRIORITY|none ABOVE
    _prio = None if sys.argv[2] == "none" else int(sys.argv[2])
    sys.exit(child_main(int(sys.argv[1]), _prio, int(sys.argv[3])))
