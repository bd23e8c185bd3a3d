"""build_sensors: presets, the PSNS devices on an internal link, the magnetometer, scenario errors."""

from __future__ import annotations

import asyncio

import pytest

from emulator.clock import EmulatorLoop
from emulator.devices.camera import PolarizationCamera
from emulator.devices.compass import PolarizationCompass
from emulator.devices.sensors import build_sensors, camera_config, gnss_config
from emulator.errors import ScenarioError
from emulator.links import LineConfig, MemHub
from emulator.scenario.schema import Scenario
from emulator.world.build import build_trajectory
from protocols.psns import CompassFrame, PolarizationObs, PsnsFormat
from protocols.stream import StreamDecoder


def scenario(sensors=None, **kw):
    d = {"name": "t", "epoch": "2019-09-18T08:14:00Z", "duration_s": 3,
         "origin": {"lat_deg": 39.979, "lon_deg": 116.339, "height_m": 50},
         "links": {"psns": {"url": "mem://psns", "baud": 115200}}, "sensors": sensors or {}}
    d.update(kw)
    return Scenario.model_validate(d)


def wire(scn):
    loop = EmulatorLoop("fast")
    hub = MemHub()
    internal, ext = {}, {}
    for port, baud in (("gyro", 460800), ("gnss", 9600), ("psns", 115200)):
        a, b = hub.pair(port, LineConfig(baud=baud), loop)
        ext[port], internal[port] = a, b
    pps = []
    s = build_sensors(scn, 1, build_trajectory(scn), internal, pps.append)
    return loop, ext, s, pps


def run(loop, ext, s, seconds):
    dec = StreamDecoder([PsnsFormat()])
    frames = []
    ext["psns"].on_receive = lambda d: frames.extend(dec.feed(d))

    async def main():
        s.start()
        await asyncio.sleep(seconds)

    loop.run_until_complete(main())
    loop.close()
    return frames


def test_default_camera_on_a_psns_link():
    loop, ext, s, pps = wire(scenario())
    assert isinstance(s.psns, PolarizationCamera) and s.compass is None and s.mag is None
    frames = run(loop, ext, s, 1.05)
    assert len(frames) == 5 and all(isinstance(f, PolarizationObs) for f in frames)
    assert s.counters()["psns_frames"] == 6 and len(pps) == 2  # the 6th frame is still on the wire


def test_compass_and_camera_share_the_port_and_mag_is_built():
    scn = scenario({"camera": {"fidelity": "binned", "grid": [10, 10], "rate_hz": 2},
                    "compass": {"rate_hz": 10}, "magnetometer": {"noise_nt": 5.0, "hard_iron_nt": [100, 0, 0]}})
    loop, ext, s, _ = wire(scn)
    assert isinstance(s.compass, PolarizationCompass) and s.mag is not None
    assert s.mag.cfg.noise_nt == 5.0 and s.mag.cfg.hard_iron_nt == (100, 0, 0)
    frames = run(loop, ext, s, 1.05)
    assert sum(isinstance(f, CompassFrame) for f in frames) == 11  # t = 0.015 .. 1.015 s
    assert sum(isinstance(f, PolarizationObs) for f in frames) == 2


def test_camera_settings_come_from_preset_and_overrides():
    cfg = camera_config(scenario({"camera": {"preset": "ideal", "lens": "fisheye", "focal_length_mm": 1.8,
                                             "mounting": {"installation_error_deg": [0, 0, 0.5]}}}))
    assert cfg.noise is False and cfg.lens == "fisheye" and cfg.focal_m == pytest.approx(1.8e-3)
    assert cfg.mounting_c_b[0, 1] == pytest.approx(-0.5 * 3.141592653589793 / 180, rel=1e-4)


def test_too_many_points_for_the_line_is_a_scenario_error():
    scn = scenario({"camera": {"grid": [30, 30]}})
    with pytest.raises(ScenarioError, match="max_points"):
        wire(scn)


def test_gnss_config_from_preset_outages_glitches():
    scn = scenario({"gnss": {"preset": "paper", "fix_quality": 2, "outages": [{"start_s": 10, "duration_s": 5}],
                            "glitches": [{"start_s": 3, "duration_s": 1, "offset_enu_m": [5, 0, 0]}],
                            "errors": {"pos_sigma_h_m": 2.0}}})
    g = gnss_config(scn)
    assert g.fix_quality == 2 and g.errors.pos_sigma_h_m == 2.0 and g.errors.pos_sigma_v_m == 7.5
    assert g.outages[0].duration_s == 5 and g.glitches[0].offset_enu_m == (5, 0, 0)
    with pytest.raises(ValueError):
        scenario({"gnss": {"reacquisition_s": 1.5}})
