"""Link faults: in the links' byte hooks (bit errors, drops, noise, disconnects, stalls) and baud mismatches."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from ..links.base import Link
from ..links.line import LineConfig
from .base import Injector, bind_error, injects
from .targets import FaultTargets

__all__ = ["LinkBaudMismatch", "LinkBitErrors", "LinkByteDrops", "LinkDisconnect", "LinkNoiseBurst", "LinkStall"]


def _link(targets: FaultTargets, kind: str, name: str) -> Link:
    link = targets.links.get(name)
    if link is None:
        raise bind_error(kind, f"no link {name!r} (links: {', '.join(targets.links)})")
    return link


class ByteFault(Injector):
    """Base of the faults that sit in a link's byte hooks (``Link.faults_in`` / ``faults_out``)."""

    directions: tuple[str, ...] = ()

    def __init__(self, *a: Any) -> None:
        super().__init__(*a)
        self.link = _link(self.targets, self.kind, self.spec.link)
        if not self.directions:
            self.directions = ("in",) if self.spec.effective_direction() == "to_dsp" else ("out",)
        self._acc = {k: 0 for k in self.effect_keys}

    @property
    def target(self) -> str:
        d = getattr(self.spec, "effective_direction", None)
        return f"link {self.spec.link}" + (f" {d()}" if d is not None else "")

    def on(self, t: float) -> None:
        for d in self.directions:
            (self.link.faults_in if d == "in" else self.link.faults_out).append(self)

    def off(self, t: float) -> None:
        for d in self.directions:
            hooks = self.link.faults_in if d == "in" else self.link.faults_out
            if self in hooks:
                hooks.remove(self)

    def count(self, key: str, n: int) -> None:
        self._acc[key] = self._acc.get(key, 0) + n
        st = self.link.stats
        st.faults[self.kind] = st.faults.get(self.kind, 0) + n
        if key == "bytes_corrupted":
            st.corrupted_bytes += n

    def apply(self, link: Link, direction: str, t: float, data: bytes) -> bytes:  # ByteFault
        raise NotImplementedError


@injects("link_bit_errors")
class LinkBitErrors(ByteFault):
    """Bits flip at ``ber`` per bit on the wire. A flipped data bit corrupts the byte; a flipped start or
    stop bit is a framing error and a flipped parity bit a parity error (the receiver drops the byte)."""

    effect_keys: tuple[str, ...] = ("bytes_corrupted", "framing_errors", "parity_errors")

    def _ber(self) -> float:
        return float(self.spec.ber)

    def apply(self, link: Link, direction: str, t: float, data: bytes) -> bytes:
        return self._flip(link, data, self._ber())

    def _flip(self, link: Link, data: bytes, ber: float) -> bytes:
        line = link.line
        nd = line.data_bits
        has_par = line.parity != "N"
        bpb = int(1 + nd + (1 if has_par else 0) + math.ceil(line.stop_bits))
        n = len(data)
        k = int(self.rng.binomial(n * bpb, ber))
        if k == 0:
            return data
        pos = self.rng.integers(0, n * bpb, k)
        out = bytearray(data)
        lost = np.zeros(n, dtype=bool)
        flipped = np.zeros(n, dtype=bool)
        fe = pe = 0
        for p in pos.tolist():
            i, b = divmod(p, bpb)
            if b == 0 or b >= 1 + nd + (1 if has_par else 0):  # start or stop bit
                if not lost[i]:
                    fe += 1
                lost[i] = True
            elif has_par and b == 1 + nd:
                if not lost[i]:
                    pe += 1
                lost[i] = True
            else:
                out[i] ^= 1 << (b - 1)
                flipped[i] = True
        corrupted = int(np.count_nonzero(flipped & ~lost))
        if corrupted:
            self.count("bytes_corrupted", corrupted)
        if fe:
            self.count("framing_errors", fe)
            link.stats.framing_errors += fe
        if pe:
            self.count("parity_errors", pe)
            link.stats.parity_errors += pe
        if lost.any():
            return bytes(b for b, gone in zip(out, lost.tolist()) if not gone)
        return bytes(out)


