"""The run directory's timeline.csv / filter_state.csv and report.html (written by every `psns-hil run`, and by
`psns-hil report RUN_DIR`), with faults, link errors over time and the DSP load per task."""

from __future__ import annotations

import base64
import csv
import json
import re
import subprocess
import sys

import pytest

from emulator.postrun.report import fault_spans, write_report
from tests.conftest import ROOT, SCENARIOS


@pytest.fixture(scope="module")
def cli_run(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("rep")
    text = (SCENARIOS / "quickstart.yaml").read_text().replace("duration_s: 120", "duration_s: 6.5") \
        .replace("{duration_s: 120}", "{duration_s: 6.5}")
    text = text[: text.index("expectations:")] + (
        "faults:\n"
        "  - link_bit_errors: {link: gnss, ber: 2.0e-3, start_s: 2, duration_s: 3}\n"
        "  - dsp_extra_load: {load_pct: 120, start_s: 4, duration_s: 0.5}\n"
        "expectations:\n  - dsp: {field: deadline_misses, min: 1}\n")
    p = tmp / "s.yaml"
    p.write_text(text)
    out = tmp / "run"
    r = subprocess.run([sys.executable, "-m", "emulator", "run", str(p), "--out", str(out)], capture_output=True,
                       text=True, cwd=ROOT)
    return r, out


def _rows(path):
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def test_run_writes_the_report_and_says_where(cli_run):
    r, out = cli_run
    assert r.returncode == 0, r.stdout + r.stderr
    assert (out / "report.html").exists() and f"report: {out / 'report.html'}" in r.stdout


def test_timeline_has_one_row_per_second_with_cumulative_link_counters_and_the_dsp_load(cli_run):
    _, out = cli_run
    rows = _rows(out / "timeline.csv")
    assert [float(x["time_s"]) for x in rows] == [1, 2, 3, 4, 5, 6, 6.5]  # and the end of the run
    crc = [int(x["gnss_crc_errors"]) for x in rows]
    assert crc == sorted(crc) and crc[1] == 0 and crc[-1] > 0  # errors only once the fault started
    s = json.loads((out / "summary.json").read_text())
    assert crc[-1] == s["links"]["gnss"]["crc_errors"]
    assert int(rows[-1]["uart1_frames"]) == s["links"]["uart1"]["frames"]
    load = {float(x["time_s"]): float(x["cpu_load_pct"]) for x in rows}
    assert load[5] > 50.0 > load[3]  # the second [4, 5) carried the injected load
    assert load[5] == pytest.approx(100 * min(1.0, 0.5 * 1.2 + 0.5 * 0.003), abs=2.0)
    assert int(rows[-1]["deadline_misses"]) == s["dsp"]["deadline_misses"] > 0


def test_filter_state_is_sampled_every_second(cli_run):
    _, out = cli_run
    rows = _rows(out / "filter_state.csv")
    assert [float(x["time_s"]) for x in rows] == [1, 2, 3, 4, 5, 6]
    assert rows[0]["state"] == "coarse_align" and rows[-1]["state"] == "fine_align"
    assert {f"p{i}" for i in range(15)} <= set(rows[0]) and "gyro_bias_z" in rows[0]
    assert float(rows[-1]["p8"]) > 0  # height variance


def test_report_shows_validity_faults_link_errors_and_dsp_load_per_task(cli_run):
    _, out = cli_run
    doc = (out / "report.html").read_text()
    assert doc.startswith("<!DOCTYPE html>") and "src='http" not in doc
    assert "passed" in doc and "valid (every fault took effect)" in doc
    assert "<h2>Faults</h2>" in doc and "link_bit_errors" in doc and "bytes_corrupted" in doc
    imgs = dict(re.findall(r"<h2>([^<]+)</h2><img alt='[^']*' src='data:image/png;base64,([A-Za-z0-9+/=]+)'", doc))
    for title in ("Attitude error", "Mode timeline", "Link errors over time", "DSP load over time",
                  "DSP load per task"):
        assert title in imgs and base64.b64decode(imgs[title]).startswith(b"\x89PNG")


def test_fault_spans_pair_starts_and_ends():
    events = [{"t_s": 1.0, "source": "fault", "event": "fault_start", "index": 0, "fault": "gnss_outage",
               "end_s": 3},
              {"t_s": 2.0, "source": "fault", "event": "fault_start", "index": 1, "fault": "dsp_extra_load",
               "end_s": 9},
              {"t_s": 3.0, "source": "fault", "event": "fault_end", "index": 0},
              {"t_s": 3.0, "source": "firmware", "event": "fault_end", "index": 1}]  # not a fault event
    assert fault_spans(events) == [(1.0, 3.0, "#0 gnss_outage"), (2.0, 9.0, "#1 dsp_extra_load")]


def test_report_command_rewrites_the_report_and_refuses_a_non_run_directory(cli_run, tmp_path):
    _, out = cli_run
    (out / "report.html").unlink()
    r = subprocess.run([sys.executable, "-m", "emulator", "report", str(out)], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0 and (out / "report.html").exists()
    r = subprocess.run([sys.executable, "-m", "emulator", "report", str(tmp_path)], capture_output=True, text=True,
                       cwd=ROOT)
    assert r.returncode == 2 and "not a run directory" in r.stderr


def test_an_invalid_run_says_so_in_its_report(tmp_path):
    from emulator.assembly.session import run_scenario
    from emulator.testing import load_test_scenario

    scn = load_test_scenario(SCENARIOS / "quickstart.yaml", {
        "duration_s": 3, "motion": [{"static": {"duration_s": 3}}], "expectations": [],
        "faults": [{"imu_saturation": {"gyro_range_dps": 300, "start_s": 1}}]})
    run_scenario(scn, tmp_path / "run")
    import re

    doc = re.sub(r"<[^>]+>", "", write_report(tmp_path / "run").read_text())  # the text a reader sees
    assert "INVALID: a scheduled fault never took effect" in doc and "samples_clipped 0" in doc
