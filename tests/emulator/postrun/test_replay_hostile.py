"""Replay of a crafted capture (issue 41 item 2): the sentences that once raised OverflowError out of the decoders
(tests/fuzz/corpus/), inserted into a run's GNSS UART input, are counted by the firmware's decoder; the replay runs
to its end and writes its summary (before the fix the firmware's GNSS decoder stuck on the first of them)."""

from __future__ import annotations

import json
from pathlib import Path

from emulator.assembly.session import run_scenario
from emulator.postrun.replay import run_replay
from emulator.recording.capture import CaptureWriter, read_capture
from emulator.scenario import load_scenario

SCENARIOS = Path(__file__).resolve().parents[3] / "scenarios"
CORPUS = Path(__file__).resolve().parents[2] / "fuzz" / "corpus" / "nmea_hostile_fields.nmea"


def test_replay_of_a_capture_with_hostile_sentences(tmp_path: Path) -> None:
    scn = load_scenario(SCENARIOS / "quickstart.yaml").model_copy(update={"duration_s": 4.0})
    run_scenario(scn, tmp_path / "run", mode="fast")
    header, records = read_capture(tmp_path / "run" / "capture.psnscap")
    links = [str(x) for x in header["links"]]
    assert "uart3" in links
    cases = [c + b"\r\n" for c in CORPUS.read_bytes().split(b"\r\n") if c]
    crafted = tmp_path / "crafted.psnscap"
    w = CaptureWriter(crafted, header, links)
    inserted = 0
    for r in records:
        if r.link == "uart3" and r.direction == "in" and inserted < len(cases) and r.t_s > 1.0:
            w.write(links.index("uart3"), True, r.t_s - 1e-4, cases[inserted])  # just before a real burst
            inserted += 1
        w.write(links.index(r.link), r.direction == "in", r.t_s, r.data, r.pitch_s)
    w.close()
    assert inserted >= 2
    summary = run_replay(crafted, tmp_path / "replay", mode="fast")
    uart3 = summary["firmware"]["decoders"]["uart3"]
    assert json.loads((tmp_path / "replay" / "summary.json").read_text())["firmware"]["decoders"]["uart3"] == uart3
    assert uart3["parse_errors"] == inserted and uart3["format_faults"] == 0
    assert uart3["per_format"]["nmea"] >= 2 * inserted  # the receiver's own sentences after each still decode
    nav_rows = (tmp_path / "replay" / "nav.csv").read_text().count("\n") - 1
    assert nav_rows > 300  # the replay ran on (200 Hz output over 4 s, minus alignment gaps)
