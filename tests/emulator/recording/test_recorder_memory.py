"""Bounded event memory (docs/hostile-input.md): a flood of host commands for 60 s of emulated time (every command
an event, as the firmware reports them) keeps the recorder's memory flat; events.jsonl still holds every event and
event expectations see all of them.

Before: the recorder kept every event in a list besides events.jsonl (62 MB per 60 s of status-command flood)."""

from __future__ import annotations

import gc
import tracemalloc

from emulator.recording.recorder import Recorder
from emulator.world.trajectory import StaticTrajectory

#: host link at 115200 baud, 8N1, a 10-byte command: the most commands a peer can send per second
COMMANDS_PER_S = 115200 // (10 * 10)


def _flood(rec: Recorder, t0: float, t1: float) -> None:
    n = round((t1 - t0) * COMMANDS_PER_S)
    for k in range(n):
        t = t0 + k / COMMANDS_PER_S
        rec.emit(t, "firmware", "command", command="RequestStatus", seq=k & 0xFFFF, t_fpga_s=t, accepted=True)
        rec.emit(t, "firmware", "status_sent", seq=k & 0xFFFF, t_fpga_s=t)


def test_a_60_s_command_flood_keeps_the_recorder_memory_flat(tmp_path):
    rec = Recorder(tmp_path / "run", StaticTrajectory(39.98, 116.34, 50.0))
    try:
        _flood(rec, 0.0, 10.0)  # warm-up: the tail fills
        gc.collect()
        tracemalloc.start()
        base, _ = tracemalloc.get_traced_memory()
        _flood(rec, 10.0, 60.0)
        gc.collect()
        now, _ = tracemalloc.get_traced_memory()
        tracemalloc.stop()
        assert now - base < 1_000_000, f"grew {(now - base) / 1e6:.1f} MB in 50 s of flood"
        assert len(rec.events) <= Recorder.EVENTS_TAIL
        total = 2 * round(60.0 * COMMANDS_PER_S)
        assert rec.events_total == total
        assert sum(1 for _ in rec.iter_events()) == total  # all of them on disk, streamed back
    finally:
        rec.close()
