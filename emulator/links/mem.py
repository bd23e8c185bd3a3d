"""``mem://NAME``: an in-process link between two device ports (deterministic).

The first two opens of the same name in one :class:`MemHub` become peers. Bytes sent on one
end are paced by that end's line model and delivered to the other end's device; the receiving
end does not pace again.

The two ends may have different line settings (a sensor configured at one baud, the FPGA port
at another): the receiving end then decodes the transmitter's waveform bit by bit
(:mod:`emulator.links.framing`) and counts framing and parity errors.

URL form: ``mem://NAME[?baud=N&mode=8N1&queue=BYTES]``.
"""

from __future__ import annotations

import asyncio

from ..errors import LinkConfigError
from .base import Link
from .line import LineConfig

__all__ = ["MemHub", "MemLink"]


class MemLink(Link):
    """One end of an in-process link."""

    scheme = "mem"
    url_usage = "mem://NAME[?baud=N&mode=8N1&queue=BYTES]"
    paces_input = False

    def __init__(self, name: str, url: str, line: LineConfig, loop: asyncio.AbstractEventLoop) -> None:
        super().__init__(name, url, line, loop)
        self.peer: MemLink | None = None

    def _write_raw(self, data: bytes) -> None:
        peer = self.peer
        if peer is not None and not peer.closed:
            peer._arrive(data, self._tx_start, self._tx_pitch, self.out_line)
        else:
            self.stats.dropped_out += len(data)


class MemHub:
    """Pairs ``mem://`` ends by name within one emulator instance."""

    def __init__(self) -> None:
        self._waiting: dict[str, MemLink] = {}
        self._pairs: dict[str, tuple[MemLink, MemLink]] = {}

    def attach(self, key: str, link: MemLink) -> None:
        if key in self._pairs:
            raise LinkConfigError(f"mem://{key} already has two ends")
        other = self._waiting.pop(key, None)
        if other is None:
            self._waiting[key] = link
            return
        other.peer, link.peer = link, other
        other.set_remote_line(link.line)
        link.set_remote_line(other.line)
        self._pairs[key] = (other, link)

    def unpaired(self) -> list[str]:
        """Names opened only once (a wiring mistake unless the far end comes later)."""
        return sorted(self._waiting)

    def pair(self, name: str, line: LineConfig, loop: asyncio.AbstractEventLoop,
             line_b: LineConfig | None = None, key: str | None = None) -> tuple[MemLink, MemLink]:
        """Create both ends at once: ``(a, b)``; ``line_b`` lets the two sides differ in baud."""
        key = key or name
        a = MemLink(name, f"mem://{key}", line, loop)
        b = MemLink(name, f"mem://{key}", line_b or line, loop)
        self.attach(key, a)
        self.attach(key, b)
        return a, b
