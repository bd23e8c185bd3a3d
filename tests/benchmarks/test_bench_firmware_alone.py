"""The real-time-factor table's firmware-alone row (issue 43 item 4): the reference's own capture replayed in fast
mode, the replay's nav.csv byte for byte the reference's, and the row's figures are the replay's."""

from __future__ import annotations

from pathlib import Path

from benchmarks.bench_realtime_factor import REFERENCE, _timed, firmware_alone
from emulator.scenario import load_scenario

#: simulated seconds: past the 2 s coarse alignment, so the firmware navigates and writes nav rows
CUT_S = 3.0


def test_firmware_alone_replays_the_reference_capture_to_the_same_nav(tmp_path: Path) -> None:
    scn = load_scenario(REFERENCE).model_copy(update={"duration_s": CUT_S})
    cpus: list[float] = []
    _wall, walls, s = _timed(scn, 1, keep=tmp_path, cpus=cpus)
    assert (tmp_path / "capture.psnscap").stat().st_size > 0 and len(walls) == len(cpus) == 1
    fcpus: list[float] = []
    fwall, fwalls, fs, same = firmware_alone(tmp_path, 2, fcpus)
    assert same  # the replay computed what the reference did
    assert len(fwalls) == len(fcpus) == 2 and fwall > 0
    assert fs["replay"]["records"] > 0 and fs["sim_duration_s"] == s["sim_duration_s"]
    assert fs["nav_frames"] == s["nav_frames"] > 0


def test_firmware_alone_sees_a_different_nav(tmp_path: Path) -> None:
    scn = load_scenario(REFERENCE).model_copy(update={"duration_s": CUT_S})
    _timed(scn, 1, keep=tmp_path)
    nav = tmp_path / "nav.csv"
    nav.write_text(nav.read_text() + "0\n")  # not the reference's any more
    assert not firmware_alone(tmp_path, 1)[3]
