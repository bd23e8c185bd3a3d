"""The ``consistency:`` expectation: too few runs for the confidence level, or a state group the filter does not
have, is refused by validation with file:line and the field; a valid one parses and is not evaluated by a single run.
The chi-square arithmetic is checked against published table values."""

from __future__ import annotations

import pytest

from emulator.errors import ScenarioError
from emulator.scenario import load_scenario
from emulator.scenario.consistency_schema import chi2_bounds, min_runs

HEAD = """\
name: consistency
epoch: 2019-09-18T08:14:00Z
duration_s: 10
origin: {lat_deg: 39.979, lon_deg: 116.339, height_m: 50}
expectations:
  - nav_error: {metric: position_m, stat: rms, max: 25.0}
"""


def _issue(tmp_path, line: str):
    p = tmp_path / "s.yaml"
    p.write_text(HEAD + line)
    with pytest.raises(ScenarioError) as ei:
        load_scenario(p)
    (i,) = ei.value.issues
    return i, str(ei.value)


def test_chi2_bounds_match_the_table_values():
    # chi-square quantiles (Abramowitz & Stegun table 26.8): 1 dof 0.025 -> 0.000982, 0.975 -> 5.024;
    # 30 dof: 16.791 / 46.979
    lo, hi = chi2_bounds(1, 1, 0.95)
    assert lo == pytest.approx(0.000982, rel=1e-3) and hi == pytest.approx(5.024, rel=1e-3)
    lo, hi = chi2_bounds(10, 3, 0.95)  # average of 10 runs of a 3-dof group: chi2(30) / 10
    assert lo == pytest.approx(1.6791, rel=1e-3) and hi == pytest.approx(4.6979, rel=1e-3)


def test_min_runs_is_the_first_n_with_an_interval_narrower_than_the_mean():
    for dof in (1, 3):
        n = min_runs(0.95, dof)
        lo, hi = chi2_bounds(n, dof, 0.95)
        lo1, hi1 = chi2_bounds(n - 1, dof, 0.95)
        assert (hi - lo) / dof <= 1.0 < (hi1 - lo1) / dof
    assert min_runs(0.95, 1) > min_runs(0.95, 3) and min_runs(0.99, 3) > min_runs(0.95, 3)


def test_too_few_runs_for_the_confidence_is_refused_with_file_line_and_field(tmp_path):
    i, text = _issue(tmp_path, "  - consistency: {runs: 5, groups: [attitude, heading], confidence: 0.95}\n")
    assert i.line == 7
    assert "expectations[1].consistency" in text and "too few" in text and f">= {min_runs(0.95, 1)}" in text


def test_unknown_state_group_is_refused(tmp_path):
    i, text = _issue(tmp_path, "  - consistency: {runs: 40, groups: [attitude, biases]}\n")
    assert i.line == 7 and "biases" in text and "unknown state group" in text


def test_unknown_measurement_type_is_refused(tmp_path):
    _, text = _issue(tmp_path, "  - consistency: {runs: 40, measurements: [lidar]}\n")
    assert "lidar" in text


def test_a_valid_consistency_expectation_parses(tmp_path):
    p = tmp_path / "s.yaml"
    p.write_text(HEAD + "  - consistency: {runs: 12, groups: [attitude, velocity, position], after_s: 20}\n")
    scn = load_scenario(p)
    c = scn.expectations[1].consistency
    assert c is not None and c.runs == 12 and c.groups == ["attitude", "velocity", "position"] and c.after_s == 20
