"""The firmware's calibration file: round trip, rejection of unusable files, and the scenario's way to it."""

from __future__ import annotations

import json
import math

import numpy as np
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
    {"camera": {"polarizer_deg": [0, 90, 45, 135]}},  # the camera's Stokes assume 0/45/90/135 within 10 deg
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



BORESIGHT = "mounting: {installation_error_deg: [0.0, 0.0, 0.5]}"


def _static_camera_scenario(tmp_path, name, calibration_yaml, camera_extra=BORESIGHT):
    """static_psns_camera with a world-only perturbation of the camera (by default turned 0.5 deg about its
    optical axis, the heading axis of an up-looking camera), and the given firmware.calibration."""
    from pathlib import Path

    text = (Path(__file__).resolve().parents[3] / "scenarios" / "static_psns_camera.yaml").read_text()
    text = text.replace("bin_superpixels: 8, rate_hz: 5, exposure_us: 1000}",
                        "bin_superpixels: 8, rate_hz: 5, exposure_us: 1000,\n"
                        f"           {camera_extra}}}")
    fw = "firmware:\n"
    assert fw in text
    text = text.replace(fw, fw + f"  calibration: {calibration_yaml}\n")
    p = tmp_path / f"{name}.yaml"
    p.write_text(text)
    return load_scenario(p)


def test_a_boresight_error_the_calibration_knows_vs_one_it_does_not(tmp_path):
    """Known to the calibration, the 0.5 deg boresight error leaves the heading within noise; unknown (the same
    file with the nominal boresight), the heading is off by about 0.5 deg."""
    from dataclasses import replace

    from emulator.assembly.session import run_scenario

    perfect = calibration_for(_static_camera_scenario(tmp_path, "probe", "{source: perfect}"), 3)
    save_calibration(perfect, tmp_path / "known.json")
    save_calibration(replace(perfect, camera=replace(perfect.camera, boresight_rotvec_deg=(0.0, 0.0, 0.0))),
                     tmp_path / "unknown.json")
    rms = {}
    for name in ("known", "unknown"):
        scn = _static_camera_scenario(tmp_path, name, f"{{source: file, file: {name}.json}}")
        s = run_scenario(scn, tmp_path / f"run_{name}")
        rms[name] = next(r["value"] for r in s["expectations"] if "heading" in json.dumps(r))
    assert rms["known"] < 0.2, rms
    assert 0.4 < rms["unknown"] < 0.85 and rms["unknown"] - rms["known"] > 0.3, rms  # 0.5 deg plus the rest


def test_a_polarizer_rotation_the_calibration_knows_vs_one_it_does_not(tmp_path):
    """The polarizer analogue: all four micro-polarizer channels turned by 0.5 deg more than the preset's biases
    (a world-only perturbation: the camera's on-board Stokes assume the nominal angles, so every AOP turns by
    0.5 deg). Known to the calibration (the firmware inverts its Stokes processing with the calibrated angles) the
    heading stays within noise; unknown (the file says the preset's angles) the heading is off by about 0.5 deg
    (the solved sun azimuth moves by 0.59 deg for 0.5 deg at this sun elevation of 23 deg, noise-free solve)."""
    from dataclasses import replace

    from emulator.assembly.session import run_scenario

    turned = "defects: {orientation_bias_deg: [0.6, 0.4, 0.55, 0.45]}"  # the reference preset's + 0.5 deg
    perfect = calibration_for(_static_camera_scenario(tmp_path, "probe", "{source: perfect}", turned), 3)
    assert perfect.camera.polarizer_deg == pytest.approx((0.6, 45.4, 90.55, 135.45))
    save_calibration(perfect, tmp_path / "known.json")
    unknown = tuple(a - 0.5 for a in perfect.camera.polarizer_deg)
    save_calibration(replace(perfect, camera=replace(perfect.camera, polarizer_deg=unknown)),
                     tmp_path / "unknown.json")
    rms = {}
    for name in ("known", "unknown"):
        scn = _static_camera_scenario(tmp_path, name, f"{{source: file, file: {name}.json}}", turned)
        s = run_scenario(scn, tmp_path / f"run_{name}")
        rms[name] = next(r["value"] for r in s["expectations"] if "heading" in json.dumps(r))
    assert rms["known"] < 0.2, rms
    assert 0.4 < rms["unknown"] < 0.85 and rms["unknown"] - rms["known"] > 0.3, rms


