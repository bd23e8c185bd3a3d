"""A callback that was already due when a realtime run stopped may still emit an event: the closed recorder counts
it and drops it (before: `ValueError: I/O operation on closed file` from a late deadline_miss, an error in the loop)."""

from __future__ import annotations

import json

from emulator.recording.recorder import Recorder
from emulator.world.trajectory import StaticTrajectory


def test_an_event_after_close_is_counted_not_written(tmp_path):
    rec = Recorder(tmp_path / "run", StaticTrajectory(39.98, 116.34, 50.0))
    rec.emit(1.0, "dsp", "deadline_miss", cycles=10)
    rec.close()
    rec.emit(2.0, "dsp", "deadline_miss", cycles=11)
    assert rec.events_after_close == 1 and rec.events_total == 1
    lines = (tmp_path / "run" / "events.jsonl").read_text().splitlines()
    assert [json.loads(ln)["t_s"] for ln in lines] == [1.0]