@injects("link_byte_drops")
class LinkByteDrops(ByteFault):
    effect_keys: tuple[str, ...] = ("bytes_dropped",)

    def apply(self, link: Link, direction: str, t: float, data: bytes) -> bytes:
        n = len(data)
        k = int(self.rng.binomial(n, float(self.spec.probability)))
        if k == 0:
            return data
        gone = set(self.rng.choice(n, size=k, replace=False).tolist())
        self.count("bytes_dropped", k)
        if direction == "in":
            link.stats.dropped_in += k
        else:
            link.stats.dropped_out += k
        return bytes(b for i, b in enumerate(data) if i not in gone)


@injects("link_noise_burst")
class LinkNoiseBurst(LinkBitErrors):
    effect_keys: tuple[str, ...] = ("bytes_corrupted", "framing_errors", "parity_errors", "spurious_bytes")

    def apply(self, link: Link, direction: str, t: float, data: bytes) -> bytes:
        out = self._flip(link, data, float(self.spec.ber))
        lam = float(self.spec.spurious_per_byte) * len(data)
        m = int(self.rng.poisson(lam)) if lam > 0 else 0
        if m == 0:
            return out
        buf = bytearray(out)
        junk = self.rng.integers(0, 256, m).tolist()
        where = np.sort(self.rng.integers(0, len(buf) + 1, m))[::-1].tolist()
        for w, b in zip(where, junk):
            buf.insert(w, b)
        self.count("spurious_bytes", m)
        return bytes(buf)


@injects("link_disconnect")
class LinkDisconnect(ByteFault):
    effect_keys: tuple[str, ...] = ("bytes_lost",)
    directions = ("in", "out")

    @property
    def target(self) -> str:
        return f"link {self.spec.link} (both directions)"

    def apply(self, link: Link, direction: str, t: float, data: bytes) -> bytes:
        n = len(data)
        self.count("bytes_lost", n)
        if direction == "in":
            link.stats.dropped_in += n
        else:
            link.stats.dropped_out += n
        return b""


@injects("link_stall")
class LinkStall(ByteFault):
    """Bytes wait while the line is stalled, up to the transmitter's queue; the rest is lost. They go on
    when the stall ends (delivered at that instant: the line's pacing of the backlog is not modelled)."""

    effect_keys: tuple[str, ...] = ("bytes_held", "bytes_dropped")

    def __init__(self, *a: Any) -> None:
        super().__init__(*a)
        peer = getattr(self.link, "peer", None)
        if self.directions == ("in",) and peer is not None:
            self.capacity = peer.line.tx_queue_bytes
        else:
            self.capacity = self.link.line.tx_queue_bytes
        self.held = bytearray()

    def apply(self, link: Link, direction: str, t: float, data: bytes) -> bytes:
        room = self.capacity - len(self.held)
        keep = data[:max(room, 0)]
        lost = len(data) - len(keep)
        if keep:
            self.held += keep
            self.count("bytes_held", len(keep))
        if lost:
            self.count("bytes_dropped", lost)
            if direction == "in":
                link.stats.dropped_in += lost
            else:
                link.stats.dropped_out += lost
        return b""

    def off(self, t: float) -> None:
        super().off(t)
        held, self.held = bytes(self.held), bytearray()
        if held:
            self.link.deliver_held(self.directions[0], held)


@injects("link_baud_mismatch")
class LinkBaudMismatch(Injector):
    effect_keys: tuple[str, ...] = ("framing_errors", "parity_errors")

    def __init__(self, *a: Any) -> None:
        super().__init__(*a)
        self.link = _link(self.targets, self.kind, self.spec.link)
        peer = getattr(self.link, "peer", None)
        self.tx: LineConfig = peer.line if peer is not None else self.link.line
        s = self.spec
        base = self.link.line.baud
        baud = s.rx_baud if s.rx_baud is not None else round(base * (1.0 + s.baud_error_pct / 100.0))
        self.rx = self.link.line.with_(baud=max(1, baud))

    @property
    def target(self) -> str:
        return f"link {self.spec.link} receiver at {self.rx.baud} baud (transmitter {self.tx.baud})"

    def on(self, t: float) -> None:
        self.link.set_remote_line(self.tx, self.rx)

    def off(self, t: float) -> None:
        self.link.set_remote_line(self.tx)

    def _counts(self) -> dict[str, int]:
        st = self.link.stats
        return {"framing_errors": st.framing_errors, "parity_errors": st.parity_errors}
