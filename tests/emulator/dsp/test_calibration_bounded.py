"""A user's calibration file (``firmware.calibration.file``) is read as every file a scenario names: confined by
``emulator.scenario.paths.confine`` and bounded (one read of at most ``MAX_CALIBRATION_BYTES``, JSON nesting
checked before decoding) -- docs/hostile-input.md section 6 (issue 41)."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time

import pytest

from emulator.dsp.firmware_setup import calibration_for
from emulator.errors import ScenarioError
from emulator.scenario.loader import load_scenario
from firmware_model.calibration import MAX_CALIBRATION_BYTES, Calibration, save_calibration

SCN = """\
name: cal
epoch: 2019-09-18T08:14:00Z
duration_s: 10
origin: {lat_deg: 39.979, lon_deg: 116.339, height_m: 50}
links:
  psns: {url: "mem://psns", baud: 115200}
sensors:
  camera: {}
firmware: {calibration: {source: file, file: cal.json}}
"""

GOOD = {"format": "psns-hil-calibration", "version": 1}


def _scenario(tmp_path):
    p = tmp_path / "s.yaml"
    p.write_text(SCN)
    return load_scenario(p)


def _refused(scn) -> str:
    t0 = time.process_time()
    with pytest.raises(ScenarioError) as exc:
        calibration_for(scn)
    assert time.process_time() - t0 < 5.0  # bounded work, not a parse of everything
    msg = str(exc.value)
    assert "firmware.calibration.file" in msg and "s.yaml" in msg
    return msg


def test_a_hostile_calibration_file_is_one_error_after_bounded_work(tmp_path):
    scn = _scenario(tmp_path)
    cal = tmp_path / "cal.json"
    # 100 000 nested lists: json.loads raised RecursionError (a traceback) before; now refused before decoding
    cal.write_bytes(b"[" * 100_000 + b"]" * 100_000)
    assert "deeper than 64 levels" in _refused(scn)
    # a valid calibration padded past the cap was read whole and accepted before; now refused by its size
    cal.write_bytes(json.dumps(GOOD).encode() + b" " * MAX_CALIBRATION_BYTES)
    assert "larger than 1 MiB" in _refused(scn)
    # an endless FIFO: one bounded read (a writer that never stops would hang a whole read)
    cal.unlink()
    os.mkfifo(cal)
    writer = subprocess.Popen([sys.executable, "-c", f"import sys\nwith open({str(cal)!r}, 'wb') as f:\n"
                               "    try:\n        while True: f.write(b' ' * 65536)\n"
                               "    except BrokenPipeError: pass\n"], stderr=subprocess.DEVNULL)
    try:
        assert "larger than 1 MiB" in _refused(scn)
    finally:
        writer.kill()
        writer.wait(timeout=30)
    cal.unlink()
    # NaN is not JSON; the error names line and column, never the text
    cal.write_text('{"format": "psns-hil-calibration", "version": 1,\n "camera": {"k1": NaN}}')
    assert "not JSON" in _refused(scn)
    cal.write_text('{"format": "psns-hil-calibration",\n "version": 1 secret-token}')
    msg = _refused(scn)
    assert "line 2" in msg and "secret-token" not in msg
    # a good one still loads
    save_calibration(Calibration(), cal)
    assert calibration_for(scn) == Calibration()


def test_a_calibration_behind_a_symlink_out_of_the_directory_is_refused(tmp_path):
    inside = tmp_path / "scn"
    inside.mkdir()
    outside = tmp_path / "elsewhere.json"
    save_calibration(Calibration(), outside)
    (inside / "cal.json").symlink_to(outside)
    scn = _scenario(inside)
    assert "outside the scenario's directory" in _refused(scn)
    # the same answer when the outside file does not exist: no existence oracle
    outside.unlink()
    assert "outside the scenario's directory" in _refused(scn)


def test_validate_reads_the_calibration_file_and_exits_2_with_one_line(tmp_path):
    (tmp_path / "s.yaml").write_text(SCN)
    (tmp_path / "cal.json").write_bytes(b"[" * 100_000)
    r = subprocess.run([sys.executable, "-m", "emulator", "validate", str(tmp_path / "s.yaml")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2, r.stderr
    assert "Traceback" not in r.stderr + r.stdout
    assert "firmware.calibration.file" in r.stderr + r.stdout
    save_calibration(Calibration(), tmp_path / "cal.json")
    r = subprocess.run([sys.executable, "-m", "emulator", "validate", str(tmp_path / "s.yaml")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
