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


def test_export_of_a_damaged_run_directory_skips_bad_rows_or_says_why(tmp_path):
    """Hostile input: cells that are not finite numbers, a latitude out of range, a line of garbage, bytes that are
    not UTF-8, an event with an impossible time: left out, and the KML / GPX stay valid against their schemas and the
    MCAP readable; a file without the columns the conversion needs: exit 2 and one line, no traceback."""
    import xmlschema

    from tests.conftest import ROOT

    out = tmp_path / "run"
    r = psns_hil("run", str(SCENARIOS / "quickstart.yaml"), "--set", "duration_s=2", "--out", str(out),
                 "--no-tables", "--no-report", "--quiet")
    assert r.returncode in (0, 1), r.stderr
    for name in ("nav.csv", "truth.csv"):
        lines = (out / name).read_text().splitlines()
        head = lines[0].split(",")
        lat, lon = head.index("lat_deg"), head.index("lon_deg")
        for i, (col, bad) in enumerate(((lat, "nan"), (lon, "abc"), (lat, "999"), (lon, "inf")), start=50):
            cells = lines[i].split(",")
            cells[col] = bad
            lines[i] = ",".join(cells)
        lines.insert(60, "x")
        (out / name).write_text("\n".join(lines) + "\n")
    with open(out / "events.jsonl", "ab") as f:
        f.write(b'\xff\xfe{"t_s": 1}\n{"t_s": 1e300, "source": "fault", "event": "fault_start", "fault": "x"}\n')
        f.write(b'{"t_s": "soon", "source": "fault", "event": "fault_start", "fault": "y", "index": "z"}\n')
    r = psns_hil("export", str(out), "--kml", "--gpx", "--mcap")
    assert r.returncode == 0, r.stderr
    xmlschema.XMLSchema(str(ROOT / "tests" / "vectors" / "kml" / "ogckml22.xsd")).validate(str(out / "tracks.kml"))
    xmlschema.XMLSchema(str(ROOT / "tests" / "vectors" / "gpx" / "gpx.xsd")).validate(str(out / "tracks.gpx"))
    nav_rows = len((out / "nav.csv").read_text().splitlines()) - 2  # the header and the garbage line
    with open(out / "run.mcap", "rb") as f:
        summary = make_reader(f).get_summary()
    counts = {summary.channels[c].topic: n for c, n in summary.statistics.channel_message_counts.items()}
    assert counts["/nav/solution"] == nav_rows and counts["/nav/location"] == nav_rows - 4
    (out / "truth.csv").write_text("time_s,lat\n1.0,2.0\n")
    for flag in ("--kml", "--mcap"):
        r = psns_hil("export", str(out), flag)
        assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
        assert "truth.csv" in r.stderr and "lat_deg" in r.stderr
