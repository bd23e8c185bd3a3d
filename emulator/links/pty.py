"""``pty://NAME``: a pseudo-terminal that real serial tools attach to.

The master side stays in the emulator; the slave side is what a user opens, through a stable
symlink ``<run_dir>/NAME`` (the run directory is private: mode 0700; the pty node is 0600).
Measured behaviour this module is built around (``docs/reference/wire-formats.md`` section 5):

* with no peer holding the slave open, reading the master gives EIO and ``poll`` reports
  POLLHUP; an fd reader would spin, so the link polls for attachment instead and only reads
  while a peer is attached;
* bytes written while nobody listens would be read by the next opener: they are discarded (and
  counted as ``no_peer_out``, apart from ``dropped_out``) instead, so a new peer never sees stale data;
* a peer that opens but does not read makes the master's writes fail with EAGAIN after
  ~18 KiB: the excess is dropped and counted, memory stays bounded;
* a peer that closes leaves what it did not read in the slave's input queue, where the next
  opener would find it: the link flushes the slave's queues when it sees the detach, and it
  checks for a hang-up before every write;
* a pty ignores the baud rate; pacing comes from the link's line model, and long chunks are
  written in slices of ``slice_s`` of wire time so bytes trickle out at the line's pace. The
  client's termios speed is readable (``peer_baud``); with ``?peer_baud=check`` a client set to
  another baud (beyond the UART tolerance) gets, and sends, what a real mismatched line would
  carry: framing errors, counted. The default (``ignore``) suits tools that never set a speed.

URL form: ``pty://NAME[?baud=N&mode=8N1&queue=BYTES&peer_baud=ignore|check]``.
"""

from __future__ import annotations

import asyncio
import errno
import math
import os
import select
import termios
import tty
from pathlib import Path
from typing import Any

from ..errors import LinkConfigError
from .base import Link
from .line import LineConfig

__all__ = ["ATTACH_POLL_S", "PtyLink"]

#: Attachment poll period, s of scenario time.
ATTACH_POLL_S = 0.02

_BAUD_CONST = {getattr(termios, f"B{b}"): b for b in (
    50, 75, 110, 134, 150, 200, 300, 600, 1200, 1800, 2400, 4800, 9600, 19200, 38400, 57600,
    115200, 230400, 460800, 500000, 576000, 921600, 1000000, 1152000, 1500000, 2000000,
    2500000, 3000000, 3500000, 4000000) if hasattr(termios, f"B{b}")}


