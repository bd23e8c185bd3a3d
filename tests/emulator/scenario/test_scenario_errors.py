"""Broken scenario files: every kind of mistake gives a clear error with file:line:column and the field path,
all problems at once, and nothing runs."""

from __future__ import annotations

import subprocess
import sys

import pytest

from emulator.errors import ScenarioError
from emulator.scenario import load_scenario
from tests.conftest import ROOT

HEAD = """\
name: broken
epoch: 2019-09-18T08:14:00Z
duration_s: 100
origin: {lat_deg: 39.979, lon_deg: 116.339, height_m: 50}
"""


def issues(tmp_path, text, name="s.yaml"):
    p = tmp_path / name
    p.write_text(text)
    with pytest.raises(ScenarioError) as ei:
        load_scenario(p)
    return ei.value.issues, p


def one(tmp_path, text):
    got, p = issues(tmp_path, text)
    assert len(got) == 1, [str(i) for i in got]
    i = got[0]
    assert i.file == str(p) and i.line is not None and i.column is not None
    return i


def test_bad_yaml_names_line_and_column(tmp_path):
    i = one(tmp_path, HEAD + "faults:\n  - gnss_outage: {start_s: 10, duration_s: 5\n")
    assert "invalid YAML" in i.message and i.line >= 6


def test_unknown_fault_kind_with_did_you_mean(tmp_path):
    i = one(tmp_path, HEAD + "faults:\n  - gnss_outag: {start_s: 10, duration_s: 5}\n")
    assert (i.line, i.column) == (6, 5)
    assert i.path == "faults[0].gnss_outag"
    assert "unknown key 'gnss_outag'; did you mean 'gnss_outage'?" in i.message


def test_unknown_key_inside_a_fault_and_an_expectation(tmp_path):
    got, _ = issues(tmp_path, HEAD + "faults:\n  - link_bit_errors: {link: gnss, ber: 1.0e-4, durtion_s: 5}\n"
                                     "expectations:\n  - evnt: {name: x}\n")
    msgs = {i.path: (i.line, i.column, i.message) for i in got}
    assert msgs["faults[0].link_bit_errors.durtion_s"][:2] == (6, 48)
    assert "did you mean 'duration_s'?" in msgs["faults[0].link_bit_errors.durtion_s"][2]
    assert msgs["expectations[0].evnt"][0] == 8 and "did you mean 'event'?" in msgs["expectations[0].evnt"][2]


def test_wrong_type(tmp_path):
    i = one(tmp_path, HEAD + "faults:\n  - link_bit_errors: {link: gnss, ber: high}\n")
    assert i.path == "faults[0].link_bit_errors.ber" and i.line == 6
    assert "valid number" in i.message and "'high'" in i.message


def test_out_of_range_value(tmp_path):
    i = one(tmp_path, HEAD + "faults:\n  - link_bit_errors: {link: gnss, ber: 0.9}\n")
    assert i.path == "faults[0].link_bit_errors.ber" and "less than or equal to 0.5" in i.message


def test_bad_link_url(tmp_path):
    i = one(tmp_path, HEAD + "links:\n  gnss: {url: 'tcp://127.0.0.1:5000'}\n")
    assert i.path == "links.gnss.url" and i.line == 6 and "tcp" in i.message


def test_fault_starting_or_ending_outside_the_run(tmp_path):
    got, _ = issues(tmp_path, HEAD + "faults:\n  - gnss_outage: {start_s: 150, duration_s: 5}\n"
                                     "  - gnss_glitch: {start_s: 90, duration_s: 20, offset_enu_m: [10, 0, 0]}\n")
    by = {i.path: i for i in got}
    a = by["faults[0].gnss_outage.start_s"]
    assert a.line == 6 and "starts at 150 s, at or after the end of the run (100 s)" in a.message
    b = by["faults[1].gnss_glitch.duration_s"]
    assert b.line == 7 and "ends at 110 s, after the end of the run" in b.message and "omit duration_s" in b.message


