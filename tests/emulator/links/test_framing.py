"""Baud / format mismatch: what a 16550-style receiver samples from another transmitter."""

from __future__ import annotations

import asyncio
import math

import numpy as np
import pytest

from emulator.clock import EmulatorLoop
from emulator.links import LineConfig, MemHub
from emulator.links.framing import UartReceiver, baud_tolerance, uart_compatible


def test_tolerance_window_for_8n1_is_derived_from_the_stop_bit_sample():
    # stop bit index N = 9, sampled at (N + 1/2 + 1/32) T_rx; it must land in [N, N+1) T_tx
    lo, hi = baud_tolerance(LineConfig())
    assert lo == pytest.approx((9 + 17 / 32) / 10 - 1)  # receiver slower by up to 4.69 %
    assert hi == pytest.approx((9 + 17 / 32) / 9 - 1)
    assert -0.05 < lo < -0.045 and 0.055 < hi < 0.06
    # 8E1 has one more bit before the stop bit: a narrower window
    lo_e, hi_e = baud_tolerance(LineConfig(parity="E"))
    assert lo < lo_e and hi_e < hi


def test_compatibility_fast_path():
    base = LineConfig(baud=115200)
    assert uart_compatible(base, base)
    assert uart_compatible(base, base.with_(baud=int(115200 * 1.04)))
    assert uart_compatible(base, base.with_(baud=int(115200 * 0.96)))
    assert not uart_compatible(base, base.with_(baud=int(115200 * 1.07)))
    assert not uart_compatible(base, base.with_(baud=int(115200 * 0.94)))
    assert not uart_compatible(base, base.with_(parity="E"))
    assert not uart_compatible(base, base.with_(data_bits=7))
    assert uart_compatible(base.with_(stop_bits=2.0), base)  # a receiver checks one stop bit


