"""Multi-unit polarization compass: geometry, exact inversion, AOP accuracy against DOP, frames."""

from __future__ import annotations

import asyncio
import datetime as dt
import math

import numpy as np
import pytest

from emulator.clock import EmulatorLoop
from emulator.devices.compass import CompassConfig, CompassModel, PolarizationCompass, _own_mountings, default_mountings
from emulator.links import LineConfig, MemHub
from emulator.world.sky import SkyModel
from emulator.world.sun import SunModel
from emulator.world.trajectory import StaticTrajectory
from protocols.psns import CompassFrame, PsnsFormat, PsnsStatus
from protocols.stream import StreamDecoder

EPOCH = dt.datetime(2019, 12, 1, 2, 0, tzinfo=dt.UTC)  # Taiyuan reference case


def compass(noise=True, seed=1, heading=10.0, pitch=0.0, roll=0.0, **kw):
    traj = StaticTrajectory(37.59, 112.24, 800.0, heading, pitch, roll)
    return CompassModel(CompassConfig(noise=noise, **kw), SkyModel(), SunModel(EPOCH, 69.0), traj,
                        np.random.default_rng(seed))


def test_default_geometry():
    m = default_mountings()
    assert m.shape == (9, 3, 3)
    assert np.allclose(m[0], np.eye(3))
    for c in m:
        assert np.allclose(c.T @ c, np.eye(3), atol=1e-15) and math.isclose(np.linalg.det(c), 1.0)
    for k in range(1, 9):
        z, y = m[k][:, 2], m[k][:, 1]
        assert math.isclose(math.degrees(math.acos(z[2])), 45.0)
        az = math.degrees(math.atan2(z[0], z[1])) % 360  # from body +y towards +x
        assert math.isclose(az, 45.0 * (k - 1), abs_tol=1e-9)
        assert y[2] > 0 and abs(y @ z) < 1e-15 and abs(m[k][2, 0]) < 1e-15  # y up the hemisphere, x level


def test_installed_geometry_matches_the_firmware_nominal_layout():
    """The world's declaration and the firmware's nominal copy are written separately; they describe one layout."""
    from emulator.devices.compass import mountings_from_directions
    from firmware_model import psns_geometry as geo
    from firmware_model.variants.common import compass_mountings

    assert np.allclose(geo.compass_unit_mountings(), _own_mountings(), atol=1e-15)
    dirs = [(0.0, 30.0), (60.0, 0.0), (60.0, 120.0), (30.0, 250.0)]
    assert np.allclose(compass_mountings(dirs), mountings_from_directions(dirs), atol=1e-15)


def test_noise_free_units_invert_exactly():
    for att in ((10.0, 0.0, 0.0), (123.0, 12.0, -7.0)):
        cm = compass(noise=False, heading=att[0], pitch=att[1], roll=att[2])
        r = cm.read(0.0)
        assert r.status & PsnsStatus.VALID and len(r.units) == 9
        st = cm.traj.state(0.0)
        s_b = st.c_bn.T @ cm.sun.sun_enu(0.0, *st.pos)
        for u, a in zip(r.units, r.aop):
            e_b = cm.mountings[u] @ np.array([math.sin(a), math.cos(a), 0.0])
            assert abs(e_b @ s_b) < 1e-12


def test_aop_accuracy_0_1_deg_at_high_dop_and_growing_as_dop_falls():
    truth = compass(noise=False).read(0.0)
    cm = compass(seed=3)
    n = 4000
    errs = np.array([(cm.read(0.0).aop - truth.aop + math.pi / 2) % math.pi - math.pi / 2 for _ in range(n)])
    sd = np.degrees(errs.std(axis=0))
    pred = 0.1 * cm.cfg.dop_ref / truth.dop  # 0.1 deg at DOP_ref, sigma/(sqrt(2) S0 DOP) elsewhere
    assert np.all(np.abs(sd / pred - 1) < 0.1)
    # the truth DOPs span a range, so this checks the 1/DOP growth too
    assert truth.dop.max() / truth.dop.min() > 1.5


def test_sun_in_a_unit_saturates_it():
    # sun az 144.9, el 22.2 in Taiyuan: pitch the box so that ring unit 1 (forward) looks at the sun
    cm = compass(noise=False, heading=144.9255, pitch=-(45.0 - 22.1787))
    r = cm.read(0.0)
    assert r.status & PsnsStatus.SATURATED and 1 not in r.units and len(r.units) == 8


def test_compass_device_frames():
    loop = EmulatorLoop("fast")
    hub = MemHub()
    a, b = hub.pair("psns", LineConfig(baud=115200), loop)
    dec = StreamDecoder([PsnsFormat()])
    frames = []
    b.on_receive = lambda d: frames.extend((loop.time(), f) for f in dec.feed(d))
    dev = PolarizationCompass(a, compass(), rate_hz=10.0, integration_s=0.01, processing_s=0.005)

    async def main():
        dev.start()
        await asyncio.sleep(1.0)

    loop.run_until_complete(main())
    loop.close()
    assert len(frames) == 10
    for k, (t_rx, f) in enumerate(frames):
        assert isinstance(f, CompassFrame) and len(f.units) == 9 and f.header.seq == k
        n_bytes = 7 + 13 + 5 * 9
        t_mid = t_rx - n_bytes * 10 / 115200 - f.header.latency_us * 1e-6
        assert t_mid == pytest.approx(k * 0.1 + 0.005, abs=1e-6)


def test_calibration_residuals_turn_each_unit_about_its_ray_and_offset_its_aop_exactly():
    """``aop_offset_deg`` (Zhang et al. Table 2's residuals): each reported AOP is the nominal one plus its unit's
    offset, exactly (noise-free), and the view rays do not move."""
    from emulator.devices.compass import turned_about_view_rays
    from emulator.devices.sensors import compass_config
    from emulator.scenario.sensor_schema import Sensors

    table2 = [-0.1, 0.1, 0.3, 0.2, 0.2, 0.2, -0.2, -0.1, -0.1]

    class _Scn:
        sensors = Sensors.model_validate({"compass": {"preset": "ideal", "aop_offset_deg": table2}})

    mounts = compass_config(_Scn()).mountings  # type: ignore[arg-type]
    assert np.allclose(mounts, turned_about_view_rays(default_mountings(), np.radians(table2)), atol=0)
    assert np.allclose(mounts[:, :, 2], default_mountings()[:, :, 2], atol=1e-15)
    for att in ((10.0, 0.0, 0.0), (123.0, 12.0, -7.0)):
        nominal = compass(noise=False, heading=att[0], pitch=att[1], roll=att[2]).read(0.0)
        turned = compass(noise=False, heading=att[0], pitch=att[1], roll=att[2], mountings=mounts).read(0.0)
        assert list(turned.units) == list(nominal.units)
        d = (turned.aop - nominal.aop + math.pi / 2) % math.pi - math.pi / 2
        assert np.allclose(np.degrees(d), np.array(table2)[nominal.units], atol=1e-9)


def test_calibration_residuals_need_one_value_per_unit():
    from pydantic import ValidationError

    from emulator.scenario.sensor_schema import CompassSpec

    with pytest.raises(ValidationError, match="9 units, got 2"):
        CompassSpec.model_validate({"aop_offset_deg": [0.1, 0.2]})
    with pytest.raises(ValidationError, match="within"):
        CompassSpec.model_validate({"aop_offset_deg": [0.1] * 8 + [12.0]})