def test_expectation_on_a_link_that_does_not_exist(tmp_path):
    got, _ = issues(tmp_path, HEAD + "expectations:\n  - link: {name: gnns, counter: crc_errors, max: 0}\n"
                                     "  - link: {name: psns, counter: crc_errors, max: 0}\n")
    assert [i.path for i in got] == ["expectations[0].link.name", "expectations[1].link.name"]
    assert "no link 'gnns' in this scenario" in got[0].message and "did you mean 'gnss'?" in got[0].message
    assert "no link 'psns'" in got[1].message and "uart0" in got[1].message  # psns is not wired here
    assert got[0].line == 6 and got[1].line == 7


def test_fault_on_a_link_or_sensor_the_scenario_does_not_have(tmp_path):
    got, _ = issues(tmp_path, HEAD + "faults:\n  - link_stall: {link: monitor}\n  - psns_cloud_cover: {start_s: 3}\n"
                                     "  - fpga_channel_stall: {channel: mag}\n")
    by = {i.path: i.message for i in got}
    assert "no link 'monitor'" in by["faults[0].link_stall.link"]
    assert "needs a polarization sensor" in by["faults[1].psns_cloud_cover"]
    assert "needs sensors.magnetometer" in by["faults[2].fpga_channel_stall.channel"]


def test_a_fault_or_an_expectation_with_two_kinds_or_contradictory_fields(tmp_path):
    got, _ = issues(tmp_path, HEAD + "faults:\n  - gnss_outage: {start_s: 1}\n"
                                     "    gnss_glitch: {offset_enu_m: [1, 0, 0]}\n"
                                     "  - imu_bias_step: {gyro_deg_h: [1, 0, 0], accel_mg: [1, 0, 0]}\n"
                                     "  - link_baud_mismatch: {link: gnss, baud_error_pct: 0}\n"
                                     "expectations:\n  - event: {name: x, min_count: 3, max_count: 1}\n"
                                     "  - event: {name: x, between_s: [5, 2]}\n")
    msgs = [i.message for i in got]
    assert any("exactly one kind" in m for m in msgs)
    assert any("exactly one of gyro_deg_h, accel_mg" in m for m in msgs)
    assert any("baud_error_pct is 0" in m for m in msgs)
    assert any("max_count 1 is below min_count 3" in m for m in msgs)
    assert any("between_s must be [a, b] with 0 <= a < b" in m for m in msgs)


def test_python_hooks_are_checked_without_being_imported(tmp_path):
    """validate confines and finds the hook file but never imports it (a scenario could run any code); a file that
    does not import fails when the run evaluates it (with --allow-hooks)."""
    (tmp_path / "bad_syntax.py").write_text("def f(summary, run_dir:\n    return True\n")
    (tmp_path / "good.py").write_text("def nav_ok(summary, run_dir):\n    return True\n")
    got, _ = issues(tmp_path, HEAD + "expectations:\n"
                                     "  - python: {file: missing.py, function: f}\n"
                                     "  - python: {file: bad_syntax.py, function: f}\n"
                                     "  - python: {file: ../outside.py, function: f}\n"
                                     "  - python: {file: /etc/hostname.py, function: f}\n"
                                     "  - python: {file: good.py, function: nav_ok}\n")
    assert [i.line for i in got] == [6, 8, 9]
    assert "no such file" in got[0].message
    assert "outside the scenario's directory" in got[1].message and "outside the scenario's directory" in got[2].message


def test_every_problem_at_once_sorted_by_line(tmp_path):
    got, _ = issues(tmp_path, HEAD.replace("duration_s: 100", "duration_s: -5") +
                    "faults:\n  - link_bit_errors: {link: gnss, ber: 2}\n  - gnss_outge: {}\n"
                    "expectations:\n  - dsp: {field: deadline_misses}\n")
    assert [i.path for i in got] == ["duration_s", "faults[0].link_bit_errors.ber", "faults[1].gnss_outge",
                                     "expectations[0].dsp"]
    assert [i.line for i in got] == [3, 6, 7, 9]


