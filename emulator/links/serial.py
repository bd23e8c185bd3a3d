"""``serial:///dev/ttyXXX``: a real serial device (real hardware in the loop), via pyserial.

The device's own UART paces what we write; bytes we read are paced again by the line model
(they arrive in bursts from the driver). pyserial errors are mapped to
:class:`~emulator.errors.LinkBrokenError` at this boundary.

URL form: ``serial:///dev/ttyUSB0[?baud=460800&mode=8N1&queue=BYTES]``.
"""

from __future__ import annotations

import asyncio
from typing import Any

from ..errors import LinkBrokenError, LinkConfigError
from .base import LineConfig, Link

__all__ = ["SerialLink"]


class SerialLink(Link):
    """A real serial port opened with pyserial."""

    scheme = "serial"
    paces_input = True

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
                self.device, self.line.baud, bytesize=self.line.data_bits, parity=parity, stopbits=stop, timeout=0
            )
        except (serial.SerialException, OSError, ValueError) as exc:
            raise LinkBrokenError(f"{self.name}: cannot open {self.device}: {exc}") from exc
        self.loop.add_reader(self._ser.fileno(), self._on_readable)

    def _on_readable(self) -> None:
        import serial

        try:
            data = self._ser.read(4096)
        except (serial.SerialException, OSError) as exc:
            self.loop.remove_reader(self._ser.fileno())
            raise LinkBrokenError(f"{self.name}: reading {self.device} failed: {exc}") from exc
        if data:
            self._input(bytes(data))

    def _write_raw(self, data: bytes) -> None:
        import serial

        if self._ser is None:
            self.stats.dropped_out += len(data)
            return
        try:
            n = self._ser.write(data) or 0
        except serial.SerialTimeoutException:
            n = 0
        except (serial.SerialException, OSError) as exc:
            raise LinkBrokenError(f"{self.name}: writing {self.device} failed: {exc}") from exc
        if n < len(data):
            self.stats.dropped_out += len(data) - n

    def describe(self) -> str:
        return self.device

    async def close(self) -> None:
        await super().close()
        if self._ser is not None:
            try:
                self.loop.remove_reader(self._ser.fileno())
            except (ValueError, OSError):
                pass
            self._ser.close()
            self._ser = None
