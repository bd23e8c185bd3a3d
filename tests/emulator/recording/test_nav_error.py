"""Navigation error against truth: the per-phase split (fine alignment vs navigating proper) of the summary."""

from __future__ import annotations

import math

import pytest

from emulator.recording.nav_error import NAV_PHASES, NavVsTruth
from emulator.world.trajectory import StaticTrajectory
from protocols.host import NavMode, NavSolution


def _frame(k: int, heading_deg: float, mode: int) -> NavSolution:
    return NavSolution(seq=k, time_s=0.01 * k, lat_deg=39.98, lon_deg=116.34, height_m=50.0,
                       vel_enu_mps=(0.0, 0.0, 0.0), roll_deg=0.0, pitch_deg=0.0, heading_deg=heading_deg,
                       sigma=(0.1,) * 9, mode=mode, gnss_status=1, psns_status=0, cpu_load_pct=0.2,
                       deadline_misses=0)


def test_fine_alignment_frames_are_their_own_phase_and_coarse_alignment_is_none():
    cmp = NavVsTruth(StaticTrajectory(39.98, 116.34, 50.0))  # truth: level, heading 0
    fine = int(NavMode.ALIGNING | NavMode.NAVIGATING)
    nav = int(NavMode.NAVIGATING)
    frames = ([_frame(k, 5.0, int(NavMode.ALIGNING)) for k in range(10)]  # coarse: no error counted
              + [_frame(10 + k, 2.0, fine) for k in range(30)]
              + [_frame(40 + k, 0.5, nav) for k in range(60)])
    cmp.add([(f.time_s, f) for f in frames])
    by = {ph: {k: v.as_dict() for k, v in e.items()} for ph, e in cmp.errors_by_phase.items()}
    assert tuple(by) == NAV_PHASES
    assert by["fine_alignment"]["heading_deg"] == pytest.approx({"rms": 2.0, "max": 2.0}, abs=1e-6)
    assert by["navigating"]["heading_deg"] == pytest.approx({"rms": 0.5, "max": 0.5}, abs=1e-6)
    # the overall figure still covers both phases (expectations keep their meaning)
    total = cmp.errors["heading_deg"].as_dict()
    assert total["rms"] == pytest.approx(math.sqrt((30 * 4.0 + 60 * 0.25) / 90), abs=1e-6)
    assert cmp.errors["heading_deg"].n == 90


@pytest.mark.parametrize("change", [
    {"roll_deg": math.inf}, {"pitch_deg": -math.inf}, {"heading_deg": math.inf}, {"heading_deg": math.nan},
    {"lat_deg": math.inf}, {"height_m": math.nan}, {"vel_enu_mps": (math.inf, 0.0, 0.0)}, {"time_s": math.inf},
    {"time_s": math.nan}, {"time_s": -math.inf},
])
def test_a_non_finite_frame_is_counted_never_raised(change: dict[str, object]) -> None:
    """Issue 41 item 2: one NAV_SOLUTION of an outside DSP with +-inf roll ended the run (math domain error)."""
    import dataclasses

    cmp = NavVsTruth(StaticTrajectory(39.98, 116.34, 50.0))
    nav = int(NavMode.NAVIGATING)
    frames = [_frame(k, 0.5, nav) for k in range(5)]
    frames[2] = dataclasses.replace(frames[2], **change)  # type: ignore[arg-type]
    cmp.add([(0.01 * k, f) for k, f in enumerate(frames)])
    assert cmp.nonfinite_frames == 1
    for k, v in cmp.errors.items():  # the four good frames only, all finite
        assert v.n == 4, k
        assert all(math.isfinite(x) for x in v.as_dict().values() if x is not None), k
    assert cmp.errors["heading_deg"].as_dict() == pytest.approx({"rms": 0.5, "max": 0.5}, abs=1e-9)
    rows = len(cmp.nav_rows) - 1  # a frame with a finite time keeps its row (empty cells for inf/nan)
    assert rows == (4 if "time_s" in change else 5)


def test_the_recorder_reports_non_finite_frames(tmp_path) -> None:
    import dataclasses

    from emulator.recording.recorder import Recorder

    rec = Recorder(tmp_path, StaticTrajectory(39.98, 116.34, 50.0))
    nav = int(NavMode.NAVIGATING)
    for k in range(10):
        f = _frame(k, 0.5, nav)
        rec._on_nav(0.01 * k, dataclasses.replace(f, roll_deg=math.inf) if k in (3, 7) else f)
    assert rec.nav_nonfinite_frames == 2
    assert rec.event_counts.get("nav_nonfinite") == 1
    ev = [e for e in rec.iter_events() if e["event"] == "nav_nonfinite"]
    assert ev[0]["total"] == 2 and ev[0]["source"] == "recorder"
    assert rec.errors["attitude_deg"].n == 8
    rec.close()