def test_cli_validate_reports_everything_and_run_runs_nothing(tmp_path):
    p = tmp_path / "broken.yaml"
    p.write_text(HEAD + "faults:\n  - gnss_outage: {start_s: 150}\nexpectations:\n"
                        "  - link: {name: nope, counter: crc_errors, max: 0}\n")
    r = subprocess.run([sys.executable, "-m", "emulator", "validate", str(p)], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 2 and "Traceback" not in r.stderr
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 2
    assert lines[0].startswith(f"error: {p}:6:") and "faults[0].gnss_outage.start_s" in lines[0]
    assert lines[1].startswith(f"error: {p}:8:") and "expectations[0].link.name" in lines[1]
    out = tmp_path / "run"
    r = subprocess.run([sys.executable, "-m", "emulator", "run", str(p), "--out", str(out)], capture_output=True,
                       text=True, cwd=ROOT)
    assert r.returncode == 2 and not out.exists()  # nothing ran, nothing was written


def test_the_library_and_its_faults_validate(tmp_path):
    from emulator.postrun.golden import library

    for p in library():
        scn = load_scenario(p)
        assert scn.expectations, f"{p.name} has no expectations"


def _plain(x):
    """YAML data as JSON would carry it: timestamps as ISO strings, and numbers such as ``300.0e6``, which
    PyYAML (YAML 1.1: an exponent needs a sign) reads as strings, as YAML 1.2 editors read them."""
    import datetime as dt
    import re

    if isinstance(x, dict):
        return {k: _plain(v) for k, v in x.items()}
    if isinstance(x, list):
        return [_plain(v) for v in x]
    if isinstance(x, (dt.datetime, dt.date)):
        return x.isoformat()
    if isinstance(x, str) and re.fullmatch(r"[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+", x):
        return float(x)
    return x


def test_the_exported_json_schema_accepts_the_library_and_rejects_broken_items():
    """An independent validator (jsonschema, Draft 2020-12) on docs/scenario.schema.json: what editors see."""
    import json

    import jsonschema
    import yaml

    from emulator.postrun.golden import library

    schema = json.loads((ROOT / "docs" / "scenario.schema.json").read_text())
    v = jsonschema.Draft202012Validator(schema)
    for p in library():
        errs = list(v.iter_errors(_plain(yaml.safe_load(p.read_text()))))
        assert not errs, (p.name, [e.message for e in errs])
    base = _plain(yaml.safe_load(HEAD))
    bad = [{"faults": [{"gnss_outage": {"start_s": 1}, "gnss_glitch": {"offset_enu_m": [1, 0, 0]}}]},
           {"faults": [{}]},
           {"faults": [{"gnss_outag": {"start_s": 1}}]},
           {"faults": [{"link_bit_errors": {"link": "gnss", "ber": 0.9}}]},
           {"expectations": [{"event": {"name": "x", "nope": 1}}]}]
    for extra in bad:
        assert list(v.iter_errors({**base, **extra})), extra


VIB = "sensors:\n  imu:\n    vibration:\n      psd: "


@pytest.mark.parametrize(("psd", "path", "col", "words"), [
    ("[[10, 0.01], [40, 0.01], [30, 0.001]]", "sensors.imu.vibration.psd[2][0]", 38,
     "PSD frequencies must increase: 30 Hz follows 40 Hz"),
    ("[[10, 0.01], [10, 0.001]]", "sensors.imu.vibration.psd[1][0]", 26, "must increase"),
    ("[[10, -0.01], [40, 0.01]]", "sensors.imu.vibration.psd[0][1]", 18, "greater than 0"),
    ("[[10, 0.01], [40, 500]]", "sensors.imu.vibration.psd[1][1]", 30, "less than or equal to 100"),
    ("[[0, 0.01], [40, 0.01]]", "sensors.imu.vibration.psd[0][0]", 14, "greater than 0"),
    ("[[10, 0.01], [150, 0.01]]", "sensors.imu.vibration.psd[1][0]", 26,
     "150 Hz is beyond the IMU's Nyquist frequency 100 Hz (sensors.imu.rate_hz 200 Hz); allowed range (0, 100] Hz"),
    ("[[10, 0.01]]", "sensors.imu.vibration.psd", 7, "at least 2"),
])
def test_vibration_psd_out_of_range_names_the_breakpoint(tmp_path, psd, path, col, words):
    i = one(tmp_path, HEAD + VIB + psd + "\n")
    assert i.path == path and i.line == 8 and i.column == col, (i.path, i.line, i.column)
    assert words in i.message


def test_vibration_beyond_nyquist_follows_the_imu_rate(tmp_path):
    # at 400 Hz the IMU's Nyquist frequency is 200 Hz: 150 Hz is fine, 250 Hz is not
    ok = tmp_path / "ok.yaml"
    ok.write_text(HEAD + "sensors:\n  imu:\n    rate_hz: 400\n    vibration:\n      psd: [[10, 0.01], [150, 0.01]]\n")
    assert load_scenario(ok).sensors.imu.vibration.psd[-1] == (150.0, 0.01)
    i = one(tmp_path, HEAD + "sensors:\n  imu:\n    rate_hz: 400\n    vibration:\n"
                             "      psd: [[10, 0.01], [250, 0.01]]\n")
    assert i.path == "sensors.imu.vibration.psd[1][0]" and "allowed range (0, 200] Hz" in i.message


def test_vibration_without_a_profile_needs_one_from_the_preset(tmp_path):
    i = one(tmp_path, HEAD + "sensors:\n  imu:\n    vibration: {axes: [1, 1, 1]}\n")
    assert i.path == "sensors.imu.vibration.psd" and "IMU preset 'paper' has none" in i.message
    ok = tmp_path / "ok.yaml"  # the field preset has one: its axes may be overridden alone
    ok.write_text(HEAD + "sensors:\n  preset: field\n  imu:\n    vibration: {axes: [0, 0, 2]}\n")
    assert load_scenario(ok).sensors.imu.vibration.axes == (0.0, 0.0, 2.0)


@pytest.mark.parametrize(("body", "path", "words"), [
    ("temperature: {warmup_tau_s: 0}", "sensors.imu.temperature.warmup_tau_s", "greater than or equal to 1"),
    ("temperature: {warmup_c: 80}", "sensors.imu.temperature.warmup_c", "less than or equal to 60"),
    ("vibration: {psd: [[10, 0.01], [40, 0.01]], axes: [1, 1, 11]}", "sensors.imu.vibration.axes[2]",
     "less than or equal to 10"),
    ("accel: {vre_ug_per_g2: [50, 50, 5000]}", "sensors.imu.accel.vre_ug_per_g2[2]", "less than or equal to 1000"),
])
def test_warm_up_and_vibration_figures_out_of_range(tmp_path, body, path, words):
    i = one(tmp_path, HEAD + "sensors:\n  imu:\n    " + body + "\n")
    assert i.path == path and i.line == 7 and words in i.message


def test_validate_rejects_a_bad_vibration_profile_and_runs_nothing(tmp_path):
    p = tmp_path / "bad.yaml"
    p.write_text(HEAD + VIB + "[[10, 0.01], [150, 0.01]]\n")
    r = subprocess.run([sys.executable, "-m", "emulator", "validate", str(p)], capture_output=True, text=True,
                       cwd=ROOT, timeout=120)
    assert r.returncode != 0
    assert f"{p}:8:26" in r.stdout + r.stderr and "sensors.imu.vibration.psd[1][0]" in r.stdout + r.stderr
