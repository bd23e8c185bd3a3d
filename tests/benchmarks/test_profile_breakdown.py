"""``benchmarks.profile_breakdown``: which component a profiled function is charged to, and how library time is
passed on to its callers."""

from __future__ import annotations

import pytest

from benchmarks.profile_breakdown import OTHER, RECORDER, attribute, home_of, main

RUNNER = "runner (setup, 1 Hz samples, summary, expectations)"


@pytest.mark.parametrize(("path", "component"), [
    # the recorder's work while the run goes: listener, capture file, nav and solar vectors vs truth, counting
    # decoders, CSV cells
    ("/w/emulator/recording/recorder.py", RECORDER),
    ("/w/emulator/recording/capture.py", RECORDER),
    ("/w/emulator/recording/nav_error.py", RECORDER),
    ("/w/emulator/recording/psns_error.py", RECORDER),
    ("/w/emulator/recording/counting.py", RECORDER),
    ("/w/emulator/recording/formatting.py", RECORDER),
    # after the run: the runner's
    ("/w/emulator/recording/summary_model.py", RUNNER),
    ("/w/emulator/postrun/report.py", RUNNER),
    ("/w/emulator/postrun/golden.py", RUNNER),
    ("/w/emulator/assembly/runner.py", RUNNER),
    ("/w/emulator/links/base.py", "links (line model, mem transport)"),
    ("/w/protocols/stream.py", "protocols (frame build / stream decode)"),
    ("C:\\w\\emulator\\recording\\nav_error.py", RECORDER),
    ("/usr/lib/python3.11/asyncio/events.py", "asyncio loop (incl. emulator.clock)"),
    ("/v/site-packages/numpy/core/numeric.py", None),
    ("~", None),
])
def test_home_of_charges_each_file_to_its_component(path, component):
    assert home_of((path, 1, "f")) == component


class _Stats:
    def __init__(self, stats):
        self.stats = stats


def test_library_time_goes_to_its_callers_in_proportion():
    rec = ("/w/emulator/recording/nav_error.py", 101, "_compare")
    run = ("/w/emulator/assembly/runner.py", 10, "run")
    lib = ("~", 0, "<built-in method builtins.repr>")
    orphan = ("~", 0, "<built-in method builtins.len>")
    # (cc, nc, tottime, cumtime, callers: {caller: (cc, nc, tottime, cumtime)})
    stats = {
        rec: (1, 1, 0.5, 2.0, {}),
        run: (1, 1, 0.25, 1.0, {}),
        lib: (4, 4, 1.0, 1.0, {rec: (3, 3, 0.75, 0.75), run: (1, 1, 0.25, 0.25)}),
        orphan: (1, 1, 0.125, 0.125, {}),
    }
    acc = attribute(_Stats(stats))  # type: ignore[arg-type]
    assert acc == {RECORDER: 0.5 + 0.75, RUNNER: 0.25 + 0.25, OTHER: 0.125}


def test_help_names_the_arguments(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    assert "scenario" in out and "duration_s" in out


def test_set_overrides_the_scenario_before_the_profile(capsys):
    """``--set`` reaches the profiled run: with the world-only override no firmware function is charged."""
    from benchmarks.bench_realtime_factor import REFERENCE, WORLD_ONLY

    assert main([str(REFERENCE), "0.5"]) == 0
    with_dsp = capsys.readouterr().out
    assert main([str(REFERENCE), "0.5", "--set", WORLD_ONLY[0]]) == 0
    world_only = capsys.readouterr().out
    assert "firmware (firmware_model)" in with_dsp and "DSP host" in with_dsp
    assert "firmware (firmware_model)" not in world_only and "DSP host" not in world_only
    assert "device: IMU" in world_only and "FPGA" in world_only


def test_profile_run_counts_the_loops_callbacks():
    """The event-loop callbacks a run made are counted (each runs in its context: ``Context.run``, D-10.E22): the
    quickstart's 200 Hz trigger, the gyro's datagram and the frames it carries give a few per tick, not none."""
    from benchmarks.profile_breakdown import profile_run
    from emulator.testing import load_test_scenario
    from tests.conftest import SCENARIOS

    scn = load_test_scenario(SCENARIOS / "quickstart.yaml", {"duration_s": 2.0})
    _acc, summary, callbacks = profile_run(scn)
    ticks = round(summary["sim_duration_s"] * scn.sensors.imu.rate_hz)
    assert ticks == 400
    assert 2.0 < callbacks / ticks < 10.0
