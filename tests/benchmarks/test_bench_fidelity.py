"""The real-time-factor table's world-fidelity row switches off what docs/performance.md section 2 says it does,
and nothing of the firmware: the reference with ``FIDELITY_OFF`` against the reference as it is."""

from __future__ import annotations

from benchmarks.bench_realtime_factor import FIDELITY_OFF, REFERENCE
from emulator.devices.camera.optics import SensorDefects
from emulator.devices.sensors import build_vibration, camera_config, gyro_lp_filter_hz, imu_temperature
from emulator.scenario import load_scenario


def test_fidelity_off_switches_off_the_world_instrument_models_only():
    on = load_scenario(REFERENCE)
    off = load_scenario(REFERENCE, FIDELITY_OFF)
    # on: the reference really has the fidelity the row prices
    assert build_vibration(on, 1) is not None
    assert imu_temperature(on).warms_up
    assert gyro_lp_filter_hz(on) > 0
    cam_on = camera_config(on, 1)
    assert cam_on.defects != SensorDefects() and cam_on.extinction_ratio != 300.0
    # off: none of it
    assert build_vibration(off, 1) is None
    assert not imu_temperature(off).warms_up
    assert gyro_lp_filter_hz(off) == 0
    cam_off = camera_config(off, 1)
    assert cam_off.defects == SensorDefects() and cam_off.extinction_ratio == 300.0
    # the same sky, sensors, links, firmware and duration
    assert off.sky == on.sky and off.firmware == on.firmware and off.links == on.links
    assert off.duration_s == on.duration_s and off.sensors.gnss == on.sensors.gnss
    assert cam_off.k1 == cam_on.k1 and cam_off.noise == cam_on.noise
