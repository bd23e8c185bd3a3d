"""Expectations: each kind passes and fails on what it measures; a deliberately wrong expectation fails the
run (exit 1) and the pytest item of the scenario library."""

from __future__ import annotations

import json
import shutil
from array import array
from typing import ClassVar

import pytest

from emulator.recording.nav_error import ErrorStats
from emulator.scenario.expectations_schema import EventExpectation
from emulator.scenario.schema import Expectation
from emulator.verification.expectations import evaluate_expectations, matching_events
from tests.conftest import ROOT, SCENARIOS

pytest_plugins = ["pytester"]


class FakeRecorder:
    """What the evaluators read from a recorder: events, the error series and the mode series."""

    def __init__(self, events=(), errors=(), modes=()):
        self.events = list(events)
        self.error_series = array("d", [x for row in errors for x in row])
        self.mode_series = array("d", [x for row in modes for x in row])

    def error_window(self, metric, after_s, until_s):
        idx = {"attitude_deg": 1, "heading_deg": 2, "position_m": 3, "velocity_mps": 4}[metric]
        es = ErrorStats()
        s = self.error_series
        for k in range(0, len(s), 5):
            if s[k] >= after_s and (until_s is None or s[k] <= until_s):
                es.add(s[k + idx])
        return es


EVENTS = [
    {"t_s": 10.0, "source": "firmware", "event": "gnss_update", "n_meas": 5},
    {"t_s": 301.2, "source": "firmware", "event": "gnss_isolated", "chi2": 42.5, "branch": "gnss"},
    {"t_s": 302.0, "source": "firmware", "event": "gnss_isolated", "chi2": 12.0, "branch": "gnss"},
    {"t_s": 303.0, "source": "dsp", "event": "gnss_isolated"},
    {"t_s": 400.0, "source": "firmware", "event": "mode_switch", "to": "vector", "ok": True},
]


def ev(**kw):
    return EventExpectation(**kw)


def test_event_matching_by_name_source_window_count_and_fields():
    assert len(matching_events(EVENTS, ev(name="gnss_isolated"))) == 3
    assert len(matching_events(EVENTS, ev(name="gnss_isolated", source="firmware"))) == 2
    assert len(matching_events(EVENTS, ev(name="gnss_isolated", source="firmware", between_s=(300, 302)))) == 2
    assert len(matching_events(EVENTS, ev(name="gnss_isolated", source="firmware", between_s=(301.5, 305)))) == 1
    assert len(matching_events(EVENTS, ev(name="gnss_isolated", fields={"chi2": {"min": 20}}))) == 1
    assert len(matching_events(EVENTS, ev(name="gnss_isolated", fields={"branch": "gnss"}))) == 2
    assert len(matching_events(EVENTS, ev(name="gnss_isolated", fields={"branch": "psns"}))) == 0
    assert len(matching_events(EVENTS, ev(name="mode_switch", fields={"to": "vector", "ok": True}))) == 1
    assert len(matching_events(EVENTS, ev(name="mode_switch", fields={"ok": 1}))) == 0  # True is not 1
    assert len(matching_events(EVENTS, ev(name="gnss_update", fields={"n_meas": 5.0}))) == 1
    assert len(matching_events(EVENTS, ev(name="gnss_update", fields={"missing": 1}))) == 0


def _eval(items, rec=None, summary=None, **kw):
    exps = [Expectation.model_validate(x) for x in items]
    return evaluate_expectations(exps, rec or FakeRecorder(EVENTS), summary or {"sim_duration_s": 500.0}, **kw)


def test_event_expectations_must_and_must_not_occur():
    r = _eval([
        {"event": {"name": "gnss_isolated", "source": "firmware", "between_s": [300, 305], "min_count": 1}},
        {"event": {"name": "gnss_isolated", "source": "firmware", "between_s": [300, 305], "min_count": 3}},
        {"event": {"name": "deadline_miss", "max_count": 0}},
        {"event": {"name": "gnss_isolated", "max_count": 0}},
        {"event": {"name": "gnss_isolated", "min_count": 2, "max_count": 2, "source": "firmware"}},
    ])
    assert [x.passed for x in r] == [True, False, True, False, True]
    assert [x.value for x in r] == [2, 2, 0, 3, 2]
    assert r[0].message == "first at t = 301.200 s"
    assert "between" not in r[0].description and "300 s <= t <= 305 s" in r[0].description


