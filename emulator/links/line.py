"""The serial line: its configuration (:class:`LineConfig`) and its timing model (:class:`LineModel`).

Line model (per direction, :class:`LineModel`): an asynchronous serial line at ``baud`` with
``data_bits``, parity and ``stop_bits`` takes ``(1 + data + parity + stop) / baud`` seconds per
byte, so a 40-byte 8N1 frame occupies the line 400/baud s. Bytes written while the line is
busy wait in a bounded TX queue of ``tx_queue_bytes``; what does not fit is lost and counted
(``dropped_out``), as a real UART driver's ring buffer or an FPGA FIFO overflows. A chunk is
delivered to the far end when its last stop bit has been sent.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass
from typing import Any

__all__ = ["LineConfig", "LineModel", "parse_mode"]


def parse_mode(mode: str) -> tuple[int, str, float]:
    """Parse a ``"8N1"``-style frame format into (data bits, parity, stop bits)."""
    m = mode.strip().upper()
    if len(m) < 3 or m[0] not in "5678" or m[1] not in "NEO" or m[2:] not in ("1", "1.5", "2"):
        raise ValueError(f"bad serial mode {mode!r}; expected e.g. 8N1, 8E1, 7O2")
    return int(m[0]), m[1], float(m[2:])


@dataclass(frozen=True)
class LineConfig:
    """Asynchronous serial line parameters of one link end."""

    baud: int = 115200
    data_bits: int = 8
    parity: str = "N"
    stop_bits: float = 1.0
    tx_queue_bytes: int = 4096

    def __post_init__(self) -> None:
        if self.baud <= 0:
            raise ValueError(f"baud must be > 0, got {self.baud}")
        if self.tx_queue_bytes < 1:
            raise ValueError("tx_queue_bytes must be >= 1")
        if self.data_bits not in (5, 6, 7, 8):
            raise ValueError(f"data_bits must be 5..8, got {self.data_bits}")
        if self.parity not in ("N", "E", "O"):
            raise ValueError(f"parity must be N, E or O, got {self.parity!r}")
        if self.stop_bits not in (1.0, 1.5, 2.0):
            raise ValueError(f"stop_bits must be 1, 1.5 or 2, got {self.stop_bits}")

    @property
    def bits_per_byte(self) -> float:
        """Bits on the wire per byte: start + data + parity + stop."""
        return 1 + self.data_bits + (0 if self.parity == "N" else 1) + self.stop_bits

    @functools.cached_property
    def byte_time(self) -> float:
        """Seconds per byte on the wire (kept after the first use: the recorder compares every inbound chunk's
        byte pitch with it)."""
        return self.bits_per_byte / self.baud

    @property
    def bytes_per_second(self) -> float:
        return self.baud / self.bits_per_byte

    @property
    def mode(self) -> str:
        stop = "1.5" if self.stop_bits == 1.5 else str(int(self.stop_bits))
        return f"{self.data_bits}{self.parity}{stop}"

    def with_(self, **kw: Any) -> LineConfig:
        """A copy with some fields changed."""
        d: dict[str, Any] = {"baud": self.baud, "data_bits": self.data_bits, "parity": self.parity,
             "stop_bits": self.stop_bits, "tx_queue_bytes": self.tx_queue_bytes}
        d.update(kw)
        return LineConfig(**d)


class LineModel:
    """Pacing of one direction of a serial line (see module docstring).

    ``free_at`` is the scenario time at which the last admitted byte's stop bit ends.
    """

    __slots__ = ("_bt", "_q", "cfg", "free_at")

    def __init__(self, cfg: LineConfig) -> None:
        self.cfg = cfg
        self.free_at = 0.0
        self._bt = cfg.byte_time
        self._q = cfg.tx_queue_bytes

    def _waiting(self, now: float) -> int:
        """Bytes admitted earlier whose stop bit has not ended by ``now``."""
        fa = self.free_at
        if fa <= now:
            return 0
        return math.ceil((fa - now) / self._bt - 1e-9)

    def admit(self, now: float, n: int, atomic: bool = False) -> tuple[int, float, float]:
        """Queue ``n`` bytes written at once at time ``now``.

        Returns ``(accepted, start, end)``: how many bytes fit in the TX queue (all or none when
        ``atomic``), when the first accepted byte starts on the wire and when the last one's stop
        bit ends.
        """
        bt = self._bt
        fa = self.free_at
        if fa > now:
            start = fa
            room = self._q - math.ceil((fa - now) / bt - 1e-9)
        else:
            start = now
            room = self._q
        if n <= room:
            accepted = n
        elif atomic or room <= 0:
            accepted = 0
        else:
            accepted = room
        end = start + accepted * bt
        if accepted:
            self.free_at = end
        return accepted, start, end

    def admit_cut_through(self, now: float, n: int, in_pitch: float) -> tuple[int, float, float, float]:
        """Queue ``n`` bytes that arrived one every ``in_pitch`` s, the last one at ``now``.

        Byte ``i`` (available at ``a_i = now - (n - 1 - i) in_pitch``) can start only once it has
        arrived and the line is free. Returns ``(accepted, start, end, pitch)``: bytes kept (the
        queue holds ``tx_queue_bytes``; the excess tail is lost), the first byte's start, the
        last stop bit's end and the mean start-to-start spacing of the bytes on the wire.
        """
        bt = self._bt
        a0 = now - (n - 1) * in_pitch
        prior = self._waiting(now)
        start = self.free_at if self.free_at > a0 else a0
        if bt >= in_pitch or n == 1:
            pitch = bt
            end = start + n * bt
        else:
            end = start + n * bt
            last_ready = now + bt
            if last_ready > end:
                end = last_ready
            pitch = (end - bt - start) / (n - 1)
        # bytes of this chunk still waiting at `now` (not yet started)
        started = min(n, int((now - start) / pitch + 1e-09) + 1) if start <= now else 0
        waiting = prior + (n - started)
        accepted = n
        if waiting > self._q:
            accepted = max(0, n - (waiting - self._q))
            if accepted < started:
                accepted = started
            if accepted < n:
                end = start + (accepted - 1) * pitch + bt if accepted else start
        if accepted:
            self.free_at = end
        return accepted, start, end, pitch

    def busy_until(self) -> float:
        return self.free_at
