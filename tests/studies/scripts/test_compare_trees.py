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