def test_nav_error_nav_mode_link_dsp_and_summary_bounds():
    rec = FakeRecorder(errors=[(t, 0.1, 0.05 * t, 3.0, 0.2) for t in range(0, 20)],
                       modes=[(t * 0.5, 0x06 if t < 20 else 0x12) for t in range(40)])
    summary = {"sim_duration_s": 20.0, "links": {"gnss": {"crc_errors": 3, "dropped": 0}},
               "dsp": {"deadline_misses": 0, "cpu_load_pct_max": 0.3},
               "firmware": {"counters": {"psns_rejected": 4}}, "faults": [{"evidence": {"bytes_lost": 10}}]}
    r = _eval([
        {"nav_error": {"metric": "heading_deg", "stat": "max", "max": 0.5, "until_s": 10}},
        {"nav_error": {"metric": "heading_deg", "stat": "max", "max": 0.5, "after_s": 10}},
        {"nav_error": {"metric": "position_m", "stat": "rms", "max": 1.0, "after_s": 19.5}},
        {"nav_mode": {"flag": "gnss_aided", "until_s": 9.9, "min_fraction": 1.0}},
        {"nav_mode": {"flag": "degraded", "between_s": [10, 20], "min_fraction": 0.99}},
        {"nav_mode": {"flag": "gnss_aided", "between_s": [10, 20], "max_fraction": 0.0}},
        {"link": {"name": "gnss", "counter": "crc_errors", "min": 1}},
        {"link": {"name": "gnss", "counter": "crc_errors", "max": 0}},
        {"link": {"name": "psns", "counter": "crc_errors", "max": 0}},
        {"dsp": {"field": "deadline_misses", "max": 0}},
        {"dsp": {"field": "cpu_load_pct_max", "min": 50}},
        {"summary": {"path": "firmware.counters.psns_rejected", "min": 1, "max": 10}},
        {"summary": {"path": "faults.0.evidence.bytes_lost", "min": 11}},
        {"summary": {"path": "firmware.counters.nope", "min": 1}},
    ], rec, summary)
    assert [x.passed for x in r] == [True, False, False, True, True, True, True, False, False, True, False, True,
                                     False, False]
    assert r[1].value == pytest.approx(0.95)
    assert r[2].value is None and "no navigation frames" in r[2].message  # nothing measured proves nothing
    assert r[4].message == "20 of 20 frames"
    assert "no link 'psns'" in r[8].message
    assert "missing 'nope'" in r[13].message


def test_windows_after_the_end_of_the_run_fail_with_the_reason():
    r = _eval([{"nav_error": {"metric": "heading_deg", "max": 1, "after_s": 100}},
               {"event": {"name": "gnss_isolated", "after_s": 600}}], summary={"sim_duration_s": 60.0})
    assert not r[0].passed and "after the run ended (60 s)" in r[0].message
    assert not r[1].passed and "after the run ended" in r[1].message


HOOKS = '''
def ok(summary, run_dir, limit=1):
    return summary["x"] <= limit, summary["x"], "x within the limit"

def as_dict(summary, run_dir):
    return {"passed": False, "value": 7, "message": "seven is too many"}

def plain(summary, run_dir):
    return True

def boom(summary, run_dir):
    raise RuntimeError("disk on fire")

def bad_return(summary, run_dir):
    return 42

def mutate(summary, run_dir):
    summary["x"] = 1000
    return True
'''


