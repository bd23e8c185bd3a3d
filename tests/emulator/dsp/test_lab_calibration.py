"""The lab calibration (firmware.calibration.source: lab): the firmware's lens family fitted to simulated bench
observations of the true lens, which can be outside that family: then the calibration is wrong."""

from __future__ import annotations

import numpy as np
import pytest

from emulator.devices.sensors import camera_config
from emulator.dsp.firmware_setup import calibration_for, lab_lens_fit
from emulator.scenario.loader import load_scenario
from tests.conftest import ROOT

QS = ROOT / "scenarios" / "quickstart.yaml"


def test_a_lens_inside_the_family_is_recovered():
    cc = camera_config(load_scenario(QS), 1)
    f, cx, cy, k1, k2 = lab_lens_fit(cc, np.random.default_rng(2))
    assert f == pytest.approx(cc.focal_m, rel=2e-5)
    assert (cx, cy) == pytest.approx((cc.lens_model.cx, cc.lens_model.cy), abs=0.02)
    assert k1 == pytest.approx(cc.k1, abs=2e-4) and abs(k2 - cc.k2) < 2e-4


def test_a_lens_outside_the_family_leaves_a_model_form_error():
    over = ["sensors.camera.optics.distortion_k3=0.005", "sensors.camera.optics.tangential_p1=0.0005",
            "sensors.camera.optics.tangential_p2=-0.0005"]
    cc = camera_config(load_scenario(QS, overrides=over), 1)
    f, cx, cy, k1, k2 = lab_lens_fit(cc, np.random.default_rng(2))
    # the fit absorbs the decentering into the principal point and k3 into k1, k2: the file is wrong by
    # far more than its centroid noise could make it
    assert abs(cx - cc.lens_model.cx) > 0.5 or abs(cy - cc.lens_model.cy) > 0.5
    assert abs(k1 - cc.k1) > 5e-3 and abs(k2 - cc.k2) > 1e-3
    assert abs(f / cc.focal_m - 1.0) > 1e-3


def test_the_lab_source_writes_the_fit_into_the_calibration_file():
    scn = load_scenario(QS, overrides=["firmware.calibration.source=lab", "sensors.camera.optics.distortion_k3=0.005"])
    cal = calibration_for(scn, 4).camera
    cc = camera_config(scn, 4)
    assert cal.k1 != cc.k1 and cal.projection == "pinhole"
    assert calibration_for(scn, 4) == calibration_for(scn, 4)  # reproducible per seed