def _reference_receive(tx: LineConfig, rx: LineConfig, data: bytes, grid: int = 4096) -> list[int]:
    """Independent receiver: the waveform on a fine integer grid, a sample-by-sample state machine.

    Time unit = T_rx / grid. The edge is seen ``grid/32`` units after it occurs (the same mean
    detection delay as the model), then bit k is sampled at ``edge + (k + 1/2) * grid + grid/32``.
    """
    t_tx = grid * rx.baud / tx.baud  # one transmitted bit, in grid units (float)
    bits_tx = []
    for v in data:
        frame = [0] + [(v >> k) & 1 for k in range(tx.data_bits)]
        if tx.parity != "N":
            p = bin(v).count("1") & 1
            frame.append(p if tx.parity == "E" else p ^ 1)
        frame += [1] * round(tx.stop_bits * 2)  # half-bit resolution for 1.5 stop bits
        bits_tx.append(frame)

    def level(u: float) -> int:
        pos = 0.0
        for frame in bits_tx:
            nbits = len(frame) - round(tx.stop_bits * 2) + tx.stop_bits
            dur = nbits * t_tx
            if u < pos + dur:
                j = int((u - pos) // t_tx)
                return frame[j] if j < len(frame) else 1
            pos += dur
        return 1

    total = sum((len(f) - round(tx.stop_bits * 2) + tx.stop_bits) * t_tx for f in bits_tx)
    n_stop = 1 + rx.data_bits + (0 if rx.parity == "N" else 1)
    out: list[int] = []
    u = 0.0
    step = grid / 64
    forced = None
    while u < total + 2 * grid * n_stop:
        if forced is None:
            if level(u) != 0:
                u += step
                continue
            # find the exact edge by bisection between u - step and u
            a, b = u - step, u
            for _ in range(60):
                m = (a + b) / 2
                if level(m) == 0:
                    b = m
                else:
                    a = m
            ts = b + grid / 2 + grid / 32
            if level(ts) != 0:
                u = ts
                continue
        else:
            ts = forced
            forced = None
        v = sum(level(ts + (k + 1) * grid) << k for k in range(rx.data_bits))
        ok = True
        if rx.parity != "N":
            p = bin(v).count("1") & 1
            want = p if rx.parity == "E" else p ^ 1
            ok = level(ts + (rx.data_bits + 1) * grid) == want
        t_stop = ts + n_stop * grid
        if level(t_stop) == 0:
            forced = t_stop
        elif ok:
            out.append(v)
        u = t_stop
    return out


@pytest.mark.parametrize("ratio", [1.0, 0.97, 1.03, 0.93, 1.08, 0.85, 1.2, 0.6])
@pytest.mark.parametrize("fmt", [("8N1", "8N1"), ("8E1", "8N1"), ("8N1", "8O1"), ("7N1", "8N1"), ("8N2", "8N1")])
def test_receiver_model_matches_an_independent_sampler(ratio, fmt):
    rng = np.random.default_rng(3)
    data = rng.integers(0, 256, 60, dtype=np.uint8).tobytes() + b"\xff\x00\x55\xaa"
    from emulator.links import parse_mode

    dt, pt, st = parse_mode(fmt[0])
    dr, pr, sr = parse_mode(fmt[1])
    tx = LineConfig(baud=100000, data_bits=dt, parity=pt, stop_bits=st)
    rx = LineConfig(baud=round(100000 * ratio), data_bits=dr, parity=pr, stop_bits=sr)
    if dt < 8:
        data = bytes(b & ((1 << dt) - 1) for b in data)
    m = UartReceiver(tx, rx)
    m.feed(0.0, data)
    got = [b for _t, b in m.decode(math.inf)]
    assert got == _reference_receive(tx, rx, data)
    if uart_compatible(tx, rx):
        assert got == list(data) and m.framing_errors == 0 and m.parity_errors == 0


def _mismatch_run(rx_ratio: float, n_frames: int = 50) -> tuple[bytes, bytes, dict]:
    loop = EmulatorLoop("fast")
    hub = MemHub()
    tx = LineConfig(baud=115200)
    rx = tx.with_(baud=round(115200 * rx_ratio))
    a, b = hub.pair("x", tx, loop, line_b=rx)
    got = bytearray()
    b.on_receive = got.extend
    rng = np.random.default_rng(11)
    sent = bytearray()

    async def main():
        for _ in range(n_frames):
            frame = rng.integers(0, 256, 40, dtype=np.uint8).tobytes()
            a.send(frame)
            sent.extend(frame)
            await asyncio.sleep(0.002)  # 40 bytes take 3.47 ms: the line stays saturated
        await asyncio.sleep(1.0)

    loop.run_until_complete(main())
    loop.close()
    return bytes(sent), bytes(got), b.stats.as_dict()


def test_mem_link_within_tolerance_delivers_everything():
    for ratio in (0.96, 1.0, 1.05):
        sent, got, st = _mismatch_run(ratio)
        assert got == sent and st["framing_errors"] == 0, ratio


def test_mem_link_beyond_tolerance_sees_framing_errors():
    for ratio in (0.92, 1.08):
        sent, got, st = _mismatch_run(ratio)
        assert st["framing_errors"] > 0, ratio
        assert got != sent
        assert len(got) < len(sent) or got != sent
    # the slow receiver's effect on a stream at line rate: most bytes lost or wrong
    sent, got, st = _mismatch_run(0.85)
    agree = sum(x == y for x, y in zip(sent, got))
    assert agree < 0.5 * len(sent)


def test_pending_byte_completes_on_an_idle_line():
    """A slow receiver's last byte needs samples after the chunk ended: they read idle (high)."""
    loop = EmulatorLoop("fast")
    hub = MemHub()
    tx = LineConfig(baud=100000)
    a, b = hub.pair("x", tx, loop, line_b=tx.with_(baud=94000))  # -6 %: outside tolerance
    got = []
    b.on_receive = lambda d: got.append((loop.time(), bytes(d)))

    async def main():
        a.send(b"\xff")  # 0xFF: only the start bit is low; a late stop sample still reads high
        await asyncio.sleep(0.01)

    loop.run_until_complete(main())
    loop.close()
    assert got and got[0][1] == b"\xff"
    # delivered at the receiver's stop-bit sample, after the transmitter's stop bit ended
    assert got[0][0] == pytest.approx((9 + 17 / 32) / 94000, rel=1e-9)
