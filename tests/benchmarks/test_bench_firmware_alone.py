"""The real-time-factor table's firmware-alone rows (issue 43 item 4): the reference's own capture replayed in fast
mode, the replay's nav.csv byte for byte the reference's, and the row's figures are the replay's; the reference's
firmware timed per tick (and by part) inside such a replay."""

from __future__ import annotations

from pathlib import Path

from benchmarks.bench_firmware import PARTS, firmware_in_replay, timed_methods
from benchmarks.bench_realtime_factor import REFERENCE, _timed, firmware_alone
from emulator.postrun.replay import same_file
from emulator.scenario import load_scenario
from firmware_model import Firmware

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


class _Counter:
    def __init__(self) -> None:
        self.calls = 0

    def step(self, k: int) -> int:
        self.calls += k
        return self.calls


def test_timed_methods_times_at_the_class_passes_calls_through_and_restores() -> None:
    orig = _Counter.__dict__["step"]
    c = _Counter()
    with timed_methods({"step": (_Counter, "step")}) as acc:
        assert _Counter.__dict__["step"] is not orig
        assert [c.step(2), c.step(k=3)] == [2, 5]  # the arguments, keywords too, and the results pass through
    assert _Counter.__dict__["step"] is orig and c.step(1) == 6
    assert acc["step"] > 0.0
    try:
        with timed_methods({"step": (_Counter, "step")}):
            raise RuntimeError("a failing run")
    except RuntimeError:
        pass
    assert _Counter.__dict__["step"] is orig  # restored on an exception too


def test_firmware_in_replay_times_the_reference_firmware_on_its_capture(tmp_path: Path) -> None:
    scn = load_scenario(REFERENCE).model_copy(update={"duration_s": CUT_S})
    kept = tmp_path / "kept"
    kept.mkdir()
    _timed(scn, 1, keep=kept)
    ticks = round(CUT_S * scn.sensors.imu.rate_hz)
    us = firmware_in_replay(kept / "capture.psnscap", tmp_path, ticks)
    assert set(us) == {"total", *PARTS}
    # both timed replays computed what the reference did (the timers pass every call through)
    assert same_file(kept / "nav.csv", tmp_path / "a" / "nav.csv")
    assert same_file(kept / "nav.csv", tmp_path / "b" / "nav.csv")
    assert all(us[p] > 0.0 for p in PARTS)  # each part ran (the 3 s cut navigates and writes nav rows)
    assert us["total"] > us["decode"]  # service runs beside receive
    # receive + service of one replay against the parts of the other: the same work, within a factor for noise
    assert 0.3 < sum(us[p] for p in PARTS) / us["total"] < 3.0
    assert Firmware.__dict__["service"].__name__ == "service"  # the class has its method back
