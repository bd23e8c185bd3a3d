"""firmware.spec_sheet: the firmware's figures come from its spec sheet (bundled or next to the scenario), never from
the world's presets; a missing, escaping or malformed sheet stops the run naming the field."""

from __future__ import annotations

import shutil

import pytest

from emulator.dsp.firmware_setup import firmware_config, spec_sheet_for
from emulator.errors import ScenarioError
from emulator.scenario import load_scenario
from tests.conftest import ROOT

QUICKSTART = ROOT / "scenarios" / "quickstart.yaml"


def test_the_world_presets_do_not_reach_the_firmware():
    # the same spec sheet whatever the world's IMU draws: a perfect IMU in the world changes nothing in the filter
    cfg = firmware_config(load_scenario(QUICKSTART))
    perfect = ["sensors.imu.preset=perfect", "sensors.gnss.preset=perfect"]
    cfg_perfect = firmware_config(load_scenario(QUICKSTART, perfect))
    # the quickstart names the bundled field sheet (its world runs the field presets)
    field = spec_sheet_for(load_scenario(QUICKSTART))
    assert cfg.spec_sheet == "field" and cfg.gyro_bias_sigma_deg_h == cfg_perfect.gyro_bias_sigma_deg_h
    assert cfg.gnss_pos_sigma_h_m == pytest.approx(field.gnss.horizontal_95_m / 2.448) == cfg_perfect.gnss_pos_sigma_h_m


def test_bundled_field_sheet():
    cfg = firmware_config(load_scenario(QUICKSTART, ["firmware.spec_sheet=field"]))
    assert cfg.spec_sheet == "field" and cfg.accel_bias_instability_mg == pytest.approx(0.045)


def test_a_sheet_next_to_the_scenario(tmp_path):
    shutil.copy(QUICKSTART, tmp_path / "q.yaml")
    (tmp_path / "mine.yaml").write_text("name: mine\ngyro: {arw_deg_rt_h: 0.3}\n")
    cfg = firmware_config(load_scenario(tmp_path / "q.yaml", ["firmware.spec_sheet=mine.yaml"]))
    assert cfg.spec_sheet == "mine" and cfg.gyro_arw_deg_rt_h == pytest.approx(0.3)


def test_a_leading_dot_is_refused_by_validation():
    with pytest.raises(ScenarioError) as ei:
        load_scenario(QUICKSTART, ["firmware.spec_sheet=../x.yaml"])
    assert "firmware.spec_sheet" in str(ei.value)


@pytest.mark.parametrize("ref, text, needle", [
    ("nosuch", None, "no bundled spec sheet 'nosuch'"),
    ("d/../../x.yaml", None, "outside the scenario's directory"),
    ("bad.yaml", "gyro: {arw_deg_rt_h: -1}\n", "gyro.arw_deg_rt_h"),
    ("missing.yaml", None, "no such file"),
])
def test_bad_sheets_stop_the_run(tmp_path, ref, text, needle):
    (tmp_path / "sub").mkdir()
    shutil.copy(QUICKSTART, tmp_path / "sub" / "q.yaml")
    if text is not None:
        (tmp_path / "sub" / "bad.yaml").write_text(text)
    (tmp_path / "x.yaml").write_text("name: x\n")
    scn = load_scenario(tmp_path / "sub" / "q.yaml", [f"firmware.spec_sheet={ref}"])
    with pytest.raises(ScenarioError) as ei:
        spec_sheet_for(scn)
    assert "firmware.spec_sheet" in str(ei.value) and needle in str(ei.value)
