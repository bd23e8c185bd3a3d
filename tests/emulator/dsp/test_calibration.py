"""The firmware's calibration file: round trip, rejection of unusable files, and the scenario's way to it."""

from __future__ import annotations

import json
import math

import pytest

from emulator.dsp.firmware_setup import calibration_for, firmware_config
from emulator.errors import ScenarioError
from emulator.scenario.loader import load_scenario
from firmware_model.calibration import (
    Calibration,
    CalibrationError,
    CameraCalibration,
    MagnetometerCalibration,
    load_calibration,
    save_calibration,
)

SCN = """\
name: cal
epoch: 2019-09-18T08:14:00Z
duration_s: 10
origin: {lat_deg: 39.979, lon_deg: 116.339, height_m: 50}
links:
  psns: {url: "mem://psns", baud: 115200}
sensors:
  camera: {}
"""


def test_round_trip(tmp_path):
    cal = Calibration(camera=CameraCalibration(cx_px=1230.2, k1=-0.031, exit_pupil_m=math.inf,
                                               boresight_rotvec_deg=(0.1, -0.2, 0.3)),
                      magnetometer=MagnetometerCalibration(hard_iron_nt=(100.0, -50.0, 3.0)))
    save_calibration(cal, tmp_path / "c.json")
    assert load_calibration(tmp_path / "c.json") == cal
    assert load_calibration_defaults(tmp_path) == Calibration()


def load_calibration_defaults(tmp_path):
    (tmp_path / "d.json").write_text(json.dumps({"format": "psns-hil-calibration", "version": 1}))
    return load_calibration(tmp_path / "d.json")


@pytest.mark.parametrize("bad", [
    {"camera": {"focal_m": -1.0}},
    {"camera": {"k1": float("nan")}},
    {"camera": {"polarizer_deg": [0, 45, 90]}},
    {"camera": {"lens": "pinhole"}},
    {"camera": {"projection": "orthographic"}},
    {"magnetometer": {"soft_iron": [1, 0, 0]}},
    {"extra": {}},
    {"version": 2},
    {"format": "other"},
])
def test_unusable_files_are_rejected(tmp_path, bad):
    d = {"format": "psns-hil-calibration", "version": 1, **bad}
    (tmp_path / "c.json").write_text(json.dumps(d))
    with pytest.raises(CalibrationError):
        load_calibration(tmp_path / "c.json")
    (tmp_path / "n.json").write_text("{not json")
    with pytest.raises(CalibrationError):
        load_calibration(tmp_path / "n.json")


def test_a_users_file_inside_the_scenario_directory(tmp_path):
    cal = Calibration(camera=CameraCalibration(k1=-0.02, boresight_rotvec_deg=(0.0, 0.0, 0.5)))
    (tmp_path / "cal").mkdir()
    save_calibration(cal, tmp_path / "cal" / "unit7.json")
    p = tmp_path / "s.yaml"
    p.write_text(SCN + "firmware: {calibration: {source: file, file: cal/unit7.json}}\n")
    scn = load_scenario(p)
    assert calibration_for(scn) == cal
    assert firmware_config(scn).camera.k1 == -0.02


@pytest.mark.parametrize("path", ["/etc/passwd", "../outside.json", "cal/../../x.json", "C:\\\\x.json"])
def test_a_file_outside_the_scenario_directory_is_rejected(tmp_path, path):
    p = tmp_path / "s.yaml"
    p.write_text(SCN + f"firmware: {{calibration: {{source: file, file: '{path}'}}}}\n")
    with pytest.raises(ScenarioError) as exc:
        load_scenario(p)
    assert "s.yaml:" in str(exc.value) and "calibration" in str(exc.value)


def test_residuals_out_of_range_name_file_line_field_and_range(tmp_path):
    p = tmp_path / "s.yaml"
    p.write_text(SCN + "firmware:\n  calibration:\n    residuals:\n      boresight_deg: 10\n")
    with pytest.raises(ScenarioError) as exc:
        load_scenario(p)
    msg = str(exc.value)
    assert "s.yaml:12" in msg and "boresight_deg" in msg and "2" in msg