def test_camera_defects_override_the_preset_and_are_range_checked(tmp_path):
    from emulator.devices.sensors import camera_config

    p = tmp_path / "s.yaml"
    p.write_text(SCN.replace("camera: {}", "camera: {defects: {orientation_bias_deg: [0.6, 0.4, 0.55, 0.45], "
                                           "prnu: 0.0}}"))
    d = camera_config(load_scenario(p)).defects
    assert d.orientation_bias_deg == (0.6, 0.4, 0.55, 0.45) and d.prnu == 0.0
    assert d.orientation_sigma_deg == 0.2 and d.crosstalk == 0.01  # the reference preset's, not overridden
    p.write_text(SCN.replace("camera: {}", "camera:\n    defects:\n      orientation_bias_deg: [0, 0, 6, 0]"))
    with pytest.raises(ScenarioError) as exc:
        load_scenario(p)
    assert "s.yaml:10" in str(exc.value) and "orientation_bias_deg" in str(exc.value) and "[-5, 5]" in str(exc.value)


COMPASS_SCN = """\
name: cal_compass
seed: 11
epoch: 2019-09-18T08:14:00Z
duration_s: 10
origin: {lat_deg: 39.979, lon_deg: 116.339, height_m: 50}
attitude: {heading_deg: 30.0, pitch_deg: 2.0, roll_deg: -1.0}
sky: {model: rayleigh}
links:
  psns: {url: "mem://psns", baud: 115200}
sensors:
  compass: {preset: paper, aop_sigma_deg: 0.0, installation_error_sigma_deg: 1.0}
  magnetometer: {preset: field, noise_nt: 0.0}
"""


def _compass_solve_error_deg(scn, source):
    """Angle (deg) between the true body-frame sun and the firmware's solve of one noise-free compass reading, the
    firmware knowing its units through the calibration file of ``source``."""
    import numpy as np

    from emulator.devices.base import device_rng
    from emulator.devices.compass import CompassModel
    from emulator.devices.sensors import build_sky, build_sun, compass_config
    from emulator.world.trajectory import StaticTrajectory
    from firmware_model import psns
    from firmware_model.psns_geometry import compass_unit_mountings

    scn = scn.model_copy(update={"firmware": scn.firmware.model_copy(update={
        "calibration": scn.firmware.calibration.model_copy(update={"source": source})})})
    traj = StaticTrajectory(39.979, 116.339, 50.0, 30.0, 2.0, -1.0)
    sun = build_sun(scn)
    model = CompassModel(compass_config(scn, device_rng(scn.seed, "compass_mount")), build_sky(scn, scn.seed), sun,
                         traj, np.random.default_rng(0))
    r = model.read(0.0)
    cfg = firmware_config(scn, calibration_for(scn))
    m = cfg.compass_mountings if cfg.compass_mountings is not None else compass_unit_mountings()  # the firmware's
    assert len(m) == 9
    e = psns.evectors_compass(r.aop.astype(np.float64), m[r.units], dtype=np.float64)
    sol = psns.solve_solar_vector(e, r.dop.astype(np.float64))
    st = traj.state(0.0)
    s_b = st.c_bn.T @ sun.sun_enu(0.0, *st.pos)
    return math.degrees(math.acos(min(1.0, abs(float(sol.s @ s_b)))))


def test_compass_installation_angles_reach_the_firmware(tmp_path):
    """The firmware's compass units are its nominal layout turned by the calibrated installation angles: with the
    truth (perfect) a noise-free reading of units installed with 1 deg (1 sigma) errors gives the sun back to
    float precision; with the layout drawing (nominal) the error stays; residuals (0.13 deg per axis, Zhang et al.
    Table 2) sit between."""
    from emulator.devices.base import device_rng
    from emulator.devices.sensors import compass_config

    p = tmp_path / "c.yaml"
    p.write_text(COMPASS_SCN)
    scn = load_scenario(p)
    true = compass_config(scn, device_rng(scn.seed, "compass_mount")).mountings
    perfect = scn.model_copy(update={"firmware": scn.firmware.model_copy(update={
        "calibration": scn.firmware.calibration.model_copy(update={"source": "perfect"})})})
    cal = calibration_for(perfect)
    assert len(cal.compass.unit_installation_deg) == 9
    assert abs(cal.compass.unit_installation_deg[4][2]) > 0.01  # about the unit's own view axis
    m = firmware_config(perfect, cal).compass_mountings
    assert m is not None and np.allclose(m, true, atol=1e-12)
    errs = {src: _compass_solve_error_deg(scn, src) for src in ("perfect", "residuals", "nominal")}
    assert errs["perfect"] < 1e-4 and errs["nominal"] > 0.3 and errs["perfect"] < errs["residuals"] < errs["nominal"]


