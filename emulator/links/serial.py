"""``serial:///dev/ttyXXX``: a real serial device (real hardware in the loop), via pyserial.

The device's own UART paces what we write; bytes we read are paced again by the line model
(they arrive in bursts from the driver). Writes go straight to pyserial's non-blocking file
descriptor: a full driver buffer is counted overflow, never a blocked event loop. A device that
cannot be opened raises :class:`~emulator.errors.LinkBrokenError` (the pyserial error as its
cause); one that goes away later (USB unplugged, the other end of a pty pair closed) stops the
link without a busy loop and leaves the reason in ``Link.error`` (reported in the summary).

URL form: ``serial:///dev/ttyUSB0[?baud=460800&mode=8N1&queue=BYTES&pps=dcd|cts]``.

PPS from a modem line (``pps=dcd`` or ``pps=cts``), the way gpsd takes a receiver's timepulse: a thread
waits for a change of the line with the ``TIOCMIWAIT`` ioctl, reads the lines with ``TIOCMGET`` and, on an
asserted (rising) edge, hands the loop time taken right after the wake-up to :attr:`SerialLink.on_pps`
(the session wires it to the virtual FPGA's PPS latch, as the modelled receiver's PPS). A pseudo-terminal
has no modem lines: on a pty both ioctls fail with ENOTTY; the link then keeps its data path, stops
waiting and leaves the reason in :attr:`SerialLink.pps_error` (reported with the port), so a scenario with
``pps=dcd`` on a pty is told it has no PPS instead of silently running without one.
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import fcntl
import os
import struct
import termios
import threading
from collections.abc import Callable
from typing import Any

from ..errors import LinkBrokenError, LinkConfigError
from .base import Link
from .line import LineConfig

__all__ = ["PPS_LINES", "ModemPpsWatcher", "SerialLink"]

#: ``TIOCMIWAIT`` (Linux asm-generic ioctls.h 0x545C; Python's termios exposes it where the platform has it)
TIOCMIWAIT = getattr(termios, "TIOCMIWAIT", 0x545C)
#: modem line of the PPS -> its TIOCM_* bit
PPS_LINES = {"dcd": termios.TIOCM_CAR, "cts": termios.TIOCM_CTS}


class ModemPpsWatcher:
    """Wait for PPS edges on a modem line of ``fd`` (module docstring). ``ioctl`` is the OS boundary
    (``fcntl.ioctl`` by default; a test hands in a fake device there and nowhere else).

    ``on_edge(t)`` is called in the event loop with the loop time of each asserted edge; ``on_error(why)`` once
    when the device cannot wait for modem lines (a pty) or goes away.
    """

    def __init__(self, fd: int, line: str, loop: asyncio.AbstractEventLoop, on_edge: Callable[[float], None],
                 on_error: Callable[[str], None], ioctl: Callable[..., Any] = fcntl.ioctl) -> None:
        if line not in PPS_LINES:
            raise LinkConfigError(f"pps={line!r}: expected one of {', '.join(PPS_LINES)}")
        self.fd = fd
        self.line = line
        self.mask = PPS_LINES[line]
        self.loop = loop
        self.on_edge = on_edge
        self.on_error = on_error
        self.ioctl = ioctl
        self.edges = 0
        self.clears = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def _lines(self) -> int:
        buf = self.ioctl(self.fd, termios.TIOCMGET, struct.pack("I", 0))
        return int(struct.unpack("I", buf)[0])

    def start(self) -> None:
        try:
            level = self._lines() & self.mask  # a device without modem lines fails here already (pty: ENOTTY)
        except OSError as exc:
            self.on_error(f"PPS on {self.line.upper()}: the device has no modem lines ({exc}); a pty cannot carry "
                          "them, use a real serial port")
            return
        self._thread = threading.Thread(target=self._run, args=(level,), name=f"pps-{self.line}", daemon=True)
        self._thread.start()

    def _run(self, level: int) -> None:
        while not self._stop.is_set():
            try:
                self.ioctl(self.fd, TIOCMIWAIT, self.mask)
                t = self.loop.time()  # taken right after the wake-up (gpsd does the same)
                now = self._lines() & self.mask
            except OSError as exc:
                if not self._stop.is_set():
                    self.loop.call_soon_threadsafe(self.on_error, f"PPS on {self.line.upper()} stopped: {exc}")
                return
            if self._stop.is_set():
                return
            if now and not level:
                self.edges += 1
                self.loop.call_soon_threadsafe(self.on_edge, t)
            elif level and not now:
                self.clears += 1
            elif now and level:
                # a whole pulse between two wake-ups (a short pulse): assert-then-clear counts as one edge
                self.edges += 1
                self.loop.call_soon_threadsafe(self.on_edge, t)
            level = now

    def stop(self) -> None:
        self._stop.set()


class SerialLink(Link):
    """A real serial port opened with pyserial."""

    scheme = "serial"
    url_usage = "serial:///dev/ttyXXX[?baud=N&mode=8N1&queue=BYTES&pps=dcd|cts]"
    url_options = frozenset({"pps"})
    paces_input = True
    slice_s = 0.001
    deferred_write = True

    def __init__(self, name: str, url: str, line: LineConfig, loop: asyncio.AbstractEventLoop,
                 target: str = "", **kw: Any) -> None:
        super().__init__(name, url, line, loop)
        if not target.startswith("/"):
            raise LinkConfigError(f"{url!r}: expected serial:///dev/ttyXXX (an absolute device path)")
        self.device = target
        self._ser: Any = None
        opts: dict[str, str] = kw.get("options") or {}
        #: modem line carrying the receiver's PPS (``dcd`` / ``cts``), or None
        self.pps_line: str | None = opts.get("pps") or None
        if self.pps_line is not None and self.pps_line not in PPS_LINES:
            raise LinkConfigError(f"{url!r}: pps={self.pps_line!r}; expected one of {', '.join(PPS_LINES)}")
        #: called with the loop time of each PPS edge (the session wires the FPGA's PPS latch here)
        self.on_pps: Callable[[float], None] | None = None
        #: why PPS is not available (a pty has no modem lines), None while it works
        self.pps_error: str | None = None
        self.pps_edges = 0
        self._pps: ModemPpsWatcher | None = None
        #: the OS boundary of the PPS watcher (tests hand in a fake device)
        self.ioctl: Callable[..., Any] = fcntl.ioctl

    async def open(self) -> None:
        import serial  # pyserial, imported only when this scheme is used

        parity = {"N": serial.PARITY_NONE, "E": serial.PARITY_EVEN, "O": serial.PARITY_ODD}[self.line.parity]
        stop = {1.0: serial.STOPBITS_ONE, 1.5: serial.STOPBITS_ONE_POINT_FIVE, 2.0: serial.STOPBITS_TWO}[
            float(self.line.stop_bits)
        ]
        try:
            self._ser = serial.Serial(
                self.device, self.line.baud, bytesize=self.line.data_bits, parity=parity, stopbits=stop, timeout=0,
                write_timeout=0,
            )
        except (serial.SerialException, OSError, ValueError) as exc:
            raise LinkBrokenError(f"{self.name}: cannot open {self.device}: {exc}") from exc
        self.loop.add_reader(self._ser.fileno(), self._on_readable)
        if self.pps_line is not None:
            self._pps = ModemPpsWatcher(self._ser.fd, self.pps_line, self.loop, self._pps_edge, self._pps_failed,
                                        ioctl=self.ioctl)
            self._pps.start()

    def _pps_edge(self, t: float) -> None:
        self.pps_edges += 1
        if self.on_pps is not None:
            self.on_pps(t)

    def _pps_failed(self, why: str) -> None:
        self.pps_error = why

    def _on_readable(self) -> None:
        try:
            data = os.read(self._ser.fd, 4096)
        except BlockingIOError:
            return
        except OSError as exc:
            self._broken(f"reading {self.device} failed: {exc}")
            return
        if not data:
            self._broken(f"{self.device} reports end of file (device gone?)")
            return
        self._input(data)

    def _broken(self, why: str) -> None:
        """The device went away: stop reading (no busy loop), keep the reason for the summary."""
        self.error = why
        with contextlib.suppress(ValueError, OSError):
            self.loop.remove_reader(self._ser.fd)

    def _write_raw(self, data: bytes) -> None:
        if self._ser is None:
            self.stats.dropped_out += len(data)
            return
        self._hand_over(data)

    def peer_fd(self) -> int | None:
        ser = self._ser
        return None if ser is None else int(ser.fd)

    def _write_out(self, data: bytes) -> tuple[int, int | None]:
        # os.write on pyserial's non-blocking fd: pyserial's own write() spins on EAGAIN when
        # write_timeout is 0, and blocks the event loop otherwise. A full driver buffer is
        # overflow, counted like every other.
        ser = self._ser
        if ser is None:
            return 0, errno.EBADF
        try:
            return os.write(ser.fd, data), None
        except BlockingIOError:
            return 0, None
        except OSError as exc:
            return 0, exc.errno or errno.EIO

    def _after_write(self, size: int, written: int, err: int | None) -> None:
        if err is not None and self.error is None and self._ser is not None:
            self._broken(f"writing {self.device} failed: {os.strerror(err)}")
        if written < size:
            self.stats.dropped_out += size - written

    def describe(self) -> str:
        if self.pps_line is None:
            return self.device
        return f"{self.device} (PPS on {self.pps_line.upper()}{': ' + self.pps_error if self.pps_error else ''})"

    async def close(self) -> None:
        if self._pps is not None:
            self._pps.stop()
        self._drain_writes()
        await super().close()
        if self._ser is not None:
            with contextlib.suppress(ValueError, OSError):
                self.loop.remove_reader(self._ser.fileno())
            self._ser.close()
            self._ser = None
