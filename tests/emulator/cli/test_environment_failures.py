"""The machine, not the input (issue 41 item 7, docs/hostile-input.md section 8): a full disk, a file-size limit
(``ulimit -f``), a read-only output directory and a recorded CSV that is not UTF-8 or holds a 50 MB line end
``psns-hil`` with exit 2 and one ``error:`` line, never a traceback; the summary is written where the disk allows
it (space for it is reserved when the run starts). Before: a traceback each, no summary after ENOSPC, and
SIGXFSZ killed the process under ``ulimit -f``.

The tmpfs cases need root (``mount``); they skip with the reason otherwise."""

from __future__ import annotations

import contextlib
import json
import os
import resource
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from emulator.recording.capture import read_capture
from tests.conftest import ROOT


def _scenario(tmp_path: Path, duration_s: int = 60) -> str:
    text = (ROOT / "scenarios" / "quickstart.yaml").read_text()
    text = text.replace("duration_s: 120", f"duration_s: {duration_s}").replace(
        "- static: {duration_s: 120}", f"- static: {{duration_s: {duration_s}}}")
    text = text[: text.index("expectations:")] + "expectations: []\n"
    p = tmp_path / "s.yaml"
    p.write_text(text)
    return str(p)


def _run(*args: str, preexec_fn=None, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-m", "emulator", "run", *args, "--fast", "--quiet"], cwd=ROOT,
                          capture_output=True, text=True, preexec_fn=preexec_fn, env=env, timeout=300)


def _untraced_env() -> dict[str, str]:
    """This environment without coverage's child-process measurement (``make test``): under a file-size limit the
    tracer's own data file cannot be written either, and its traceback at exit is not psns-hil's."""
    return {k: v for k, v in os.environ.items() if not k.startswith("COVERAGE_")}


def _one_error(r: subprocess.CompletedProcess[str]) -> str:
    assert r.returncode == 2, r.stderr
    assert "Traceback" not in r.stderr
    errors = [ln for ln in r.stderr.splitlines() if ln.startswith("error:")]
    assert len(errors) == 1, r.stderr
    return errors[0]


@contextlib.contextmanager
def _tmpfs(where: Path, options: str):
    if os.geteuid() != 0 or shutil.which("mount") is None:
        pytest.skip("mounting a tmpfs needs root and mount(8)")
    where.mkdir(parents=True, exist_ok=True)
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", options, "tmpfs", str(where)], capture_output=True, text=True)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here: {r.stderr.strip()}")
    try:
        yield where
    finally:
        subprocess.run(["umount", "-l", str(where)], check=False)


def _kept_summary_and_capture(out: Path, errno_text: str) -> None:
    s = json.loads((out / "summary.json").read_text())
    assert s["passed"] is False and errno_text in s["storage_error"]
    _header, records = read_capture(out / "capture.psnscap")  # what reached the disk is readable
    assert records


def test_disk_full_exits_2_with_one_message_and_keeps_a_summary(tmp_path):
    with _tmpfs(tmp_path / "mnt", "size=2m") as mnt:
        out = mnt / "run"
        line = _one_error(_run(_scenario(tmp_path), "--out", str(out)))
        assert "No space left on device" in line and "summary.json written" in line
        _kept_summary_and_capture(out, "errno 28")


def _fsize_limit() -> None:
    resource.setrlimit(resource.RLIMIT_FSIZE, (400_000, 400_000))


def test_file_size_limit_exits_2_instead_of_sigxfsz(tmp_path):
    out = tmp_path / "run"
    r = _run(_scenario(tmp_path), "--out", str(out), preexec_fn=_fsize_limit, env=_untraced_env())
    line = _one_error(r)  # before: killed by SIGXFSZ (rc -25), nothing said
    assert "File too large" in line and "summary.json written" in line
    _kept_summary_and_capture(out, "errno 27")


def test_read_only_output_exits_2_with_one_message(tmp_path):
    with _tmpfs(tmp_path / "ro", "ro,size=1m") as ro:
        for out in (ro, ro / "run"):  # the mount point itself, and a directory to create in it
            line = _one_error(_run(_scenario(tmp_path, 4), "--out", str(out)))
            assert "read-only file system or no permission" in line
            assert not (ro / "run").exists()


def _recorded(tmp_path: Path, body: bytes) -> str:
    text = (ROOT / "scenarios" / "recorded_replay.yaml").read_text()
    shutil.copytree(ROOT / "scenarios" / "data", tmp_path / "data")
    (tmp_path / "data" / "drive_imu.csv").write_bytes(body)
    p = tmp_path / "recorded.yaml"
    p.write_text(text)
    return str(p)


_HEADER = b"time_s,gyro_x_dps,gyro_y_dps,gyro_z_dps,accel_x_mps2,accel_y_mps2,accel_z_mps2\n"
_ROW = b"0.0,0,0,0,0,0,9.8\n"


@pytest.mark.parametrize("body, says", [
    (_HEADER + _ROW + b"0.01,0,0,\xff\xfe,0,0,9.8\n" + _ROW, "line 3, column 10: not UTF-8"),
    (_HEADER + _ROW + b"0.01," + b"1" * 50_000_000 + b",0,0,0,0,9.8\n", "line 3, column 65537: line longer than"),
], ids=["non-utf8", "50MB-line"])
def test_a_hostile_recorded_csv_exits_2_with_one_message(tmp_path, body, says):
    r = subprocess.run([sys.executable, "-m", "emulator", "run", _recorded(tmp_path, body), "--out",
                        str(tmp_path / "run"), "--quiet"], cwd=ROOT, capture_output=True, text=True, timeout=300)
    line = _one_error(r)
    assert says in line and "1111" not in line  # never the file's text
