"""Pty delivery timing in realtime mode: when does a frame's last byte reach a real reader?

A :class:`~emulator.links.pty.PtyLink` at 460 800 baud (8N1) on a realtime
:class:`~emulator.clock.EmulatorLoop` sends a 109-byte host frame every 10 ms (the nav output),
each paced by the line model (2.37 ms on the wire, written in 1 ms slices). A pyserial reader
time-stamps every read. For each frame the *lateness* is the arrival of its last
byte minus the instant the line model says its last stop bit ends. The reader is a separate
process (pyserial, blocking reads), as a real tool is. Reported: median, p99 and
max over 300 frames, against the raw-pty latency measured without the emulator
(``shared/reference/protocols.md`` 5.2: paced 40-byte frames, median 16 us, p99 121 us).
"""

from __future__ import annotations

import asyncio
import statistics
import tempfile
from pathlib import Path

N_FRAMES = 300
PERIOD_S = 0.01
BAUD = 460800
RAW_PTY_P99_US = 121.0  # protocols.md 5.2, paced frames, reader on the event loop
RAW_PTY_MEDIAN_US = 16.0


_READER = r"""
import sys, time, serial
from protocols.host import HostFormat
from protocols.stream import StreamDecoder
ser = serial.Serial(sys.argv[1], int(sys.argv[2]), timeout=0.2)
dec = StreamDecoder([HostFormat()])
print("ready", flush=True)
idle = 0
while idle < 5:
    try:
        data = ser.read(1)  # blocks until a byte arrives (or the timeout), then takes what is there
    except serial.SerialException:
        break  # the emulator closed the pty
    if not data:
        idle += 1
        continue
    idle = 0
    t = time.monotonic()
    n = ser.in_waiting
    if n:
        data += ser.read(n)
    for f in dec.feed(data):
        print(t, int.from_bytes(f.payload[:4], "little"))
"""


def _measure() -> list[float]:
    import subprocess
    import sys

    from emulator.clock import EmulatorLoop
    from emulator.links import LineConfig
    from emulator.links.pty import PtyLink
    from protocols.host import build_host_frame

    loop = EmulatorLoop("realtime")
    asyncio.set_event_loop(loop)
    expected: dict[int, float] = {}  # seq -> CLOCK_MONOTONIC time its last stop bit ends
    out: list[str] = []

    async def main() -> None:
        with tempfile.TemporaryDirectory() as d:
            link = PtyLink("host", "pty://host", LineConfig(baud=BAUD), loop, target="host", run_dir=Path(d) / "ports")
            await link.open()
            # the reader is another process, as a real tool would be (CLOCK_MONOTONIC is system-wide)
            proc = await asyncio.create_subprocess_exec(sys.executable, "-c", _READER, str(link.link_path), str(BAUD),
                                                        stdout=asyncio.subprocess.PIPE)
            assert proc.stdout is not None
            await proc.stdout.readline()
            while not link.attached:
                await asyncio.sleep(0.005)
            t0 = loop.time() + 0.05
            for k in range(N_FRAMES):
                await asyncio.sleep(max(0.0, t0 + k * PERIOD_S - loop.time()))
                link.send(build_host_frame(0x7F, k.to_bytes(4, "little") + bytes(98)))
                expected[k] = loop._wall0 + link.busy_until() / loop.speed  # noqa: SLF001 - loop time -> monotonic
            await asyncio.sleep(0.05)
            await link.close()
            text, _ = await proc.communicate()
            out.extend(text.decode().splitlines())

    try:
        loop.run_until_complete(main())
    finally:
        asyncio.set_event_loop(None)
        loop.close()
    late = []
    for ln in out:
        t, seq = ln.split()
        if int(seq) in expected:
            late.append((float(t) - expected[int(seq)]) * 1e6)
    return late


def run() -> list[dict]:
    late = sorted(_measure())
    if not late:
        return [{"name": "pty frame lateness", "value": float("nan"), "unit": "us", "baseline": RAW_PTY_P99_US,
                 "ratio": None, "note": "no frame arrived"}]
    p = lambda q: late[min(len(late) - 1, int(q * len(late)))]  # noqa: E731
    med = statistics.median(late)
    return [
        {"name": "pty frame lateness, median", "value": med, "unit": "us", "baseline": RAW_PTY_MEDIAN_US,
         "ratio": med / RAW_PTY_MEDIAN_US, "note": f"{len(late)} frames of 109 B at 460800 baud, 100 Hz, realtime"},
        {"name": "pty frame lateness, p99", "value": p(0.99), "unit": "us", "baseline": RAW_PTY_P99_US,
         "ratio": p(0.99) / RAW_PTY_P99_US, "note": "baseline: raw pty without the emulator (protocols.md 5.2)"},
        {"name": "pty frame lateness, max", "value": late[-1], "unit": "us", "baseline": None, "ratio": None,
         "note": f"min {late[0]:.0f} us (negative = before the modelled end: a read woke mid-frame)"},
    ]


if __name__ == "__main__":  # pragma: no cover
    for row in run():
        print(row)
