"""No silent fallbacks (issue 38): validate warns with file:line where the scenario leaves the heading to a
default or the sky to the night, the run lists every fallback it took in summary.json and on the console."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from emulator.assembly.fallbacks import has_polarization_sensor, scenario_warnings, sun_below_minimum
from emulator.scenario import load_scenario
from tests.conftest import ROOT, SCENARIOS

QUICK = (SCENARIOS / "quickstart.yaml").read_text()


def _write(tmp_path: Path, text: str) -> Path:
    p = tmp_path / "s.yaml"
    p.write_text(text)
    return p


def _line_of(text: str, needle: str) -> int:
    return next(i for i, ln in enumerate(text.splitlines(), 1) if needle in ln)


def test_the_library_leaves_nothing_to_a_silent_default():
    warned = {p.name: [str(w) for w in scenario_warnings(load_scenario(p))] for p in sorted(SCENARIOS.glob("*.yaml"))}
    assert {k: v for k, v in warned.items() if v} == {}


def test_heading_source_psns_without_a_polarization_sensor(tmp_path):
    text = (QUICK.replace("  camera: {preset: reference, fidelity: binned, rate_hz: 5}\n", "")
            .replace('  psns: {url: "mem://psns", baud: 115200}\n', ""))
    assert text != QUICK
    scn = load_scenario(_write(tmp_path, text))
    assert not has_polarization_sensor(scn)
    ws = scenario_warnings(scn)
    kinds = [w.kind for w in ws]
    assert kinds == ["alignment_heading_not_given", "heading_source_without_sensor"]
    w = ws[1]
    assert (w.line, w.path) == (_line_of(text, "heading_source: psns"), "firmware.alignment.heading_source")
    assert str(w).startswith(f"{tmp_path / 's.yaml'}:{w.line}:") and "no polarization camera or compass" in str(w)
    assert "heading 0 deg (the truth starts at 30 deg)" in ws[0].message


def test_the_sun_below_the_psns_minimum_elevation(tmp_path):
    """Beijing at local midnight (16:00 UTC): the sun is about 50 deg below the horizon for the whole run. Towards
    sunset (18:21 local = 10:21 UTC on 2019-09-18, NOAA solar calculator; the sun sets at about -0.8 deg geometric,
    dropping about 0.19 deg a minute) it crosses 5 deg near 09:49 UTC: a 25 min run from 09:30 UTC meets it after
    about 19 min."""
    night = load_scenario(_write(tmp_path, QUICK.replace("epoch: 2019-09-18T08:14:00Z", "epoch: 2019-09-18T16:00:00Z")))
    spans, lowest, _ = sun_below_minimum(night)
    assert spans == [(0.0, 120.0)] and lowest < -40.0
    (w,) = scenario_warnings(night)
    assert w.kind == "sun_below_psns_minimum" and w.line == _line_of(QUICK, "epoch:") and w.path == "epoch"
    assert "for the whole run" in w.message and "alignment falls back to heading_deg" in w.message
    dusk = load_scenario(_write(tmp_path, QUICK.replace("epoch: 2019-09-18T08:14:00Z", "epoch: 2019-09-18T09:30:00Z")
                                .replace("duration_s: 120", "duration_s: 1500")
                                .replace("static: {duration_s: 120}", "static: {duration_s: 1500}")))
    spans, lowest, _ = sun_below_minimum(dusk)
    assert len(spans) == 1 and 1000.0 < spans[0][0] < 1300.0 and spans[0][1] == 1500.0 and 3.0 < lowest < 5.0
    (w,) = scenario_warnings(dusk)
    assert f"at t = {spans[0][0]:g}-1500 s" in w.message and "alignment" not in w.message.split("then")[1]


def test_validate_prints_the_warnings_with_file_and_line_and_exits_0(tmp_path):
    text = QUICK.replace("epoch: 2019-09-18T08:14:00Z", "epoch: 2019-09-18T16:00:00Z")
    p = _write(tmp_path, text)
    r = subprocess.run([sys.executable, "-m", "emulator", "validate", str(p)], capture_output=True, text=True,
                       cwd=ROOT, timeout=120)
    assert r.returncode == 0 and ": ok (" in r.stdout
    assert f"warning: {p}:{_line_of(text, 'epoch:')}:1: epoch: the sun is below" in r.stderr.replace("\n", "")


def test_the_run_lists_every_fallback_it_took(tmp_path):
    """At night with heading_source psns and no heading_deg: the alignment waits psns_timeout_s, takes the default
    heading 0 (truth 30): summary.json lists the scenario's warning and the two fallbacks, the console says them."""
    text = (QUICK.replace("epoch: 2019-09-18T08:14:00Z", "epoch: 2019-09-18T16:00:00Z")
            .replace("heading_source: psns}", "heading_source: psns, psns_timeout_s: 1}")
            .replace("duration_s: 120", "duration_s: 5")
            .replace("static: {duration_s: 120}", "static: {duration_s: 5}"))
    p = _write(tmp_path, text)
    env = dict(os.environ)
    r = subprocess.run([sys.executable, "-m", "emulator", "run", str(p), "--out", str(tmp_path / "run"),
                        "--set", "expectations=[]"], capture_output=True, text=True, cwd=ROOT, timeout=300, env=env)
    assert r.returncode == 0, r.stdout[-2000:] + r.stderr[-2000:]
    s = json.loads((tmp_path / "run" / "summary.json").read_text())
    got = [(w["source"], w["kind"]) for w in s["warnings"]]
    assert got[0] == ("scenario", "sun_below_psns_minimum")
    assert ("run", "alignment_heading_fallback") in got and ("run", "alignment_heading_default") in got
    fb = next(w for w in s["warnings"] if w["kind"] == "alignment_heading_fallback")
    assert fb["t_s"] == pytest.approx(3.0, abs=0.05) and "took the configured heading (0.00 deg)" in fb["message"]
    assert "the sun is below" in r.stderr  # said before the run
    assert "fallback taken:" in r.stdout and "psns_timeout_s" in r.stdout.replace("\n", " ")
    doc = (tmp_path / "run" / "report.html").read_text()
    assert "Warnings (fallbacks the run took)" in doc and "data-path='warnings[0].message'" in doc
