"""``studies.scripts.compare_trees``: two run directories are the same run unless a byte (or a non-wall summary field)
differs."""

from __future__ import annotations

import json

from studies.scripts.compare_trees import compare_run_dirs


def _run_dir(path, nav=b"t,x\r\n0.0,1.5\r\n", **summary):
    path.mkdir()
    (path / "nav.csv").write_bytes(nav)
    (path / "summary.json").write_text(json.dumps({"passed": True, "wall_s": 1.0, "realtime_factor": 30.0,
                                                   "run_dir": str(path), **summary}))
    return path


def test_wall_clock_fields_do_not_count_and_everything_else_does(tmp_path):
    a = _run_dir(tmp_path / "a")
    b = _run_dir(tmp_path / "b", wall_s=2.5, realtime_factor=12.0)
    assert compare_run_dirs(a, b) == []
    assert compare_run_dirs(a, _run_dir(tmp_path / "c", nav=b"t,x\r\n0.0,1.5000000000000002\r\n")) == ["nav.csv"]
    assert compare_run_dirs(a, _run_dir(tmp_path / "d", passed=False)) == ["summary.json"]
    (b / "psns.csv").write_bytes(b"")
    assert compare_run_dirs(a, b) == ["psns.csv"]


def _capture(path, base_dir, records):
    from emulator.recording.capture import CaptureWriter

    w = CaptureWriter(path, {"scenario": "s", "seed": 1, "scenario_base_dir": base_dir}, ["uart1", "uart0"])
    for rec in records:
        w.write(*rec)
    w.close()


def test_captures_compare_by_records_and_header_but_the_tree_path(tmp_path):
    """Two runs in two trees write their tree's path in the capture header and the wall-clock origin in
    clock.json: neither counts; a record, its order or another header field does."""
    recs = [(0, True, 0.005, b"\x93abc"), (1, False, 0.01, b"$GPGGA")]
    runs = []
    for name, base, rs, t0 in (("a", "/tree/a/scenarios", recs, 1.0), ("b", "/tree/b/scenarios", recs, 2.0),
                               ("c", "/tree/a/scenarios", recs[::-1], 1.0),
                               ("d", "/tree/a/scenarios", [recs[0], (1, False, 0.01, b"$GPGGB")], 1.0),
                               ("e", "/tree/a/scenarios", recs[:1], 1.0)):
        d = _run_dir(tmp_path / name)
        _capture(d / "capture.psnscap", base, rs)
        (d / "clock.json").write_text(json.dumps({"mode": "fast", "t0_monotonic_s": t0}))
        runs.append(d)
    a, b, c, d, e = runs
    assert (a / "capture.psnscap").read_bytes() != (b / "capture.psnscap").read_bytes()
    assert compare_run_dirs(a, b) == []
    assert compare_run_dirs(a, c) == compare_run_dirs(a, d) == compare_run_dirs(a, e) == ["capture.psnscap"]
    (b / "clock.json").write_text(json.dumps({"mode": "realtime", "t0_monotonic_s": 2.0}))
    assert compare_run_dirs(a, b) == ["clock.json"]
