"""``--force`` empties only a provable run directory, never through a link (issue 41 item 7,
docs/hostile-input.md section 8). Before: one run-file name (``report.html``) was taken as proof, and a
directory holding ``thesis.tex``, ``sub/`` and one ``report.html`` was emptied."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from emulator.recording.rundir import LOCK_NAME, RunDirError, claim_run_dir, is_run_dir, preflight_run_dir

SUMMARY = {"scenario": "quickstart", "run_dir": "runs/x", "interrupted": False, "passed": True}


def _thesis(d: Path) -> Path:
    d.mkdir()
    (d / "thesis.tex").write_text("\\documentclass{article}")
    (d / "sub").mkdir()
    (d / "sub" / "fig.pdf").write_bytes(b"%PDF")
    (d / "report.html").write_text("<html></html>")
    return d


def _tree(d: Path) -> list[str]:
    return sorted(str(p.relative_to(d)) for p in d.rglob("*"))


def test_force_refuses_a_directory_with_only_a_run_file_name(tmp_path):
    d = _thesis(tmp_path / "thesis")
    before = _tree(d)
    for check in (lambda: preflight_run_dir(d, force=True), lambda: claim_run_dir(d, force=True).__enter__()):
        with pytest.raises(RunDirError, match="not a run directory"):
            check()
    assert _tree(d) == before


def test_force_refuses_a_summary_that_is_not_a_run_summary(tmp_path):
    d = _thesis(tmp_path / "d")
    (d / "summary.json").write_text(json.dumps({"title": "my thesis"}))
    assert not is_run_dir(d)
    with pytest.raises(RunDirError, match="not a run directory"):
        preflight_run_dir(d, force=True)


def test_force_replaces_a_run_proven_by_its_summary_or_its_lock(tmp_path):
    by_summary = tmp_path / "a"
    by_summary.mkdir()
    (by_summary / "summary.json").write_text(json.dumps(SUMMARY))
    (by_summary / "nav.csv").write_text("t\n")
    by_lock = tmp_path / "b"  # a run killed (SIGKILL) or stopped at once: no summary, its lock file left
    by_lock.mkdir()
    (by_lock / LOCK_NAME).write_text("4242\n")
    (by_lock / "capture.psnscap").write_bytes(b"PSNSCAP")
    for d in (by_summary, by_lock):
        assert is_run_dir(d)
        with pytest.raises(RunDirError, match="already holds a run"):
            preflight_run_dir(d, force=False)
        with claim_run_dir(d, force=True):
            assert _tree(d) == [LOCK_NAME]


def test_a_lock_created_by_the_claim_itself_proves_nothing(tmp_path):
    d = tmp_path / "d"
    d.mkdir()
    (d / "notes.txt").write_text("mine")
    with pytest.raises(RunDirError, match="not a run directory"):
        claim_run_dir(d, force=True).__enter__()
    assert _tree(d) == ["notes.txt"]  # and the lock file it created is gone again


def test_force_never_acts_through_a_link(tmp_path):
    real = tmp_path / "real"
    real.mkdir()
    (real / "summary.json").write_text(json.dumps(SUMMARY))
    (real / "precious.txt").write_text("x")
    link = tmp_path / "link"
    link.symlink_to(real, target_is_directory=True)
    for check in (lambda: preflight_run_dir(link, force=True), lambda: claim_run_dir(link, force=True).__enter__()):
        with pytest.raises(RunDirError, match="symbolic link"):
            check()
    assert _tree(real) == ["precious.txt", "summary.json"]
    # a summary.json that is a link to a real summary elsewhere is no proof either
    d = _thesis(tmp_path / "d")
    (d / "summary.json").symlink_to(real / "summary.json")
    assert not is_run_dir(d)
    with pytest.raises(RunDirError, match="not a run directory"):
        preflight_run_dir(d, force=True)
