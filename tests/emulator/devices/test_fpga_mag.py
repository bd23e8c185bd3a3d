"""Magnetometer on the FPGA trigger: MAG frames on UART1 (docs/icd.md)."""

from __future__ import annotations

import numpy as np

from emulator.assembly.session import run_scenario
from emulator.recording.capture import read_capture
from emulator.testing import load_test_scenario
from protocols import imu_frame
from protocols.stream import StreamDecoder
from tests.conftest import SCENARIOS


def test_mag_frames_follow_the_imu_frames_with_the_modelled_field(tmp_path):
    from emulator.devices.magnetometer import field_enu
    from emulator.world.build import build_trajectory

    scn = load_test_scenario(SCENARIOS / "quickstart.yaml", {
        "duration_s": 2.0, "motion": [{"static": {"duration_s": 2.0}}], "expectations": [],
        "sensors.magnetometer": {"noise_nt": 0.0}})
    s = run_scenario(scn, tmp_path / "run")
    _h, recs = read_capture(tmp_path / "run" / "capture.psnscap")
    stream = b"".join(r.data for r in recs if r.link == "uart1" and r.direction == "in")
    frames = StreamDecoder([imu_frame.FpgaFrameFormat()]).feed(stream)
    imus = [f for f in frames if isinstance(f, imu_frame.ImuFrame)]
    mags = [f for f in frames if isinstance(f, imu_frame.MagFrame)]
    # 100 Hz (the ICD's MAG rate): on every second 200 Hz trigger, right after that trigger's IMU frame
    assert len(mags) == s["fpga"]["mag_frames"] and abs(len(mags) - len(imus) / 2) <= 1 and len(mags) > 195
    assert [m.t_sample_us for m in mags] == [f.t_trigger_us for f in imus[0:2 * len(mags):2]]
    kinds = [type(f).__name__ for f in frames[:6]]
    assert kinds == ["ImuFrame", "MagFrame", "ImuFrame", "ImuFrame", "MagFrame", "ImuFrame"]
    assert [m.seq for m in mags] == list(range(len(mags)))
    # the field words: C_n^b B^n in 0.1 nT (no noise, no iron)
    c_bn = build_trajectory(scn).state(0.0).c_bn
    m = scn.sensors.magnetometer
    want = np.round(c_bn.T @ field_enu(m.declination_deg, m.inclination_deg, m.intensity_nt) / 0.1)
    assert all(tuple(f.field) == tuple(int(x) for x in want) for f in mags)
    assert s["links"]["uart1"]["garbage_bytes"] == 0