def test_python_hooks_pass_fail_raise_and_cannot_corrupt_the_summary(tmp_path):
    (tmp_path / "hooks.py").write_text(HOOKS)
    summary = {"sim_duration_s": 1.0, "x": 0.5}
    items = [{"python": {"file": "hooks.py", "function": f, "args": a}} for f, a in
             [("ok", {}), ("ok", {"limit": 0.1}), ("as_dict", {}), ("plain", {}), ("boom", {}), ("bad_return", {}),
              ("mutate", {}), ("ok", {})]]
    r = _eval(items, summary=summary, run_dir=tmp_path, base_dir=tmp_path)
    assert [x.passed for x in r] == [True, False, False, True, False, False, True, True]
    assert r[0].value == 0.5 and r[0].message == "x within the limit"
    assert r[2].value == 7 and r[2].message == "seven is too many"
    assert "RuntimeError: disk on fire" in r[4].message
    assert "returns bool" in r[5].message
    assert summary["x"] == 0.5  # each hook gets a copy
    assert r[1].description == "hooks.py:ok(limit=0.1)"


WRONG = """\
name: deliberately_wrong
epoch: 2019-09-18T08:14:00Z
duration_s: 4
origin: {lat_deg: 39.979, lon_deg: 116.339, height_m: 50.0}
attitude: {heading_deg: 30.0}
firmware:
  alignment: {time_s: 2.0, heading_deg: 30.5}
expectations:
  - link: {name: uart1, counter: crc_errors, max: 0}
  # a 10 m GNSS cannot give a millimetre: this expectation is wrong on purpose
  - nav_error: {metric: position_m, stat: max, max: 0.001, after_s: 2.5}
"""


