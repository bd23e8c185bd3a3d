"""Issue 19 (a newcomer's first hour): run directories as a resource, ``--json`` as one document, strict JSON."""

import fcntl
import json
import os
from pathlib import Path

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


def _with(tmp_path, changes: dict, name="s2.yaml"):
    import yaml

    data = yaml.safe_load(Path(_scenario(tmp_path)).read_text())
    for dotted, value in changes.items():
        *head, last = dotted.split(".")
        node = data
        for k in head:
            node = node.setdefault(k, {})
        if value is None:  # None removes the key
            node.pop(last, None)
        else:
            node[last] = value
    p = tmp_path / name
    p.write_text(yaml.safe_dump(data))
    return str(p)


def test_validate_catches_a_camera_without_its_link(tmp_path):
    # the quickstart carries the camera and its link: take the link away
    p = _with(tmp_path, {"sensors.camera": {"preset": "reference"}, "links.psns": None})
    r = psns_hil("validate", p)
    assert r.returncode == 2 and "links.psns" in r.stderr and "sensors.camera" in r.stderr


def test_validate_catches_missing_files_devices_and_shared_ptys(tmp_path):
    p = _with(tmp_path, {"sensors.gnss.recorded": {"file": "nosuch.csv"}, "links.host": {"url": "pty://same"},
                        "links.gnss": {"url": "pty://same"}, "links.gyro": {"url": "serial:///dev/ttyNOSUCH0"}})
    out = tmp_path / "run"
    r = psns_hil("run", p, "--out", str(out), "--quiet")
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert "no such file" in r.stderr and "nosuch.csv" in r.stderr
    assert "no such serial device: /dev/ttyNOSUCH0" in r.stderr
    assert "same pty name 'same'" in r.stderr
    assert not out.exists()  # a bad-input exit leaves no run directory


def test_a_run_that_fails_to_start_leaves_no_run_directory(tmp_path):
    import pytest

    from emulator.errors import EmulatorError
    from emulator.recording.rundir import claim_run_dir

    out = tmp_path / "a" / "run"
    with pytest.raises(EmulatorError), claim_run_dir(out):
        (out / "nav.csv").write_text("partial")
        raise EmulatorError("bad port")
    assert not out.exists()


def test_a_pty_port_in_fast_mode_needs_an_explicit_fast(tmp_path):
    p = _with(tmp_path, {"links.host": {"url": "pty://uart0"}})  # the file says mode: fast
    r = psns_hil("run", p, "--out", str(tmp_path / "run"), "--quiet")
    assert r.returncode == 2 and "links.host (pty://uart0)" in r.stderr
    assert "--realtime" in r.stderr and "--fast" in r.stderr and not (tmp_path / "run").exists()
    r = psns_hil("run", p, "--out", str(tmp_path / "run"), "--quiet", "--fast", "--no-report")
    assert r.returncode == 0, r.stderr


def test_replay_marks_sensor_link_expectations_not_applicable_and_reports_truncation(tmp_path):
    p = short_quickstart(tmp_path, "expectations:\n  - link: {name: gnss, counter: crc_errors, max: 0}\n"
                                   "  - link: {name: uart1, counter: crc_errors, max: 0}\n")
    run = tmp_path / "run"
    assert psns_hil("run", p, "--out", str(run), "--quiet", "--no-report").returncode == 0
    r = psns_hil("replay", str(run / "capture.psnscap"), "--out", str(tmp_path / "rp"))
    assert r.returncode == 0, r.stdout + r.stderr
    assert "not applicable" in r.stdout and ": yes" in r.stdout and "psns-hil replay:" in r.stdout
    s = json.loads((tmp_path / "rp" / "summary.json").read_text())
    assert [e["applicable"] for e in s["expectations"]] == [False, True] and s["passed"] is True
    assert s["replay"]["truncated"] is False
    # cut the capture at ~60 %: detected, replayed for what it holds
    cap = run / "capture.psnscap"
    data = cap.read_bytes()
    cut = tmp_path / "cut" / "capture.psnscap"
    cut.parent.mkdir()
    cut.write_bytes(data[: int(len(data) * 0.6)])
    r = psns_hil("replay", str(cut), "--out", str(tmp_path / "rp2"), "--compare", str(run))
    assert "truncated" in r.stdout and r.returncode == 1
    s = json.loads((tmp_path / "rp2" / "summary.json").read_text())
    assert s["replay"]["truncated"] is True and s["replay"]["captured_s"] < 3.5
    assert s["sim_duration_s"] < 3.5
    assert "differing columns" in r.stdout or "rows" in r.stdout


def test_compare_nav_names_columns_and_arrival_only(tmp_path):
    from emulator.postrun.replay import compare_nav

    a, b, c = tmp_path / "a.csv", tmp_path / "b.csv", tmp_path / "c.csv"
    a.write_text("time_s,lat_deg,arrival_s\n1,2,3\n")
    b.write_text("time_s,lat_deg,arrival_s\n1,2,3.5\n")
    c.write_text("time_s,lat_deg,arrival_s\n1,2.5,3.5\n")
    assert compare_nav(a, a)["identical"]
    ab = compare_nav(a, b)
    assert not ab["identical"] and ab["only_arrival"] and ab["differing_columns"] == ["arrival_s"]
    ac = compare_nav(a, c)
    assert ac["differing_columns"] == ["lat_deg", "arrival_s"] and not ac["only_arrival"]


