"""The compass device with its own unit layout and a blocked-units schedule (the psns_unit_blocked fault
injector maps onto CompassModel.block_units)."""

from __future__ import annotations

import datetime as dt

import numpy as np
import pytest

from emulator.devices.compass import CompassConfig, CompassModel
from emulator.errors import ScenarioError
from emulator.testing import load_test_scenario
from emulator.world.sky import sky_from_spec
from emulator.world.sun import SunModel
from emulator.world.trajectory import StaticTrajectory
from firmware_model.variants.common import compass_mountings
from tests.conftest import SCENARIOS

THREE = compass_mountings([(0.0, 0.0), (45.0, 0.0), (45.0, 90.0)])


def _model(**kw) -> CompassModel:
    traj = StaticTrajectory(39.979, 116.339, 50.0, 30.0, 2.0, -3.0)
    sun = SunModel(dt.datetime(2019, 9, 18, 8, 14, tzinfo=dt.UTC), 69.0)
    return CompassModel(CompassConfig(mountings=THREE, **kw), sky_from_spec(None), sun, traj, np.random.default_rng(1))


def test_blocked_units_see_unpolarized_light_and_scrambled_aop():
    m = _model(blocked=(((1, 2), 10.0, 20.0),))
    clear = m.read(5.0)
    assert list(clear.units) == [0, 1, 2] and np.all(clear.dop > 0.3)
    aops, dops = [], []
    for t in np.arange(10.0, 20.0, 0.2):
        r = m.read(float(t))
        assert r.dop[0] > 0.3 and np.all(r.dop[1:] < 0.02)  # DOP ~ 0 (channel noise) on the blocked units
        aops.append(r.aop[1])
        dops.append(r.dop[1])
    assert np.std(aops) > 0.6  # scrambled: spread over (-90, 90] deg (uniform std = 0.91 rad)
    assert m.blocked_units(15.0) == [1, 2] and m.blocked_units(20.0) == []
    assert np.all(m.read(25.0).dop > 0.3)


def test_block_units_validates_its_arguments():
    m = _model()
    with pytest.raises(ValueError, match=r"units 0\.\.2"):
        m.block_units([3], 0.0, 1.0)
    with pytest.raises(ValueError, match="end > start"):
        m.block_units([1], 5.0, 5.0)


def test_scenario_units_and_blocked_windows_are_checked():
    s = load_test_scenario(SCENARIOS / "dual_vector_sensor_failure.yaml", {})
    assert len(s.sensors.compass.units) == 3 and s.sensors.compass.blocked[0].units == [1, 2]
    with pytest.raises(ScenarioError, match=r"units 0\.\.2"):
        load_test_scenario(SCENARIOS / "dual_vector_sensor_failure.yaml",
                           {"sensors.compass.blocked": [{"units": [3], "start_s": 1.0, "duration_s": 1.0}]})