def test_a_deliberately_wrong_expectation_fails_the_run_and_its_library_test(pytester, tmp_path):
    """The scenario library's pytest plugin reports the failed expectation with its measured value."""
    shutil.copy(SCENARIOS / "conftest.py", pytester.path / "conftest.py")
    (pytester.path / "wrong.yaml").write_text(WRONG)
    (pytester.path / "right.yaml").write_text(WRONG.replace("deliberately_wrong", "right")
                                              .replace("max: 0.001", "max: 100"))
    res = pytester.runpytest_subprocess("-p", "no:cacheprovider", "-k", "not golden and not seeds")
    res.assert_outcomes(passed=1, failed=1)
    out = res.stdout.str()
    assert "scenario deliberately_wrong" in out and "failed:" in out
    assert "expectation #1 nav_error: max position_m <= 0.001 for t >= 2.5 s: measured" in out
    assert "run directory kept:" in out and "scenario library: wall time" in out
    # the seed-robustness items (issue 15): the 4 s scenarios get [seeds-fast] with seeds 1 and 2
    res = pytester.runpytest_subprocess("-p", "no:cacheprovider", "-k", "seeds-fast")
    res.assert_outcomes(passed=1, failed=1)
    out = res.stdout.str()
    assert "scenario deliberately_wrong (" in out and "is not seed-robust over seeds [1, 2]:" in out
    assert "  seed 1: run directory kept:" in out and "  seed 2: run directory kept:" in out
    # the same file on the command line: exit code 1, the failure in summary.json
    import subprocess
    import sys

    out_dir = tmp_path / "run"
    r = subprocess.run([sys.executable, "-m", "emulator", "run", str(pytester.path / "wrong.yaml"), "--out",
                        str(out_dir), "--no-report"], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 1
    s = json.loads((out_dir / "summary.json").read_text())
    assert [e["passed"] for e in s["expectations"]] == [True, False] and s["valid"] is True


def test_the_golden_item_of_a_scenario_without_a_record_fails_with_the_command(pytester):
    shutil.copy(SCENARIOS / "conftest.py", pytester.path / "conftest.py")
    (pytester.path / "right.yaml").write_text(WRONG.replace("deliberately_wrong", "no_golden_yet")
                                              .replace("max: 0.001", "max: 100"))
    res = pytester.runpytest_subprocess("-p", "no:cacheprovider", "-k", "not seeds")
    res.assert_outcomes(passed=1, failed=1)
    assert "no golden record for no_golden_yet" in res.stdout.str() and "make golden" in res.stdout.str()


def test_slow_library_scenarios_get_the_slow_marker(pytester):
    shutil.copy(SCENARIOS / "conftest.py", pytester.path / "conftest.py")
    pytester.makeini("[pytest]\nmarkers =\n    slow: slow\n")
    (pytester.path / "s.yaml").write_text(WRONG.replace("deliberately_wrong", "tagged").replace(
        "duration_s: 4\n", "duration_s: 4\ntags: [slow]\n"))
    res = pytester.runpytest_subprocess("-p", "no:cacheprovider", "-m", "not slow", "--collect-only", "-q")
    # the scenario, its golden and its 10-seed check; a slow scenario gets no fast-seed item
    assert "3 deselected" in res.stdout.str()


def test_a_broken_library_file_is_a_collection_error_with_every_problem(pytester):
    shutil.copy(SCENARIOS / "conftest.py", pytester.path / "conftest.py")
    (pytester.path / "broken.yaml").write_text(WRONG.replace("duration_s: 4", "duration_s: -4")
                                               .replace("lat_deg: 39.979", "lat_dg: 39.979"))
    res = pytester.runpytest_subprocess("-p", "no:cacheprovider")
    out = res.stdout.str()
    assert res.ret != 0 and "scenario file does not validate" in out
    assert "broken.yaml:3:" in out and "duration_s" in out
    assert "unknown key 'lat_dg'; did you mean 'lat_deg'?" in out


def test_event_expectations_on_a_variants_events_with_an_injected_glitch(tmp_path):
    """"Chi-square isolated GNSS between 60 and 61.5 s": the federated variant's own events, matched by name,
    source, window and count, with the glitch injected as a fault instead of the receiver's schedule."""
    from emulator.assembly.session import run_scenario
    from emulator.testing import load_test_scenario

    scn = load_test_scenario(SCENARIOS / "federated_gnss_glitch.yaml", {
        "duration_s": 72, "sensors.gnss.glitches": [],
        "faults": [{"gnss_glitch": {"start_s": 60, "duration_s": 5, "offset_enu_m": [50.0, -30.0, 10.0]}}],
        "expectations": [
            {"event": {"name": "gnss_isolated", "source": "firmware", "between_s": [60, 61.5], "min_count": 1}},
            # a calibrated chi-square test alarms on a clean epoch at alpha = 0.001: at most one in the 59 before the
            # glitch (P(>= 2) = 0.0017); seed 11 has one at 45 s (lambda 23.24, D-5.34 / D-5.35)
            {"event": {"name": "gnss_isolated", "source": "firmware", "until_s": 59.5, "max_count": 1}},
            {"event": {"name": "gnss_readmitted", "source": "firmware", "between_s": [65, 72], "min_count": 1}},
            {"summary": {"path": "faults.0.evidence.glitched_fixes", "min": 5, "max": 5}},
            {"nav_error": {"metric": "position_m", "stat": "max", "max": 15.0, "between_s": [55, 72]}},
        ]})
    s = run_scenario(scn, tmp_path / "run")
    assert s["valid"] is True
    assert [e["passed"] for e in s["expectations"]] == [True] * 5, s["expectations"]
    # and the same events do not match outside their window or from another source
    scn2 = load_test_scenario(scn, {"expectations": [
        {"event": {"name": "gnss_isolated", "source": "dsp", "min_count": 1}}]})
    from emulator.verification.expectations import evaluate_expectations

    class Rec:
        events: ClassVar[list] = [json.loads(ln) for ln in (tmp_path / "run" / "events.jsonl").read_text().splitlines()]

    (r,) = evaluate_expectations(scn2.expectations, Rec(), {"sim_duration_s": 72.0})
    assert r.passed is False and r.value == 0


def test_nan_in_a_metric_fails_its_expectation_with_the_reason():
    nan = float("nan")
    rec = FakeRecorder(errors=[(10.0, 0.1, 0.2, 1.0, 0.1), (11.0, nan, nan, nan, nan), (12.0, 0.1, 0.2, 1.0, 0.1)])
    r = _eval([{"nav_error": {"metric": "heading_deg", "stat": "max", "max": 1.0}},
               {"summary": {"path": "dsp.cpu_load_pct_max", "max": 50}}],
              rec=rec, summary={"sim_duration_s": 20.0, "dsp": {"cpu_load_pct_max": nan}})
    assert [x.passed for x in r] == [False, False]
    assert all("not a finite number" in x.message for x in r)


def _nav_csv(tmp_path, arrivals):
    (tmp_path / "nav.csv").write_text("time_s,arrival_s\r\n" + "".join(f"{t - 0.003!r},{t!r}\r\n" for t in arrivals))
    return tmp_path


def test_nav_gap_and_nav_rate_measure_the_arrival_times(tmp_path):
    """100 Hz frames with a 5 s hole from 40 s (a cable pulled): the largest gap inside the window is the hole,
    clipped to the window; the rate of a window without the hole is 100 Hz; the hook these kinds replace
    (scenarios/checks.py nav_gap / nav_rate) gives the same numbers."""
    import importlib.util

    arrivals = [0.01 * k + 0.004 for k in range(6000) if not 40.0 <= 0.01 * k + 0.004 < 45.0]
    run_dir = _nav_csv(tmp_path, arrivals)
    r = _eval([
        {"nav_gap": {"between_s": [39, 46], "min_gap_s": 4.9}},
        {"nav_gap": {"between_s": [39, 46], "min_gap_s": 5.1}},
        {"nav_gap": {"between_s": [3, 39], "max_gap_s": 0.1}},
        {"nav_gap": {"between_s": [42, 44], "min_gap_s": 1.9}},  # inside the hole: the window itself is the gap
        {"nav_rate": {"rate_hz": 100.0, "until_s": 39.0}},
        {"nav_rate": {"rate_hz": 100.0, "after_s": 46.0}},
        {"nav_rate": {"rate_hz": 100.0, "tolerance": 0.01}},  # the whole run: the hole pulls the rate down
        {"nav_rate": {"rate_hz": 50.0, "until_s": 39.0}},
    ], summary={"sim_duration_s": 60.0}, run_dir=run_dir)
    assert [x.passed for x in r] == [True, False, True, True, True, True, False, False]
    assert r[0].value == pytest.approx(5.01, abs=1e-9) and "from t = 39.994 s" in r[0].message
    assert r[3].value == pytest.approx(2.0)
    assert r[4].value == pytest.approx(100.0) and r[6].value == pytest.approx(5500 / 59.99 * (5499 / 5500), rel=1e-3)
    spec = importlib.util.spec_from_file_location("library_checks", SCENARIOS / "checks.py")
    checks = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(checks)
    assert checks.nav_gap({}, run_dir, 39, 46, 4.9)[1] == pytest.approx(r[0].value, abs=1e-4)
    assert checks.nav_rate({}, run_dir, 100.0)[1] == pytest.approx(r[6].value, abs=1e-3)


def test_nav_gap_and_rate_fail_with_the_reason_when_nothing_is_measured(tmp_path):
    r = _eval([{"nav_gap": {"after_s": 70, "min_gap_s": 1}}, {"nav_rate": {"rate_hz": 100.0}}],
              summary={"sim_duration_s": 60.0}, run_dir=tmp_path)
    assert [x.passed for x in r] == [False, False]
    assert all(x.message == "no nav.csv in the run directory" for x in r)
    r = _eval([{"nav_gap": {"after_s": 70, "min_gap_s": 1}}, {"nav_rate": {"rate_hz": 100.0, "after_s": 59.995}}],
              summary={"sim_duration_s": 60.0}, run_dir=_nav_csv(tmp_path, [0.01 * k for k in range(6000)]))
    assert [x.passed for x in r] == [False, False]
    assert "after the run ended" in r[0].message and "no rate to measure" in r[1].message


def test_nav_gap_needs_a_bound():
    from pydantic import ValidationError

    with pytest.raises(ValidationError, match="min_gap_s, max_gap_s or both"):
        Expectation.model_validate({"nav_gap": {"after_s": 1}})
    with pytest.raises(ValidationError, match="below min_gap_s"):
        Expectation.model_validate({"nav_gap": {"min_gap_s": 2, "max_gap_s": 1}})


def test_a_hook_without_allow_hooks_is_not_run_neither_pass_nor_fail(tmp_path, monkeypatch):
    from emulator.scenario.paths import ALLOW_HOOKS_ENV

    monkeypatch.delenv(ALLOW_HOOKS_ENV, raising=False)
    marker = tmp_path / "ran"
    (tmp_path / "hooks.py").write_text(f"open({str(marker)!r}, 'w').write('x')\n" + HOOKS)
    r = _eval([{"python": {"file": "hooks.py", "function": "ok"}}, {"python": {"file": "hooks.py",
                                                                                "function": "as_dict"}}],
              summary={"sim_duration_s": 1.0, "x": 0.5}, run_dir=tmp_path, base_dir=tmp_path)
    assert [x.status for x in r] == ["not_run", "not_run"] and not marker.exists()
    assert all(x.passed and not x.applicable and "--allow-hooks" in x.message for x in r)
    assert r[0].as_dict()["status"] == "not_run"
    monkeypatch.setenv(ALLOW_HOOKS_ENV, "1")
    r = _eval([{"python": {"file": "hooks.py", "function": "ok"}}, {"python": {"file": "hooks.py",
                                                                                "function": "as_dict"}}],
              summary={"sim_duration_s": 1.0, "x": 0.5}, run_dir=tmp_path, base_dir=tmp_path)
    assert [x.status for x in r] == ["pass", "fail"] and marker.exists()


HOOKED = WRONG.replace("""  # a 10 m GNSS cannot give a millimetre: this expectation is wrong on purpose
  - nav_error: {metric: position_m, stat: max, max: 0.001, after_s: 2.5}
""", """  - python: {file: hooks.py, function: plain}
""")


def test_plain_run_of_a_scenario_with_a_hook_exits_0_and_says_not_run(tmp_path):
    """The CLI without --allow-hooks: exit 0 (nothing failed), a line that says the hook was not run, the report and
    summary.json say "not run"; with --allow-hooks it runs and passes."""
    import os
    import subprocess
    import sys

    from emulator.scenario.paths import ALLOW_HOOKS_ENV

    assert HOOKED != WRONG
    (tmp_path / "s.yaml").write_text(HOOKED)
    (tmp_path / "hooks.py").write_text(HOOKS)
    env = {k: v for k, v in os.environ.items() if k != ALLOW_HOOKS_ENV}
    r = subprocess.run([sys.executable, "-m", "emulator", "run", str(tmp_path / "s.yaml"), "--out",
                        str(tmp_path / "run")], capture_output=True, text=True, env=env, cwd=ROOT, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "1 python hook expectation(s) not run" in r.stdout
    s = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert [e["status"] for e in s["expectations"]] == ["pass", "not_run"] and s["passed"] is True
    assert "<td>not run</td>" in (tmp_path / "run" / "report.html").read_text()
    r = subprocess.run([sys.executable, "-m", "emulator", "run", str(tmp_path / "s.yaml"), "--out",
                        str(tmp_path / "run2"), "--allow-hooks"], capture_output=True, text=True, env=env, cwd=ROOT,
                       timeout=300)
    assert r.returncode == 0 and "not run" not in r.stdout, r.stdout + r.stderr
    s = json.loads((tmp_path / "run2" / "summary.json").read_text())
    assert [e["status"] for e in s["expectations"]] == ["pass", "pass"]


def test_every_expectation_kind_has_one_registered_evaluator():
    from emulator.scenario.expectations_schema import EXPECTATION_KINDS
    from emulator.verification.expectations import EVALUATORS, evaluates

    assert set(EVALUATORS) == set(EXPECTATION_KINDS)
    with pytest.raises(ValueError, match="already has an evaluator"):
        evaluates("nav_error")(lambda i, kind, spec, run: None)
