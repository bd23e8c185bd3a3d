"""The psns-hil command: exit codes and one-line errors, in a real subprocess."""

import json
import subprocess
import sys

from tests.conftest import ROOT


def psns_hil(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "emulator", *args], capture_output=True, text=True, cwd=cwd or ROOT)


def test_version():
    r = psns_hil("--version")
    assert r.returncode == 0 and r.stdout.startswith("psns-hil ")


def test_missing_scenario_file_is_exit_2_one_line(tmp_path):
    r = psns_hil("run", str(tmp_path / "nope.yaml"))
    assert r.returncode == 2
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "nope.yaml" in lines[0] and "no such file" in lines[0]
    assert "Traceback" not in r.stderr


def test_invalid_yaml_is_exit_2_with_location(tmp_path):
    p = tmp_path / "bad.yaml"
    p.write_text("name: x\nduration_s: [1, 2\n")
    r = psns_hil("validate", str(p))
    assert r.returncode == 2 and "Traceback" not in r.stderr
    assert f"{p}:" in r.stderr and "invalid YAML" in r.stderr


def short_quickstart(tmp_path, expectations: str) -> str:
    text = (ROOT / "scenarios" / "quickstart.yaml").read_text()
    text = text.replace("duration_s: 120", "duration_s: 4").replace("- static: {duration_s: 120}",
                                                                  "- static: {duration_s: 4}")
    text = text[: text.index("expectations:")] + expectations
    p = tmp_path / "s.yaml"
    p.write_text(text)
    return str(p)


def test_run_prints_summary_and_writes_run_dir(tmp_path):
    p = short_quickstart(tmp_path, "expectations:\n  - link: {name: uart1, counter: crc_errors, max: 0}\n")
    out = tmp_path / "run"
    r = psns_hil("run", p, "--out", str(out), "--seed", "7")
    assert r.returncode == 0, r.stderr
    assert "navigation error" in r.stdout and "uart1" in r.stdout and "imu_tick" in r.stdout
    s = json.loads((out / "summary.json").read_text())
    assert s["seed"] == 7 and s["sim_duration_s"] == 4.0 and s["passed"] is True


def test_failed_or_unmeasurable_expectation_exits_1(tmp_path):
    # an error bound far below what a 10 m GNSS allows, and one over a window with no data
    p = short_quickstart(tmp_path, "expectations:\n"
                         "  - nav_error: {metric: position_m, stat: max, max: 0.001, after_s: 2.5}\n"
                         "  - nav_error: {metric: heading_deg, stat: rms, max: 10, after_s: 100}\n")
    r = psns_hil("run", p, "--out", str(tmp_path / "run"))
    assert r.returncode == 1
    s = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert [e["passed"] for e in s["expectations"]] == [False, False]
    assert s["expectations"][1]["value"] is None
