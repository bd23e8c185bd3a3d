"""Bounded memory end to end (docs/hostile-input.md section 8): a peer floods the host port with status requests as
fast as the port takes them for 60 s of emulated time (memory measured over the last 30 s); the whole emulator (link
queues, FPGA, firmware, recorder) keeps its memory flat, every command is executed or counted, and the navigation
goes on.

The recorder-level test (tests/emulator/recording/test_recorder_memory.py) covers the event store alone; this one
sends real command frames through the host link, the FPGA and the DSP's UART0."""

from __future__ import annotations

import gc
import tracemalloc

import pytest

from emulator.testing import start_emulator
from protocols.host import NavMode, NavSolution, RequestStatus, encode_command
from tests.conftest import ROOT

#: one RequestStatus frame on the wire, and how many the host line carries per 0.1 s (8N1: 10 bits per byte)
FRAME = encode_command(RequestStatus(token=0))


@pytest.mark.slow
@pytest.mark.psns_emulator
async def test_a_60_s_status_flood_on_the_host_port_keeps_memory_flat(tmp_path):
    overrides = {"duration_s": 70.0, "sensors.camera.enabled": False, "links.psns": None,
                 "expectations": []}
    async with start_emulator(ROOT / "scenarios" / "quickstart.yaml", run_dir=tmp_path / "run",
                              overrides=overrides) as emu:
        baud = emu.emulator.links["host"].line.baud
        per_tick = max(1, round(0.1 * baud / (10 * len(FRAME))))

        async def flood(seconds: float) -> int:
            sent = 0
            for _ in range(round(seconds / 0.1)):
                accepted = emu.send("host", b"".join(encode_command(RequestStatus(token=(sent + j) & 0xFFFF))
                                                     for j in range(per_tick)))
                sent += accepted // len(FRAME)  # the port takes what its transmit buffer holds, like a write()
                await emu.run_for(0.1)
                for w in emu.watchers.values():  # read what the ports carried, as peers do (the harness keeps
                    w.buf.clear()                # up to 1 MB and 8192 frames per port unread, which would fill
                    w.frames.clear()             # for minutes and hide what the emulator itself keeps)
            return sent

        tracemalloc.start()  # from the start: blocks that the warm-up allocated and the flood frees are counted
        try:
            warm = await flood(30.0)  # warm-up: queues and the recorder's event tail (4096 events) fill up
            gc.collect()
            before, _ = tracemalloc.get_traced_memory()
            sent = await flood(30.0)
            gc.collect()
            grew = tracemalloc.get_traced_memory()[0] - before
        finally:
            tracemalloc.stop()
        nav = await emu.wait_for_frame("host", lambda f: isinstance(f, NavSolution), timeout=1.0)
        counters = dict(emu.fw.counters)
    # about 1.4 MB of command bytes arrived in those 30 s; what stays may not scale with them (the recorder's error
    # series, 56 bytes per nav frame, about 170 kB here, is the one thing that grows with the run's length)
    assert sent * len(FRAME) > 1_000_000
    assert grew < 1_000_000, f"memory grew {grew / 1e6:.2f} MB during a 30 s flood of {sent} commands"
    assert nav.mode & NavMode.NAVIGATING
    # every command is executed or counted as dropped (the firmware executes a bounded number per tick)
    handled = sum(counters.get(k, 0) for k in ("commands_accepted", "commands_rejected", "commands_dropped"))
    assert warm + sent - 2 * per_tick <= handled <= warm + sent, counters
    assert counters["commands_dropped"] > 0