def test_error_text_is_never_markup(tmp_path):
    p = tmp_path / "m.yaml"
    p.write_text(Path(_scenario(tmp_path)).read_text() + "\n'[/]': 1\n")
    r = psns_hil("validate", str(p))
    assert r.returncode == 2 and "MarkupError" not in r.stderr and "[/]" in r.stderr


def test_monitor_unknown_protocol_or_link_is_exit_2_with_the_choices(tmp_path):
    run = tmp_path / "run"
    assert psns_hil("run", _scenario(tmp_path), "--out", str(run), "--quiet", "--no-report").returncode == 0
    cap = str(run / "capture.psnscap")
    r = psns_hil("monitor", cap, "--protocol", "bogus")
    assert r.returncode == 2 and "unknown protocol 'bogus'" in r.stderr and "host" in r.stderr
    r = psns_hil("monitor", cap, "--link", "nosuch")
    assert r.returncode == 2 and "no link 'nosuch'" in r.stderr and "uart0" in r.stderr
    assert "t_s" not in r.stdout


def test_a_second_ctrl_c_says_what_it_did(monkeypatch, capsys):
    import importlib

    cli = importlib.import_module("emulator.cli.main")

    def boom(args):
        raise KeyboardInterrupt

    monkeypatch.setattr(cli, "_cmd_run", boom)
    monkeypatch.setattr(cli, "_cmd_validate", boom)
    assert cli.main(["run", "x.yaml"]) == 1
    assert "interrupted again" in capsys.readouterr().err
    assert cli.main(["validate", "x.yaml"]) == 1  # another command: its first Ctrl-C, not "again"
    err = capsys.readouterr().err
    assert "psns-hil validate: interrupted" in err and "again" not in err


def test_validate_json_omits_unused_keys():
    from tests.conftest import ROOT

    r = psns_hil("validate", str(ROOT / "scenarios" / "quickstart.yaml"), "--json")
    assert r.returncode == 0 and "null" not in r.stdout and json.loads(r.stdout)["name"] == "quickstart"


def test_pyproject_license_is_an_spdx_string():
    import tomllib

    from tests.conftest import ROOT

    meta = tomllib.loads((ROOT / "pyproject.toml").read_text())
    assert meta["project"]["license"] == "MIT"  # a table is deprecated (setuptools warns on every install)


def test_run_set_overrides_are_validated_like_the_file(tmp_path):
    from tests.conftest import ROOT

    qs = str(ROOT / "scenarios" / "quickstart.yaml")
    r = psns_hil("validate", qs, "--set", "duration_s=7", "--set", "links.host.baud=115200", "--json")
    assert r.returncode == 0, r.stderr
    doc = json.loads(r.stdout)
    assert doc["duration_s"] == 7 and doc["links"]["host"]["baud"] == 115200
    r = psns_hil("validate", qs, "--set", "duration_s=-3")
    assert r.returncode == 2 and "--set duration_s=-3" in r.stderr and "duration_s" in r.stderr
    r = psns_hil("validate", qs, "--set", "links.host.bud=1")
    assert r.returncode == 2 and "--set links.host.bud=1" in r.stderr and "did you mean 'baud'" in r.stderr
    r = psns_hil("validate", qs, "--set", "nonsense")
    assert r.returncode == 2 and "dotted.key=value" in r.stderr
    r = psns_hil("run", _scenario(tmp_path), "--set", "duration_s=2", "--out", str(tmp_path / "r"), "--quiet",
                 "--no-report")
    assert r.returncode == 0 and json.loads((tmp_path / "r" / "summary.json").read_text())["sim_duration_s"] == 2.0


def test_a_refused_out_is_the_only_line_no_running_first(tmp_path):
    """Issue 38: ``run --out README.md`` printed "running ..." before its error."""
    f = tmp_path / "README.md"
    f.write_text("x")
    r = psns_hil("run", _scenario(tmp_path), "--out", str(f))
    assert r.returncode == 2 and "running" not in r.stdout + r.stderr
    assert r.stderr.strip().splitlines() == [f"error: {f}: exists and is not a directory (--out takes a run "
                                             "directory)"]


def test_report_of_a_missing_directory_names_it(tmp_path):
    missing = tmp_path / "runs" / "nonexist"
    r = psns_hil("report", str(missing))
    assert r.returncode == 2 and r.stderr.strip() == f"error: {missing}: no such run directory"


def test_validate_json_into_a_closed_pipe_has_no_traceback(tmp_path):
    """``psns-hil validate --json SCENARIO | head -1``: the reader is gone before the JSON is written (the read end
    of the pipe is closed before the process starts, so every write fails: deterministic); exit 0, no
    BrokenPipeError traceback."""
    import subprocess
    import sys

    from tests.conftest import ROOT

    read_end, write_end = os.pipe()
    os.close(read_end)
    try:
        r = subprocess.run([sys.executable, "-m", "emulator", "validate", "--json",
                            str(ROOT / "scenarios" / "quickstart.yaml")], stdout=write_end, stderr=subprocess.PIPE,
                           cwd=ROOT, timeout=120)
    finally:
        os.close(write_end)
    err = r.stderr.decode()
    assert r.returncode == 0 and "Traceback" not in err and "BrokenPipeError" not in err, err
