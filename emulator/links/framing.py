"""Bit-level model of an asynchronous (16550-style) receiver sampling a transmitter's waveform.

Used only when the two ends of a line disagree (baud rate outside the receiver's tolerance,
or a different number of data bits or parity): then the bytes a device receives are what its
UART samples from the other end's waveform, not what was sent. With matching settings the
links take a fast path and never get here.

Receiver (TL16C550 / C6747 UART with 16x oversampling, SPRS377 section 6.24):

* it hunts for a low level on the line; the start edge is seen on the next tick of its 16x
  sample clock, on average ``T_rx / 32`` after the edge (the model uses that mean, so it is
  deterministic);
* it samples bit ``k`` (0 = start, 1..data = data bits LSB first, then parity, then the first
  stop bit) at ``edge + (k + 1/2 + 1/32) T_rx``; a start bit that reads high there is a false
  start and the hunt goes on from that instant;
* a stop bit that reads low is a **framing error**: the byte is dropped and counted. The 16550
  then assumes the low level is the next start bit, "samples this start bit twice and then
  takes in the data" (TL16C550 datasheet, LSR bit 3), which the model follows;
* a parity mismatch is a **parity error**: dropped and counted;
* after a good stop sample it hunts again from that instant.

Tolerance (derived here, docs/runtime.md "Baud mismatch"): with ``N = 1 + data + parity`` the
stop-bit index, every sample lands in its own transmitted bit if
``N <= (N + 17/32) r < N + 1`` with ``r = T_rx / T_tx``. For 8N1 (``N = 9``) that is a receiver
baud between -4.69 % and +5.90 % of the transmitter's; outside it bytes are corrupted or lost.
"""

from __future__ import annotations

import math
from collections import deque

from .line import LineConfig

__all__ = ["UartReceiver", "baud_tolerance", "uart_compatible"]

#: Mean start-edge detection delay of a 16x-oversampling receiver, in receiver bit times.
DETECT_DELAY_BITS = 1.0 / 32.0
_SAMPLE_OFFSET = 0.5 + DETECT_DELAY_BITS


def _stop_index(cfg: LineConfig) -> int:
    return 1 + cfg.data_bits + (0 if cfg.parity == "N" else 1)


def baud_tolerance(cfg: LineConfig) -> tuple[float, float]:
    """Receiver baud range (as fractions of the transmitter's baud, e.g. ``(-0.049, 0.059)``)
    within which every byte of frame format ``cfg`` is received correctly by the model."""
    n = _stop_index(cfg)
    r_lo = n / (n + _SAMPLE_OFFSET)  # T_rx / T_tx lower bound (receiver fastest)
    r_hi = (n + 1) / (n + _SAMPLE_OFFSET)  # upper bound, exclusive (receiver slowest)
    return 1.0 / r_hi - 1.0, 1.0 / r_lo - 1.0


def uart_compatible(tx: LineConfig, rx: LineConfig) -> bool:
    """True when a receiver set to ``rx`` decodes everything a transmitter set to ``tx`` sends."""
    if tx.data_bits != rx.data_bits or tx.parity != rx.parity:
        return False
    if tx.baud == rx.baud:
        return True
    n = _stop_index(rx)
    r = tx.baud / rx.baud  # T_rx / T_tx
    return n <= (n + _SAMPLE_OFFSET) * r < n + 1


def _parity_bit(value: int, parity: str) -> int:
    ones = bin(value).count("1") & 1
    return ones if parity == "E" else ones ^ 1


class _Segment:
    """Bytes on the wire: byte ``i`` starts at ``t0 + i * pitch`` (idle high in any gap)."""

    __slots__ = ("data", "pitch", "t0", "t_end")

    def __init__(self, t0: float, pitch: float, data: bytes, frame_time: float) -> None:
        self.t0 = t0
        self.pitch = pitch
        self.data = data
        self.t_end = t0 + (len(data) - 1) * pitch + frame_time