def test_compass_aop_offsets_are_what_the_calibration_left(tmp_path):
    """``aop_offset_deg`` is the E-vector error left *after* calibration (Zhang et al. Table 2): even a perfect
    calibration file gives the firmware the installed units without it, so the firmware's unit i differs from the
    world's by exactly the turn of its offset about its view ray (D-5.26; before, the calibration measured the offset
    too and the firmware corrected it away)."""
    from emulator.devices.base import device_rng
    from emulator.devices.compass import turned_about_view_rays
    from emulator.devices.sensors import compass_config

    offsets = [-0.1, 0.1, 0.3, 0.2, 0.2, 0.2, -0.2, -0.1, -0.1]
    p = tmp_path / "c.yaml"
    p.write_text(COMPASS_SCN.replace("installation_error_sigma_deg: 1.0}",
                                     f"installation_error_sigma_deg: 1.0, aop_offset_deg: {offsets}}}"))
    scn = load_scenario(p)
    true = compass_config(scn, device_rng(scn.seed, "compass_mount")).mountings
    perfect = scn.model_copy(update={"firmware": scn.firmware.model_copy(update={
        "calibration": scn.firmware.calibration.model_copy(update={"source": "perfect"})})})
    m = firmware_config(perfect, calibration_for(perfect)).compass_mountings
    assert m is not None
    assert np.allclose(turned_about_view_rays(m, np.radians(offsets)), true, atol=1e-12)
    for mi, ti, d in zip(m, true, offsets, strict=True):
        assert np.allclose(mi[:, 2], ti[:, 2], atol=1e-12)  # the same view ray
        turn = math.degrees(math.atan2(float(mi[:, 1] @ ti[:, 0]), float(mi[:, 0] @ ti[:, 0])))  # t = m R_z(d)
        assert turn == pytest.approx(d, abs=1e-9)


def test_magnetometer_iron_reaches_the_firmware(tmp_path):
    """The firmware's magnetometer consumer returns ``W^-1 (m - h)``: with the truth in the calibration file the
    field preset's 350 nT hard iron and 3 % soft iron leave only the MAG frame's 0.1 nT quantisation; with the
    nominal file (no iron) the error is the iron itself."""
    from emulator.devices.magnetometer import Magnetometer
    from emulator.devices.sensors import mag_config
    from emulator.world.trajectory import StaticTrajectory
    from firmware_model.firmware import Firmware

    p = tmp_path / "c.yaml"
    p.write_text(COMPASS_SCN)
    scn = load_scenario(p)
    traj = StaticTrajectory(39.979, 116.339, 50.0, 30.0, 2.0, -1.0)
    mag = Magnetometer(traj, np.random.default_rng(0), mag_config(scn))
    words, _ = mag.sample(1.0, 0.995)
    truth = mag.field_body(1.0)
    err = {}
    for source in ("perfect", "nominal", "residuals"):
        s = scn.model_copy(update={"firmware": scn.firmware.model_copy(update={
            "calibration": scn.firmware.calibration.model_copy(update={"source": source})})})
        fw = Firmware(firmware_config(s, calibration_for(s)))
        fw.core.add_mag(1.0, words)
        b, n = fw.core.mag_mean_nt(1.0)
        assert n == 1
        err[source] = float(np.linalg.norm(b - truth))
    assert err["perfect"] < 0.2, err
    assert err["nominal"] > 300.0, err
    assert err["perfect"] < err["residuals"] < 500.0, err  # 30 nT and 0.001 (1 sigma) of a calibrated unit


def test_a_file_with_installation_angles_for_the_wrong_number_of_units_is_refused(tmp_path):
    from firmware_model.calibration import CompassCalibration

    save_calibration(Calibration(compass=CompassCalibration(unit_installation_deg=((0.1, 0.0, 0.2),) * 2)),
                     tmp_path / "two.json")
    p = tmp_path / "c.yaml"
    p.write_text(COMPASS_SCN + "firmware: {calibration: {source: file, file: two.json}}\n")
    with pytest.raises(ScenarioError, match="installation angles for 2 compass units, the compass has 9"):
        firmware_config(load_scenario(p))
