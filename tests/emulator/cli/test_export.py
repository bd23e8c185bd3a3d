"""``psns-hil run --mcap`` / ``--no-tables`` and ``psns-hil export``, in a real subprocess."""

import json

from mcap.reader import make_reader

from tests.conftest import SCENARIOS
from tests.emulator.cli.test_cli import psns_hil


def test_run_writes_tables_and_mcap_and_export_converts_the_run_dir(tmp_path):
    out = tmp_path / "run"
    r = psns_hil("run", str(SCENARIOS / "quickstart.yaml"), "--set", "duration_s=4", "--out", str(out), "--mcap",
                 "--no-report", "--quiet")
    assert r.returncode in (0, 1), r.stderr
    for name in ("run.mcap", "imu.csv", "gnss.csv", "psns_frames.csv"):
        assert (out / name).is_file(), name
    with open(out / "run.mcap", "rb") as f:
        topics = {ch.topic for ch in make_reader(f).get_summary().channels.values()}
    assert {"/nav/location", "/truth/location", "/raw/uart1/in", "/imu"} <= topics
    r = psns_hil("export", str(out), "--kml", "--gpx", "--mcap", str(tmp_path / "again.mcap"))
    assert r.returncode == 0, r.stderr
    assert (out / "tracks.kml").read_bytes().startswith(b"<?xml") and (out / "tracks.gpx").is_file()
    assert "messages on" in r.stdout
    with open(out / "run.mcap", "rb") as a, open(tmp_path / "again.mcap", "rb") as b:
        ra, rb = make_reader(a), make_reader(b)
        assert [(c.topic, m.log_time, m.data) for _, c, m in ra.iter_messages()] == \
               [(c.topic, m.log_time, m.data) for _, c, m in rb.iter_messages()]  # the same conversion


def test_run_without_tables_and_export_errors(tmp_path):
    out = tmp_path / "run"
    r = psns_hil("run", str(SCENARIOS / "quickstart.yaml"), "--set", "duration_s=2", "--out", str(out),
                 "--no-tables", "--no-report", "--quiet")
    assert r.returncode in (0, 1), r.stderr
    assert not (out / "imu.csv").exists() and not (out / "run.mcap").exists()
    r = psns_hil("export", str(out), "--tables")
    assert r.returncode == 0 and "imu.csv: 400 rows" in r.stdout  # 2 s of 200 Hz IMU frames
    assert json.loads((out / "summary.json").read_text())["sim_duration_s"] == 2.0
    r = psns_hil("export", str(out))
    assert r.returncode == 2 and "say what to write" in r.stderr
    r = psns_hil("export", str(tmp_path), "--kml")
    assert r.returncode == 2 and "not a run directory" in r.stderr