class UartReceiver:
    """Decodes the bytes a receiver set to ``rx`` gets from a transmitter set to ``tx``.

    Feed the transmitted chunks in time order (:meth:`feed`), then call :meth:`decode` with
    the time up to which the waveform is final. Counters: ``framing_errors``,
    ``parity_errors``, ``false_starts``, ``bytes_received``.
    """

    def __init__(self, tx: LineConfig, rx: LineConfig) -> None:
        self.tx = tx
        self.rx = rx
        self.t_tx = 1.0 / tx.baud
        self.t_rx = 1.0 / rx.baud
        self._tx_bits = 1 + tx.data_bits + (0 if tx.parity == "N" else 1)  # bits before the stop bit
        self._tx_frame = (self._tx_bits + tx.stop_bits) * self.t_tx
        self._rx_stop = _stop_index(rx)
        self._segs: deque[_Segment] = deque()
        self._t_hunt = -math.inf
        self._forced: float | None = None  # start-bit sample time after a framing error
        self.framing_errors = 0
        self.parity_errors = 0
        self.false_starts = 0
        self.bytes_received = 0

    # -- waveform ----------------------------------------------------------------------------
    def feed(self, t0: float, data: bytes, pitch: float | None = None) -> None:
        """Transmitted bytes; byte ``i`` starts at ``t0 + i * pitch`` (default back to back)."""
        if data:
            self._segs.append(_Segment(t0, pitch if pitch else self._tx_frame, bytes(data), self._tx_frame))

    @property
    def waveform_end(self) -> float:
        """End of the last transmitted stop bit fed so far (``-inf`` if nothing yet)."""
        return self._segs[-1].t_end if self._segs else -math.inf

    def _tx_bit(self, value: int, j: int) -> int:
        if j == 0:
            return 0
        d = self.tx.data_bits
        if j <= d:
            return (value >> (j - 1)) & 1
        if j == d + 1 and self.tx.parity != "N":
            return _parity_bit(value & ((1 << d) - 1), self.tx.parity)
        return 1

    def level(self, t: float) -> int:
        """Line level at time ``t`` (1 = mark/idle)."""
        for s in self._segs:
            if t < s.t0:
                return 1
            if t >= s.t_end:
                continue
            i = int((t - s.t0) // s.pitch)
            if i >= len(s.data):
                i = len(s.data) - 1
            u = t - (s.t0 + i * s.pitch)
            if u >= self._tx_frame:
                return 1
            return self._tx_bit(s.data[i], int(u // self.t_tx))
        return 1

    def _find_low(self, t_from: float) -> float | None:
        """First instant >= ``t_from`` at which the line is low, or None within the waveform."""
        tt = self.t_tx
        for s in self._segs:
            if s.t_end <= t_from:
                continue
            i0 = max(0, int((t_from - s.t0) // s.pitch)) if t_from > s.t0 else 0
            for i in range(i0, len(s.data)):
                b0 = s.t0 + i * s.pitch
                v = s.data[i]
                for j in range(self._tx_bits):
                    c_end = b0 + (j + 1) * tt
                    if c_end <= t_from:
                        continue
                    if self._tx_bit(v, j) == 0:
                        return max(b0 + j * tt, t_from)
        return None

    def _trim(self) -> None:
        while self._segs and self._segs[0].t_end <= self._t_hunt and len(self._segs) > 1:
            self._segs.popleft()

    # -- receiver ----------------------------------------------------------------------------
    def decode(self, final_until: float) -> list[tuple[float, int]]:
        """Bytes the receiver completes using waveform known up to ``final_until``.

        Returns ``(t, byte)`` pairs, ``t`` being the stop-bit sample instant. A byte whose
        samples reach beyond ``final_until`` stays pending until a later call.
        """
        out: list[tuple[float, int]] = []
        trx = self.t_rx
        n_stop = self._rx_stop
        d = self.rx.data_bits
        while True:
            forced = self._forced
            if forced is not None:
                ts = forced
            else:
                t_low = self._find_low(self._t_hunt)
                if t_low is None:
                    if self._segs:
                        self._t_hunt = max(self._t_hunt, min(final_until, self.waveform_end))
                    break
                ts = t_low + _SAMPLE_OFFSET * trx
            t_stop = ts + n_stop * trx
            if t_stop > final_until:
                break
            self._forced = None
            if forced is None and self.level(ts) != 0:
                self.false_starts += 1
                self._t_hunt = ts
                continue
            value = 0
            for k in range(d):
                value |= self.level(ts + (k + 1) * trx) << k
            parity_ok = True
            if self.rx.parity != "N":
                parity_ok = self.level(ts + (d + 1) * trx) == _parity_bit(value, self.rx.parity)
            if self.level(t_stop) == 0:
                self.framing_errors += 1
                self._forced = t_stop
                self._t_hunt = t_stop
            elif not parity_ok:
                self.parity_errors += 1
                self._t_hunt = t_stop
            else:
                out.append((t_stop, value))
                self.bytes_received += 1
                self._t_hunt = t_stop
            self._trim()
        return out

    def pending_until(self) -> float | None:
        """The instant a pending byte needs the waveform until (None if nothing pending)."""
        if self._forced is not None:
            return self._forced + self._rx_stop * self.t_rx
        t_low = self._find_low(self._t_hunt)
        if t_low is None:
            return None
        return t_low + (_SAMPLE_OFFSET + self._rx_stop) * self.t_rx
