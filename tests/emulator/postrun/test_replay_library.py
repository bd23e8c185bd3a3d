"""Replay works on every library scenario's capture (issue 38: bench_vehicle_loop_10min's capture did not replay,
its embedded scenario had lost the suite preset): the replay's nav.csv and the host's bytes are the original's,
bit for bit. ``make test`` replays a 3 s run of each; the slow step replays the full runs."""

from __future__ import annotations

from pathlib import Path

import pytest

from emulator.assembly.session import run_scenario
from emulator.postrun.replay import load_replay, run_replay, same_file
from emulator.recording.capture import read_capture
from emulator.scenario.loader import load_scenario
from tests.conftest import SCENARIOS

LIBRARY = sorted(SCENARIOS.glob("*.yaml"))


def _replay_matches(scenario: Path, overrides: list[str], tmp_path: Path) -> None:
    scn = load_scenario(scenario, overrides)
    run_scenario(scn, tmp_path / "run")
    cap = tmp_path / "run" / "capture.psnscap"
    replayed, _records, _header = load_replay(cap)
    assert replayed.model_dump(mode="json") == scn.model_dump(mode="json")  # the embedded scenario is the run's
    run_replay(cap, tmp_path / "replay")
    assert same_file(tmp_path / "run" / "nav.csv", tmp_path / "replay" / "nav.csv")
    _h, orig = read_capture(cap)
    _h, rep = read_capture(tmp_path / "replay" / "capture.psnscap")
    a = [(x.t_s, x.data) for x in orig if x.link == "host" and x.direction == "out"]
    b = [(x.t_s, x.data) for x in rep if x.link == "host" and x.direction == "out"]
    assert a == b and a


@pytest.mark.parametrize("scenario", LIBRARY, ids=[p.stem for p in LIBRARY])
def test_a_short_run_of_every_library_scenario_replays_bit_for_bit(tmp_path, scenario):
    _replay_matches(scenario, ["duration_s=3", "faults=[]", "expectations=[]"], tmp_path)


@pytest.mark.slow
@pytest.mark.parametrize("scenario", LIBRARY, ids=[p.stem for p in LIBRARY])
def test_every_library_scenario_replays_bit_for_bit(tmp_path, scenario):
    _replay_matches(scenario, [], tmp_path)
