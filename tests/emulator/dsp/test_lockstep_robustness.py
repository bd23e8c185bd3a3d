"""A foreign firmware that crashes, hangs, answers garbage or floods, behind the out-of-process lockstep transport
(docs/icd.md section 10.1, docs/runtime.md "Lockstep"): contained, counted and reported; the run goes on with a
silent DSP to its end and writes its run directory; ``psns-hil run`` exits 1 naming the reason.

The misbehaving firmware is tests/emulator/dsp/faulty_firmware.c (built here with the C compiler): it behaves for
N steps (one step per 5 ms IMU frame) and then does what its mode says. The hang is the one place a test follows
the wall clock: the step timeout (1 s here) is wall-clock time by design.

The in-process transport is not tested for containment: a crash inside a loaded library is a crash of the emulator's
own process, which is what that transport trades for its speed (docs/runtime.md).
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import time
from pathlib import Path

import pytest
import yaml

from emulator.assembly.session import Emulator, run_emulator
from emulator.cli.main import main as cli_main
from emulator.dsp.lockstep import ALLOW_FIRMWARE_ENV
from emulator.recording.summary_model import load_summary
from emulator.scenario import load_scenario

HERE = Path(__file__).resolve().parent
BAD_STEP = 100  # the firmware misbehaves at its 100th step: t = 0.5 s
DURATION_S = 2.0


@pytest.fixture(scope="module")
def faulty(tmp_path_factory) -> Path:
    cc = os.environ.get("CC", "gcc")
    if shutil.which(cc) is None:
        pytest.skip("no C compiler (gcc) on this machine")
    out = tmp_path_factory.mktemp("faulty") / "faulty_firmware"
    subprocess.run([cc, "-O1", "-std=c11", "-Wall", "-Wextra", "-Werror", "-o", str(out),
                    str(HERE / "faulty_firmware.c")], check=True, timeout=120)
    return out


@pytest.fixture(autouse=True)
def allow_firmware(monkeypatch):
    monkeypatch.setenv(ALLOW_FIRMWARE_ENV, "1")


def scenario(d: Path, faulty: Path, mode: str, timeout_s: float = 10.0) -> Path:
    shutil.copy2(faulty, d / "faulty_firmware")
    data = {"name": f"faulty_{mode}", "seed": 3, "epoch": "2019-09-18T02:30:00Z", "duration_s": DURATION_S,
            "mode": "fast", "origin": {"lat_deg": 39.979, "lon_deg": 116.339, "height_m": 50.0},
            "motion": [{"static": {"duration_s": DURATION_S}}],
            "dsp": {"external": {"lockstep": {"command": ["faulty_firmware", mode, str(BAD_STEP)],
                                              "step_timeout_s": timeout_s}}}}
    p = d / f"{mode}.yaml"
    p.write_text(yaml.safe_dump(data, sort_keys=False))
    return p


def run(path: Path, run_dir: Path) -> dict:
    return run_emulator(Emulator(load_scenario(path), run_dir))


@pytest.mark.parametrize(("mode", "reason"), [
    ("crash", "crashed: killed by SIGSEGV"),
    ("exit", "exited with status 3"),
    ("garbage", "protocol violation: a reply of type"),
    ("oversize", "protocol violation: tx_len"),
])
def test_a_failing_firmware_is_contained_and_reported(faulty, tmp_path, mode, reason):
    run_dir = tmp_path / "run"
    s = run(scenario(tmp_path, faulty, mode), run_dir)
    lock = s["lockstep"]
    assert lock["failed"] is True and reason in lock["failure"], lock["failure"]
    assert lock["failed_at_s"] == pytest.approx(BAD_STEP * 0.005, abs=0.006)
    assert lock["steps"] == BAD_STEP - 1  # the steps before the bad one ran, the rest were never asked for
    assert lock["calls_after_failure"] > 0
    assert s["passed"] is False and s["sim_duration_s"] == pytest.approx(DURATION_S)  # the run went on to its end
    # the run directory is whole: summary (typed), events with the failure, captures
    assert load_summary(run_dir).scenario == f"faulty_{mode}"
    events = [json.loads(x) for x in (run_dir / "events.jsonl").read_text().splitlines()]
    failed = [e for e in events if e["event"] == "lockstep_failed"]
    assert len(failed) == 1 and reason in failed[0]["reason"]
    assert (run_dir / "capture.psnscap").stat().st_size > 0


def test_a_hanging_firmware_is_stopped_after_the_step_timeout(faulty, tmp_path):
    t0 = time.monotonic()
    s = run(scenario(tmp_path, faulty, "hang", timeout_s=1.0), tmp_path / "run")
    wall = time.monotonic() - t0
    lock = s["lockstep"]
    assert lock["failed"] is True and lock["failure"] == "step: hung: no reply within 1 s (wall clock)"
    assert 1.0 <= wall < 30.0  # it waited for the timeout, then killed it and went on
    assert lock["exit"] == -9  # killed (SIGKILL)
    assert (tmp_path / "run" / "summary.json").exists()


def test_a_flooding_firmware_is_counted_at_the_uart(faulty, tmp_path):
    s = run(scenario(tmp_path, faulty, "flood"), tmp_path / "run")
    lock = s["lockstep"]
    assert lock["failed"] is False  # within the contract: not a failure, a flood
    steps_flooding = lock["steps"] - (BAD_STEP - 1)
    assert lock["tx_bytes"]["uart0"] == 65536 * steps_flooding > 0
    # the UART's TX ring (4096 bytes) takes no 64 KiB chunk: every one dropped whole and counted
    st = s["link_stats"]["uart0"]
    assert st["dropped_out"] == lock["tx_bytes"]["uart0"] and st["dropped_chunks_out"] == steps_flooding


def test_garbage_on_uart0_is_counted_by_the_decoders(faulty, tmp_path):
    s = run(scenario(tmp_path, faulty, "uart_garbage"), tmp_path / "run")
    lock = s["lockstep"]
    assert lock["failed"] is False and lock["tx_bytes"]["uart0"] == 200 * (lock["steps"] - (BAD_STEP - 1))
    assert lock["garbage_bytes"] + lock["length_errors"] + lock["crc_errors"] > 0
    assert lock["host_frames"] == {} and s["nav_frames"] == 0
    assert s["links"]["host"]["garbage_bytes"] > 0


def test_run_exits_1_naming_the_failure(faulty, tmp_path, capsys, monkeypatch):
    monkeypatch.setenv("COLUMNS", "300")
    path = scenario(tmp_path, faulty, "crash")
    rc = cli_main(["run", str(path), "--out", str(tmp_path / "run"), "--quiet", "--no-report", "--allow-firmware"])
    assert rc == 1
    out = capsys.readouterr().out
    assert "lockstep firmware failed at t = 0.49" in out and "SIGSEGV" in out
    assert (tmp_path / "run" / "summary.json").exists()
