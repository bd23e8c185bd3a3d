"""The STIM300 device preset (``sensors.imu.device: stim300``): its datagrams on the gyro link decode as the
configured ID with a good CRC-32 in ours, their words are the truth's rate and specific force within the LSBs, and
the virtual FPGA builds IMU frames from them (no missing gyro, no counter jump) so the firmware navigates."""

from __future__ import annotations

import asyncio

import numpy as np
import pytest

from emulator.clock import EmulatorLoop
from emulator.devices.imu.stim300 import Stim300Imu
from emulator.devices.sensors import build_sensors
from emulator.links import LineConfig, MemHub
from emulator.scenario.schema import Scenario
from emulator.world.build import build_trajectory
from protocols.stim import GYRO_RATE_LSB_DPS
from protocols.stim300 import INCL_LSB_G, STIM300_ACCEL_LSB_G, Stim300Datagram, Stim300Format
from protocols.stream import StreamDecoder


def _scenario(ident: str = "0x93") -> Scenario:
    return Scenario.model_validate({
        "name": "stim300", "epoch": "2019-09-18T08:14:00Z", "duration_s": 3,
        "origin": {"lat_deg": 39.979, "lon_deg": 116.339, "height_m": 50},
        "sensors": {"preset": "ideal", "imu": {"device": "stim300", "stim300_datagram": ident}}})


@pytest.mark.parametrize("ident", ["0x93", "0xA7", "0x90"])
def test_stim300_datagrams_on_the_gyro_link(ident: str) -> None:
    scn = _scenario(ident)
    loop = EmulatorLoop("fast")
    hub = MemHub()
    internal, ext = {}, {}
    for port, baud in (("gyro", 921600), ("gnss", 9600)):
        a, b = hub.pair(port, LineConfig(baud=baud), loop)
        ext[port], internal[port] = a, b
    s = build_sensors(scn, 1, build_trajectory(scn), internal, lambda t: None)
    assert isinstance(s.gyro, Stim300Imu)
    dec = StreamDecoder([Stim300Format(int(ident, 16))])
    got: list[Stim300Datagram] = []
    ext["gyro"].on_receive = lambda d: got.extend(dec.feed(d))

    async def main() -> None:
        s.start()
        for k in range(1, 201):  # the FPGA's triggers at 200 Hz
            loop.call_at(k / 200.0, s.gyro.trigger, k / 200.0, (k - 1) / 200.0)
        await asyncio.sleep(1.01)

    loop.run_until_complete(main())
    loop.close()
    assert len(got) == 200 and dec.stats.crc_errors == 0 and dec.stats.garbage_bytes == 0
    assert all(d.ident == int(ident, 16) for d in got)
    assert {(b - a) % 256 for a, b in zip([d.counter for d in got], [d.counter for d in got][1:])} == {10}
    # a static unit: the gyros read the Earth rate (<= 15.04 deg/h) and the specific force is 1 g up
    w = np.array([d.gyro for d in got]) * GYRO_RATE_LSB_DPS * 3600.0
    assert np.all(np.linalg.norm(w, axis=1) < 15.05 + 0.5)
    if got[0].accel is not None:
        f = np.array([d.accel for d in got]) * STIM300_ACCEL_LSB_G[10]
        assert np.allclose(np.linalg.norm(f, axis=1), 9.8018 / 9.80665, atol=2e-3)  # gravity at 40 deg, 50 m
    if got[0].incl is not None:
        f = np.array([d.incl for d in got]) * INCL_LSB_G
        assert np.allclose(np.linalg.norm(f, axis=1), 9.8018 / 9.80665, atol=2e-3)
    assert (got[0].gyro_temp is not None) == (ident == "0xA7")


def test_a_run_with_a_stim300_on_the_gyro_port_navigates(tmp_path) -> None:
    from emulator.assembly.session import run_scenario

    scn = _scenario("0x93")
    scn.duration_s = 8.0
    summary = run_scenario(scn, tmp_path / "run")
    fpga = summary["fpga"]
    fw = summary["firmware"]["counters"]
    assert fw["imu_frames"] >= 8 * 200 - 2 and fw["gyro_counter_jumps"] == 0 and fw["fpga_gyro_missing"] == 0
    assert summary["links"]["gyro"]["frames"] >= 8 * 200 - 2 and summary["links"]["gyro"]["crc_errors"] == 0
    assert fpga["gyro_missing"] == 0