class PtyLink(Link):
    """A pseudo-terminal endpoint (see module docstring)."""

    scheme = "pty"
    url_usage = "pty://NAME[?baud=N&mode=8N1&queue=BYTES&peer_baud=ignore|check]"
    url_options = frozenset({"peer_baud"})
    paces_input = True
    slice_s = 0.001
    deferred_write = True

    def __init__(
        self,
        name: str,
        url: str,
        line: LineConfig,
        loop: asyncio.AbstractEventLoop,
        target: str = "",
        run_dir: str | os.PathLike[str] | None = None,
        options: dict[str, str] | None = None,
        **_: Any,
    ) -> None:
        super().__init__(name, url, line, loop)
        opts = options or {}
        check = opts.get("peer_baud", "ignore")
        if check not in ("ignore", "check"):
            raise LinkConfigError(f"{url!r}: peer_baud must be 'ignore' or 'check', got {check!r}")
        self.check_peer_baud = check == "check"
        self._peer_cfg: LineConfig | None = None
        self._out_framer: Any = None
        if not target or "/" in target:
            raise LinkConfigError(f"{url!r}: expected pty://NAME with a plain name (no '/')")
        if run_dir is None:
            raise LinkConfigError(f"{url!r}: pty links need a run directory")
        self.port_dir = Path(run_dir)
        self.link_path = self.port_dir / target
        self.master_fd: int | None = None
        self.slave_path: str | None = None
        self.attached = False
        self.attach_count = 0
        self._poll_handle: asyncio.TimerHandle | None = None
        self._reading = False
        self._poller: select.poll | None = None
        self.detach_count = 0
        self.flushed_stale = 0

    async def open(self) -> None:
        self.port_dir.mkdir(parents=True, exist_ok=True)
        os.chmod(self.port_dir, 0o700)
        master, slave = os.openpty()
        tty.setraw(slave)
        self.slave_path = os.ttyname(slave)
        os.chmod(self.slave_path, 0o600)
        os.set_blocking(master, False)
        os.close(slave)  # the user opens it; holding it would hide attach/detach
        self.master_fd = master
        self._poller = select.poll()
        self._poller.register(master, select.POLLHUP)
        tmp = self.link_path.with_name(self.link_path.name + ".tmp")
        if tmp.is_symlink() or tmp.exists():
            tmp.unlink()
        os.symlink(self.slave_path, tmp)
        os.replace(tmp, self.link_path)
        self._poll()

    def describe(self) -> str:
        return f"{self.link_path} -> {self.slave_path}"

    @property
    def peer_baud(self) -> int | None:
        """The baud the attached client set with termios (None if unknown)."""
        if self.master_fd is None:
            return None
        try:
            attrs = termios.tcgetattr(self.master_fd)
        except termios.error:
            return None
        return _BAUD_CONST.get(attrs[5])

    # attach / detach ------------------------------------------------------------------
    def _hung_up(self) -> bool:
        assert self._poller is not None
        return any(ev & select.POLLHUP for _fd, ev in self._poller.poll(0))

    def _peer_line(self) -> LineConfig | None:
        """The client's termios settings as a line config (None if unknown or unchecked)."""
        if not self.check_peer_baud or self.master_fd is None:
            return None
        try:
            attrs = termios.tcgetattr(self.master_fd)
        except termios.error:
            return None
        baud = _BAUD_CONST.get(attrs[5])
        if baud is None or baud == 0:
            return None
        return self.line.with_(baud=baud)

    def _refresh_peer(self) -> None:
        cfg = self._peer_line()
        if cfg == self._peer_cfg:
            return
        self._peer_cfg = cfg
        self.set_remote_line(cfg)  # what the client sends, as our UART samples it
        from .framing import UartReceiver, uart_compatible

        self._out_framer = None if cfg is None or uart_compatible(self.line, cfg) else UartReceiver(self.line, cfg)

    def _poll(self) -> None:
        self._poll_handle = None
        if self.closed or self.master_fd is None:
            return
        hup = self._hung_up()
        if not hup and not self.attached:
            self.attached = True
            self.attach_count += 1
            self._start_reading()
        elif hup and self.attached:
            self._detach()
        if self.attached and self.check_peer_baud:
            self._refresh_peer()
        self._poll_handle = self.loop.call_later(ATTACH_POLL_S, self._poll)

    def _start_reading(self) -> None:
        if not self._reading and self.master_fd is not None:
            self.loop.add_reader(self.master_fd, self._on_readable)
            self._reading = True

    def _stop_reading(self) -> None:
        if self._reading and self.master_fd is not None:
            self.loop.remove_reader(self.master_fd)
        self._reading = False

    def _detach(self) -> None:
        self.attached = False
        self._peer_gone()  # what the paced writer holds for this peer is not written
        self.detach_count += 1
        self._stop_reading()
        self._flush_slave()

    def _flush_slave(self) -> None:
        """Discard what the departed peer left unread, so the next one gets no stale bytes."""
        if self.slave_path is None:
            return
        try:
            fd = os.open(self.slave_path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
        except OSError:
            return
        try:
            import fcntl

            try:
                n = int.from_bytes(fcntl.ioctl(fd, termios.FIONREAD, b"\0\0\0\0"), "little")
            except OSError:
                n = 0
            termios.tcflush(fd, termios.TCIOFLUSH)
            self.flushed_stale += n
        except termios.error:
            pass
        finally:
            os.close(fd)

    def _on_readable(self) -> None:
        assert self.master_fd is not None
        try:
            data = os.read(self.master_fd, 4096)
        except BlockingIOError:
            return
        except OSError as exc:
            if exc.errno == errno.EIO:
                self._detach()
                return
            self.error = f"reading {self.slave_path} failed: {exc}"
            self._stop_reading()
            return
        if data:
            self._input(data)

    # transport --------------------------------------------------------------------------
    def _write_raw(self, data: bytes) -> None:
        if self.master_fd is None or not self.attached:
            self.stats.no_peer_out += len(data)
            return
        if self._hung_up():  # the peer left since the last poll: do not leave stale bytes
            self._detach()
            self.stats.no_peer_out += len(data)
            return
        if self._out_framer is not None:
            fr = self._out_framer
            fr.feed(self._tx_start, data, self._tx_pitch)
            data = bytes(b for _t, b in fr.decode(math.inf))
            self.stats.framing_errors = fr.framing_errors
            self.stats.parity_errors = fr.parity_errors
            if not data:
                return
        self._hand_over(data)

    def peer_fd(self) -> int | None:
        return self.master_fd

    def _write_out(self, data: bytes) -> tuple[int, int | None]:
        fd = self.master_fd
        if fd is None:
            return 0, errno.EBADF
        try:
            return os.write(fd, data), None
        except BlockingIOError:
            return 0, None
        except OSError as exc:
            return 0, exc.errno or errno.EIO

    def _after_write(self, size: int, written: int, err: int | None) -> None:
        if err == errno.EIO or (err == errno.EBADF and self.master_fd is None):
            if self.attached:
                self._detach()
            self.stats.no_peer_out += size
            return
        if err is not None:
            self.error = f"writing {self.slave_path} failed: {os.strerror(err)}"
            self.stats.dropped_out += size
            return
        if written < size:
            self.stats.dropped_out += size - written

    async def close(self) -> None:
        self._drain_writes()
        await super().close()
        if self._poll_handle is not None:
            self._poll_handle.cancel()
            self._poll_handle = None
        self._stop_reading()
        if self.master_fd is not None:
            os.close(self.master_fd)
            self.master_fd = None
        try:
            if self.link_path.is_symlink():
                self.link_path.unlink()
        except OSError:
            pass
