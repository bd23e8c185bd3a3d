"""A spec sheet next to the scenario is read as boundedly as the scenario itself (issue 41 item 5): one bounded read,
nesting screened before anything is composed, merge keys refused, confined by the same function as every named file
(:func:`emulator.scenario.paths.confine`, which follows symbolic links)."""

from __future__ import annotations

import shutil

import pytest

import emulator.scenario.loader as loader
from emulator.dsp.firmware_setup import spec_sheet_for
from emulator.errors import ScenarioError
from emulator.scenario import load_scenario
from tests.conftest import ROOT

QUICKSTART = ROOT / "scenarios" / "quickstart.yaml"


@pytest.mark.parametrize(("text", "needle", "composes"), [
    ("[" * 100_000, "deep.yaml:1:65: YAML nested deeper than 64 levels", False),
    ("#" * (loader.MAX_SCENARIO_BYTES + 1), "deep.yaml: larger than 1 MiB", False),
    ("gyro:\n  <<: {arw_deg_rt_h: 1}\n", "deep.yaml:2:3: gyro: YAML merge keys (<<) are not allowed", True),
])
def test_a_hostile_sheet_is_one_error_after_bounded_work(tmp_path, monkeypatch, text, needle, composes):
    shutil.copy(QUICKSTART, tmp_path / "q.yaml")
    (tmp_path / "deep.yaml").write_text(text)
    scn = load_scenario(tmp_path / "q.yaml", ["firmware.spec_sheet=deep.yaml"])

    def no_compose(*a, **k):
        raise AssertionError("composed a hostile spec sheet")

    if not composes:  # the caps act before the composer (a merge key is found while building, which is cheap)
        monkeypatch.setattr(loader.yaml, "compose", no_compose)
    with pytest.raises(ScenarioError) as ei:
        spec_sheet_for(scn)
    assert f"firmware.spec_sheet: {needle}" in str(ei.value)


def test_a_sheet_behind_a_symlink_out_of_the_directory_is_refused(tmp_path):
    (tmp_path / "scen").mkdir()
    shutil.copy(QUICKSTART, tmp_path / "scen" / "q.yaml")
    (tmp_path / "outside.yaml").write_text("gyro: {}\n")
    (tmp_path / "scen" / "sheet.yaml").symlink_to(tmp_path / "outside.yaml")
    scn = load_scenario(tmp_path / "scen" / "q.yaml", ["firmware.spec_sheet=sheet.yaml"])
    with pytest.raises(ScenarioError, match=r"firmware\.spec_sheet: sheet\.yaml is outside the scenario.s directory"):
        spec_sheet_for(scn)
