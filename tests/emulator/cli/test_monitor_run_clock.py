"""``psns-hil monitor`` on a live pty of a realtime run shows ``t_s`` on the scenario clock (issue 41): the run
publishes its clock's origin in ``clock.json`` (CLOCK_MONOTONIC of scenario time 0, the mode, the speed) and the
monitor reads it. Before, ``t_s`` counted from when the monitor opened the pty, so a monitor attached 2 s into the
run was 2 s off the capture's times of the same frames."""

from __future__ import annotations

import asyncio
import json
import sys

import pytest

from emulator.cli.monitor import run_clock_origin
from tests.conftest import ROOT, SCENARIOS


@pytest.mark.pty
@pytest.mark.psns_emulator(mode="realtime")
@pytest.mark.realtime
async def test_monitor_on_a_live_pty_shows_the_scenario_clock(tmp_path):
    from emulator.testing import start_emulator

    run = tmp_path / "run"
    ov = {"duration_s": 8.0, "motion": [{"static": {"duration_s": 8.0}}], "expectations": [],
          "links.host.url": "pty://uart0"}
    async with start_emulator(SCENARIOS / "quickstart.yaml", run_dir=run, overrides=ov) as emu:
        clock = json.loads((run / "clock.json").read_text())
        assert clock["mode"] == "realtime" and clock["speed"] == 1.0
        assert run_clock_origin(str(run / "ports" / "uart0")) == (clock["t0_monotonic_s"], 1.0)
        await emu.wait_until(lambda: emu.time >= 2.0, timeout=10.0)  # attach 2 s into the run
        proc = await asyncio.create_subprocess_exec(
            sys.executable, "-m", "emulator", "monitor", str(run / "ports" / "uart0"), "--count", "60", "--json",
            cwd=ROOT, stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE)
        out, err = await asyncio.wait_for(proc.communicate(), timeout=30.0)
        assert proc.returncode == 0, err.decode()
    live = {r["fields"]["seq"]: r["t_s"] for r in map(json.loads, out.decode().splitlines())
            if r["type"] == "NavSolution"}
    assert len(live) >= 50
    # the same frames in the run's capture, stamped with the scenario clock
    cap = await asyncio.create_subprocess_exec(
        sys.executable, "-m", "emulator", "monitor", str(run / "capture.psnscap"), "--link", "host", "--json",
        cwd=ROOT, stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE)
    cout, cerr = await asyncio.wait_for(cap.communicate(), timeout=60.0)
    assert cap.returncode == 0, cerr.decode()
    recorded = {r["fields"]["seq"]: r["t_s"] for r in map(json.loads, cout.decode().splitlines())
                if r["type"] == "NavSolution"}
    lags = sorted(live[s] - recorded[s] for s in live if s in recorded)
    assert len(lags) >= 50
    assert min(live.values()) >= 2.0  # attached 2 s in: its clock is the run's, not its own
    # a byte reaches the pty when the run writes it: never before its scenario time, late by the machine's latency
    assert lags[0] >= -0.05 and lags[len(lags) // 2] <= 0.5, (lags[0], lags[len(lags) // 2], lags[-1])


def test_run_clock_origin_refuses_what_is_not_a_realtime_run_clock(tmp_path):
    (tmp_path / "ports").mkdir()
    pty = str(tmp_path / "ports" / "uart0")
    assert run_clock_origin(pty) is None  # no clock.json yet: the run has not started
    for doc in ({"mode": "fast", "speed": 1.0, "t0_monotonic_s": 1.0}, {"mode": "realtime", "speed": 0,
                "t0_monotonic_s": 1.0}, {"mode": "realtime", "speed": 1.0, "t0_monotonic_s": float("inf")},
                {"mode": "realtime", "speed": 1.0, "t0_monotonic_s": 1e300}, [1, 2], "x" * 5000):
        (tmp_path / "clock.json").write_text(json.dumps(doc))
        assert run_clock_origin(pty) is None, doc
    (tmp_path / "clock.json").write_text(json.dumps({"mode": "realtime", "speed": 2.0, "t0_monotonic_s": 1.5}))
    assert run_clock_origin(pty) == (1.5, 2.0)
    assert run_clock_origin(str(tmp_path / "uart0")) is None  # not under ports/
