"""A recorded IMU file with a non-physical gyro value (issue 41 item 6: a gyro of 1e300 deg/s navigated 2.3 km off)
stops ``psns-hil run`` at load: exit 2, one message naming file, line, column and field, no run directory."""

from __future__ import annotations

import shutil
from pathlib import Path

from tests.emulator.cli.test_cli import psns_hil

ROOT = Path(__file__).resolve().parents[3]


def test_a_recorded_gyro_of_1e300_is_refused_at_load(tmp_path):
    shutil.copy(ROOT / "scenarios" / "recorded_replay.yaml", tmp_path / "s.yaml")
    (tmp_path / "data").mkdir()
    shutil.copy(ROOT / "scenarios" / "data" / "drive_gnss.nmea", tmp_path / "data")
    lines = (ROOT / "scenarios" / "data" / "drive_imu.csv").read_text().splitlines()
    header = next(i for i, ln in enumerate(lines) if ln.strip() and not ln.startswith("#"))
    cols = [c.strip() for c in lines[header].split(",")]
    row = header + 50
    cells = lines[row].split(",")
    cells[cols.index("gyro_z_dps")] = "1e300"
    lines[row] = ",".join(cells)
    (tmp_path / "data" / "drive_imu.csv").write_text("\n".join(lines) + "\n")
    out = tmp_path / "run"
    r = psns_hil("run", str(tmp_path / "s.yaml"), "--out", str(out), "--quiet")
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    err = " ".join(r.stderr.split())
    assert f"drive_imu.csv: line {row + 1}, column" in err
    assert "gyro_z_dps is outside its physical range [-10000, 10000] deg/s" in err
    assert not out.exists()
