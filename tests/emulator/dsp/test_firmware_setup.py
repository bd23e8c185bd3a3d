"""Scenario -> FirmwareConfig (emulator/dsp/firmware_setup.py): the firmware section and derived fields."""

import math

import numpy as np

from emulator.dsp.firmware_setup import build_firmware, calibration_for, firmware_config
from emulator.scenario import load_scenario
from firmware_model.attitude import a2mat, yaw_from_heading

BASE = """\
name: t
epoch: 2019-09-18T08:14:00Z
duration_s: 10
origin: {lat_deg: 39.979, lon_deg: 116.339, height_m: 50}
"""


def _load(tmp_path, extra=""):
    p = tmp_path / "s.yaml"
    p.write_text(BASE + extra)
    return load_scenario(p)


def test_defaults_without_psns_link(tmp_path):
    cfg = firmware_config(_load(tmp_path))
    assert cfg.filter == "base" and cfg.precision == "float32"
    assert cfg.psns_enabled is False  # no psns link in the scenario
    assert cfg.alignment_heading == "auto" and cfg.psns_baud == 115200
    assert cfg.camera.projection == "pinhole" and np.allclose(cfg.camera.c_c_b, np.eye(3))


def test_psns_section_camera_and_uart2_baud(tmp_path):
    scn = _load(tmp_path, """\
links:
  psns: {url: "mem://psns", baud: 230400}
fpga:
  uarts: {uart2: {baud: 230400}}
sensors:
  imu: {output: angle}
firmware:
  precision: float64
  alignment: {heading_source: psns, psns_timeout_s: 5, fine_time_s: 30}
  psns:
    sigma_deg: 0.05
    camera: {projection: fisheye, focal_mm: 1.8, mounting_heading_deg: -90, mounting_roll_deg: 1.0}
""")
    cfg = firmware_config(scn)
    assert cfg.psns_enabled and cfg.psns_baud == 230400 and cfg.psns_sigma_deg == 0.05
    assert cfg.alignment_heading == "psns" and cfg.psns_align_timeout_s == 5 and cfg.fine_align_time_s == 30
    assert cfg.camera.projection == "fisheye" and math.isclose(cfg.camera.focal_m, 1.8e-3)
    assert np.allclose(cfg.camera.c_c_b, a2mat(0.0, math.radians(1.0), math.radians(90)))
    assert np.allclose(cfg.camera.c_c_b, a2mat(0.0, math.radians(1.0), yaw_from_heading(math.radians(-90))))
    assert cfg.gyro_output == "angle" and cfg.subsamples == 2
    fw = build_firmware(scn)
    assert fw.cost.double and fw.dtype == np.float64


CAM_SCN = """\
links:
  psns: {url: "mem://psns", baud: 115200}
sensors:
  camera:
    lens: fisheye
    focal_length_mm: 1.8
    mounting: {heading_deg: 10, pitch_deg: 5, installation_error_deg: [0.3, 0, 0]}
"""


def test_camera_calibration_nominal_is_the_design_and_ignores_the_installation_error(tmp_path):
    # (this test used to be the default; the default is now a calibrated unit, tested below)
    scn = _load(tmp_path, CAM_SCN + "firmware: {calibration: {source: nominal}}\n")
    cam = firmware_config(scn).camera
    assert cam.projection == "fisheye" and math.isclose(cam.focal_m, 1.8e-3)
    assert cam.paper_lens  # no lens measurement: the paper's model
    # nominal mount only: the installation error is what the DSP does not know
    assert np.allclose(cam.c_c_b, a2mat(math.radians(5), 0.0, yaw_from_heading(math.radians(10))))


def test_camera_calibration_perfect_knows_the_truth_and_residuals_are_close_to_it(tmp_path):
    from emulator.devices.sensors import camera_config

    scn = _load(tmp_path, CAM_SCN + "firmware: {calibration: {source: perfect}}\n")
    truth = camera_config(scn)
    cam = firmware_config(scn).camera
    assert np.allclose(cam.c_c_b, truth.mounting_c_b, atol=1e-12)
    assert (cam.k1, cam.exit_pupil_m, cam.cx_px) == (truth.k1, truth.exit_pupil_m, truth.lens_model.cx)
    scn = _load(tmp_path, CAM_SCN)  # default: residuals
    cams = [firmware_config(scn, calibration_for(scn, seed)).camera for seed in range(20)]
    ang = [math.degrees(math.acos(min(1.0, (np.trace(c.c_c_b.T @ truth.mounting_c_b) - 1) / 2))) for c in cams]
    assert 0.0 < np.median(ang) < 0.2  # three axes of 0.05 deg
    assert all(abs(c.focal_m / truth.focal_m - 1) < 5e-3 for c in cams)
    assert len({c.cx_px for c in cams}) == 20


def test_the_firmware_knows_the_configured_ranges(tmp_path):
    """The fitted units' measurement ranges reach the firmware (issue 41: words beyond them are refused, D-5.46):
    the presets' +-400 deg/s and +-30/25/25 g, or what the scenario configures."""
    cfg = firmware_config(_load(tmp_path))
    assert cfg.gyro_range_dps == 400.0 and cfg.accel_range_g == (30.0, 25.0, 25.0)
    cfg = firmware_config(_load(tmp_path, "sensors:\n  imu:\n    gyro: {range_dps: 300}\n"
                                          "    accel: {range_g: [10, 10, 12]}\n"))
    assert cfg.gyro_range_dps == 300.0 and cfg.accel_range_g == (10.0, 10.0, 12.0)


def test_the_installed_unit_is_drawn_once_and_the_calibration_reads_that_draw(tmp_path, monkeypatch):
    """The compass's true mountings (a random installation error) are drawn once per run and shared: the calibration
    file is made from the very unit the sensor models were built with, not from a second draw under the same key."""
    from dataclasses import replace

    from scipy.spatial.transform import Rotation

    import emulator.assembly.session as session
    from emulator.devices import sensors
    from emulator.devices.compass import default_mountings

    scn = _load(tmp_path, "links:\n  psns: {url: \"mem://psns\"}\n"
                          "sensors:\n  compass: {installation_error_sigma_deg: 0.5}\n"
                          "firmware:\n  calibration: {source: perfect}\n")
    unit = sensors.installed_unit(scn, 7)
    # a unit turned by a known rotation: a calibration that re-drew the truth could not see it
    turn = Rotation.from_rotvec([0.0, 0.0, 2.0], degrees=True).as_matrix()
    turned = replace(unit, compass=replace(unit.compass, mountings=[m @ turn for m in unit.compass.mountings]))
    got = np.array(calibration_for(scn, 7, turned).compass.unit_installation_deg)
    want = np.array([Rotation.from_matrix(n.T @ m @ turn).as_rotvec(degrees=True)
                     for n, m in zip(default_mountings(), unit.compass.mountings, strict=True)])
    np.testing.assert_allclose(got, want, atol=1e-9)
    assert not np.allclose(got, np.array(calibration_for(scn, 7).compass.unit_installation_deg))

    calls = []
    real = session.installed_unit
    monkeypatch.setattr(session, "installed_unit", lambda *a: calls.append(a) or real(*a))
    em = session.Emulator(scn, tmp_path / "run", seed=7)
    assert em.unit is em.unit and len(calls) == 1
