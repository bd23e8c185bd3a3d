"""Issue 19 (a newcomer's first hour): run directories as a resource, ``--json`` as one document, strict JSON."""

import fcntl
import json
import os

from tests.emulator.cli.test_cli import psns_hil, short_quickstart


def _scenario(tmp_path):
    return short_quickstart(tmp_path, "expectations:\n  - link: {name: uart1, counter: crc_errors, max: 0}\n")


def test_file_as_out_is_exit_2(tmp_path):
    f = tmp_path / "notadir.txt"
    f.write_text("x")
    r = psns_hil("run", _scenario(tmp_path), "--out", str(f), "--quiet")
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert "not a directory" in r.stderr and f.read_text() == "x"


def test_busy_run_dir_is_refused_naming_the_pid(tmp_path):
    out = tmp_path / "run"
    out.mkdir()
    lock = out / ".psns-hil.lock"
    fd = os.open(lock, os.O_RDWR | os.O_CREAT)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        os.write(fd, b"4242\n")
        r = psns_hil("run", _scenario(tmp_path), "--out", str(out), "--quiet")
    finally:
        os.close(fd)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert "in use" in r.stderr and "pid 4242" in r.stderr
    assert sorted(p.name for p in out.iterdir()) == [".psns-hil.lock"]


def test_finished_run_dir_needs_force_and_is_cleaned_no_symlink_followed(tmp_path):
    scn = _scenario(tmp_path)
    out = tmp_path / "run"
    r = psns_hil("run", scn, "--out", str(out), "--quiet", "--no-report")
    assert r.returncode == 0, r.stderr
    before = (out / "summary.json").read_text()
    r = psns_hil("run", scn, "--out", str(out), "--quiet")
    assert r.returncode == 2 and "already holds a run" in r.stderr and "--force" in r.stderr
    assert (out / "summary.json").read_text() == before
    # a stale file and a symlink planted in it: --force removes them and never writes through the link
    victim = tmp_path / "victim.csv"
    victim.write_text("precious\n")
    (out / "truth.csv").unlink()
    (out / "truth.csv").symlink_to(victim)
    (out / "stale.txt").write_text("old")
    r = psns_hil("run", scn, "--out", str(out), "--quiet", "--force")
    assert r.returncode == 0, r.stderr
    assert victim.read_text() == "precious\n"
    assert not (out / "truth.csv").is_symlink() and not (out / "stale.txt").exists()
    assert not (out / ".psns-hil.lock").exists()


def test_non_run_directory_is_not_written_into(tmp_path):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "notes.txt").write_text("mine")
    r = psns_hil("run", _scenario(tmp_path), "--out", str(out), "--quiet", "--force")
    assert r.returncode == 2 and "not a run directory" in r.stderr
    assert [p.name for p in out.iterdir()] == ["notes.txt"]


def test_run_json_stdout_is_exactly_one_strict_json_document(tmp_path):
    out = tmp_path / "run"
    for extra in ((), ("--quiet",)):
        r = psns_hil("run", _scenario(tmp_path), "--out", str(out), "--json", "--force", *extra)
        assert r.returncode == 0, r.stderr
        doc = json.loads(r.stdout, parse_constant=lambda c: (_ for _ in ()).throw(ValueError(c)))
        assert doc["scenario"] and doc["passed"] is True
        assert "running" in r.stderr and "ports:" in r.stderr
    json.loads((out / "summary.json").read_text(), parse_constant=lambda c: (_ for _ in ()).throw(ValueError(c)))


def test_strict_json_nan_as_null_with_flag():
    from emulator.recording.formatting import strict_json

    doc = json.loads(strict_json({"a": {"max": float("nan"), "rms": 1.0}, "b": [float("inf")]}))
    assert doc["a"]["max"] is None and doc["a"]["rms"] == 1.0 and doc["b"] == [None]
    assert doc["non_finite"] == ["a.max", "b[0]"]
