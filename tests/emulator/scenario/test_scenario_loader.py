"""Broken scenario files give every problem at once, with file:line:column and field path."""

import pytest

from emulator.errors import ScenarioError
from emulator.scenario import load_scenario

GOOD = """\
name: t
epoch: 2019-09-18T08:14:00Z
duration_s: 10
origin: {lat_deg: 39.979, lon_deg: 116.339, height_m: 50}
"""


def write(tmp_path, text):
    p = tmp_path / "s.yaml"
    p.write_text(text)
    return p


def test_minimal_scenario_loads(tmp_path):
    scn = load_scenario(write(tmp_path, GOOD))
    assert scn.duration_s == 10 and scn.origin.lat_deg == 39.979


def test_unknown_key_did_you_mean_with_line(tmp_path):
    p = write(tmp_path, GOOD + "firmware:\n  output_rate: 50\n")
    with pytest.raises(ScenarioError) as ei:
        load_scenario(p)
    (issue,) = ei.value.issues
    assert issue.line == 6 and issue.path == "firmware.output_rate"
    assert "did you mean 'output_rate_hz'" in issue.message


def test_all_errors_reported_at_once(tmp_path):
    p = write(tmp_path, GOOD.replace("duration_s: 10", "duration_s: -1").replace("lat_deg: 39.979", "lat_deg: 99"))
    with pytest.raises(ScenarioError) as ei:
        load_scenario(p)
    paths = sorted(i.path for i in ei.value.issues)
    assert paths == ["duration_s", "origin.lat_deg"]
    assert all(i.line is not None for i in ei.value.issues)
    assert str(p) in str(ei.value)


def test_invalid_yaml_names_line(tmp_path):
    p = write(tmp_path, "name: t\norigin: {lat_deg: 1\n")
    with pytest.raises(ScenarioError) as ei:
        load_scenario(p)
    assert "invalid YAML" in str(ei.value) and ei.value.issues[0].line is not None


def test_missing_file(tmp_path):
    with pytest.raises(ScenarioError, match="no such file"):
        load_scenario(tmp_path / "nope.yaml")


def test_bad_link_url_is_a_field_error(tmp_path):
    p = write(tmp_path, GOOD + "links:\n  host: {url: 'pty://a/b?x=1'}\n")
    with pytest.raises(ScenarioError) as ei:
        load_scenario(p)
    assert ei.value.issues[0].path == "links.host.url"


def test_epoch_needs_timezone(tmp_path):
    p = write(tmp_path, GOOD.replace("08:14:00Z", "08:14:00"))
    with pytest.raises(ScenarioError, match="time zone"):
        load_scenario(p)
