"""``serial:///dev/ttyXXX``: a real serial device (real hardware in the loop), via pyserial.

The device's own UART paces what we write; bytes we read are paced again by the line model
(they arrive in bursts from the driver). Writes go straight to pyserial's non-blocking file
descriptor: a full driver buffer is counted overflow, never a blocked event loop. A device that
cannot be opened raises :class:`~emulator.errors.LinkBrokenError` (the pyserial error as its
cause); one that goes away later (USB unplugged, the other end of a pty pair closed) stops the
link without a busy loop and leaves the reason in ``Link.error`` (reported in the summary).

URL form: ``serial:///dev/ttyUSB0[?baud=460800&mode=8N1&queue=BYTES]``.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
from typing import Any

from ..errors import LinkBrokenError, LinkConfigError
from .base import Link
from .line import LineConfig

__all__ = ["SerialLink"]


class SerialLink(Link):
    """A real serial port opened with pyserial."""

    scheme = "serial"
    paces_input = True
    slice_s = 0.001

    def __init__(self, name: str, url: str, line: LineConfig, loop: asyncio.AbstractEventLoop,
                 target: str = "", **_: Any) -> None:
        super().__init__(name, url, line, loop)
        if not target.startswith("/"):
            raise LinkConfigError(f"{url!r}: expected serial:///dev/ttyXXX (an absolute device path)")
        self.device = target
        self._ser: Any = None

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
        # os.write on pyserial's non-blocking fd: pyserial's own write() spins on EAGAIN when
        # write_timeout is 0, and blocks the event loop otherwise. A full driver buffer is
        # overflow, counted like every other.
        try:
            n = os.write(self._ser.fd, data)
        except BlockingIOError:
            n = 0
        except OSError as exc:
            if self.error is None:
                self._broken(f"writing {self.device} failed: {exc}")
            n = 0
        if n < len(data):
            self.stats.dropped_out += len(data) - n

    def describe(self) -> str:
        return self.device

    async def close(self) -> None:
        await super().close()
        if self._ser is not None:
            with contextlib.suppress(ValueError, OSError):
                self.loop.remove_reader(self._ser.fileno())
            self._ser.close()
            self._ser = None
