"""Signals from the very start of ``psns-hil run`` (docs/hostile-input.md "Interruption"): a SIGTERM or SIGINT that
arrives while the scenario is still loading ends the run cleanly, with its run directory and a summary saying
``"interrupted": true``. Before: the handlers came ~1.3 s into the process; a SIGTERM then killed it (rc -15,
no run directory)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[3]


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_a_signal_during_start_up_leaves_an_interrupted_run(tmp_path: Path, sig: int) -> None:
    out = tmp_path / "run"
    env = dict(os.environ, PYTHONPATH=str(ROOT))
    p = subprocess.Popen([sys.executable, "-m", "emulator", "run", str(ROOT / "scenarios" / "quickstart.yaml"),
                          "--fast", "--quiet", "--no-report", "--out", str(out)], cwd=ROOT, env=env,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(0.6)  # the CLI has parsed its arguments; the scenario and the run are still being built
    p.send_signal(sig)
    _o, err = p.communicate(timeout=120)
    assert p.returncode not in (-signal.SIGTERM, -signal.SIGINT), err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["interrupted"] is True
    assert summary.get("sim_duration_s", 0.0) < 5.0  # it did not run on to the end
