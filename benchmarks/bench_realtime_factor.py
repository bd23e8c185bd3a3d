"""Fast-mode real-time factor of the quickstart scenario (simulated s per wall s)."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

from emulator.runner import run_scenario
from emulator.scenario import load_scenario

ROOT = Path(__file__).resolve().parents[1]


def run() -> list[dict]:
    scn = load_scenario(ROOT / "scenarios" / "quickstart.yaml")
    with tempfile.TemporaryDirectory() as d:
        t0 = time.perf_counter()
        s = run_scenario(scn, Path(d) / "run")
        wall = time.perf_counter() - t0
    return [{"name": "quickstart fast-mode real-time factor", "value": s["sim_duration_s"] / wall,
             "unit": "sim s / wall s", "baseline": 100.0, "ratio": s["sim_duration_s"] / wall / 100.0,
             "note": "target >= 100x (issue 10)"}]
