"""The STIM210 model's STATUS byte (issue 41 item 6): an axis beyond the unit's range is clipped to it and flagged
OVERLOAD with its channel bit, as the datasheet defines the byte (TS1524 r31 Table 5-23, docs/reference/
wire-formats.md 1.6; the layout is declared once, protocols.stim.StimStatus), on both the look-ahead path (truth)
and the per-trigger path (recorded data, injected faults). The FPGA passes the byte on in the IMU frame."""

from __future__ import annotations

import asyncio

import numpy as np

from emulator.clock import EmulatorLoop
from emulator.devices.imu import GyroErrors, ImuTruthTap, Stim210Gyro
from emulator.links import LineConfig, MemHub
from emulator.scenario.presets import preset
from emulator.world.trajectory import StaticTrajectory
from protocols.constants import DEG
from protocols.stim import GYRO_RATE_LSB_DPS, Stim210Format, StimStatus
from protocols.stream import StreamDecoder


def _datagrams(errs: GyroErrors, source=None, n: int = 10):
    loop = EmulatorLoop("fast")
    a, b = MemHub().pair("gyro", LineConfig(baud=460800), loop)
    gyro = Stim210Gyro(a, ImuTruthTap(StaticTrajectory(39.979, 116.339, 50.0, 30.0)), np.random.default_rng(1), errs,
                       source=source)
    dec = StreamDecoder([Stim210Format("m")])
    got = []
    b.on_receive = lambda d: got.extend(dec.feed(d))

    async def main():
        for k in range(1, n + 1):
            gyro.trigger(k * 0.005, (k - 1) * 0.005)
        await asyncio.sleep(0.1)

    loop.run_until_complete(main())
    loop.close()
    return got


def test_recorded_rate_beyond_the_range_sets_overload_on_its_axis():
    """500 deg/s on y (range 400): the word is clipped to 400 deg/s and STATUS says overload on Y; 399 deg/s on x
    is neither clipped nor flagged."""
    errs = GyroErrors(**preset("imu", "perfect")["gyro"])
    rec = np.array([399.0, -500.0, 0.0]) * DEG
    got = _datagrams(errs, source=lambda t0, t1: rec if t1 <= 0.0251 else np.zeros(3))
    assert len(got) == 10
    over = got[:5]
    assert all(d.status == StimStatus.OVERLOAD | StimStatus.Y_CHANNEL for d in over)
    assert all(d.gyro[1] == -round(400.0 / GYRO_RATE_LSB_DPS) for d in over)
    assert all(d.gyro[0] == round(399.0 / GYRO_RATE_LSB_DPS) for d in over)
    assert all(d.status == 0 and d.gyro == (0, 0, 0) for d in got[5:])


def test_truth_beyond_a_tiny_range_sets_overload_on_the_look_ahead_path():
    """A unit with a 0.001 deg/s range on the static vehicle (Earth rate 0.0042 deg/s, north and up components):
    every datagram flags the axes the Earth rate exceeds it on, from the block-wise look-ahead."""
    errs = GyroErrors(**{**preset("imu", "perfect")["gyro"], "range_dps": 0.001})
    got = _datagrams(errs)
    assert len(got) == 10
    lim = round(0.001 / GYRO_RATE_LSB_DPS)
    for d in got:
        flagged = {i for i, bit in enumerate((StimStatus.X_CHANNEL, StimStatus.Y_CHANNEL, StimStatus.Z_CHANNEL))
                   if d.status & bit}
        assert d.status & StimStatus.OVERLOAD and flagged
        assert all(abs(d.gyro[i]) == lim for i in flagged)
        assert all(abs(d.gyro[i]) <= lim for i in range(3))


def test_in_range_datagrams_carry_a_zero_status():
    got = _datagrams(GyroErrors(**preset("imu", "perfect")["gyro"]))
    assert len(got) == 10 and all(d.status == 0 for d in got)
