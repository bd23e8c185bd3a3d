"""Shared settings of the benchmarks: durations and repeats from the environment.

``PSNS_BENCH_QUICK=1`` (``make bench-quick``) shortens every long item so that the whole table
takes a few minutes; each item's own variable, when set, wins over both defaults:

========================== ============================== ========= ========================
variable                   what                           default   quick
========================== ============================== ========= ========================
PSNS_BENCH_REF_S           reference run, simulated s      600       120
PSNS_BENCH_PROFILE_S       profiled part of it, simulated  600       60
PSNS_BENCH_REPEAT          timed repeats (median)          3         1
PSNS_BENCH_RT_S            realtime pty run, wall s        600       30
PSNS_BENCH_SCALING_S       scaling durations, simulated s  60,600,3600  30,60,180
PSNS_BENCH_FIDELITY_S      fidelity on/off runs, sim. s    300       60
PSNS_BENCH_LOCKSTEP_S      lockstep C firmware runs, sim.  120       30
PSNS_BENCH_CAMPAIGN_SEEDS  members per campaign (1-K)     4         2
========================== ============================== ========= ========================
"""

from __future__ import annotations

import os
import statistics
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "scenarios" / "bench_vehicle_loop_10min.yaml"

_DEFAULTS = {"PSNS_BENCH_REF_S": ("600", "120"), "PSNS_BENCH_PROFILE_S": ("600", "60"),
             "PSNS_BENCH_REPEAT": ("3", "1"), "PSNS_BENCH_RT_S": ("600", "30"),
             "PSNS_BENCH_SCALING_S": ("60,600,3600", "30,60,180"), "PSNS_BENCH_FIDELITY_S": ("300", "60"),
             "PSNS_BENCH_LOCKSTEP_S": ("120", "30"), "PSNS_BENCH_CAMPAIGN_SEEDS": ("4", "2")}


def quick() -> bool:
    return os.environ.get("PSNS_BENCH_QUICK", "") not in ("", "0")


def setting(name: str) -> str:
    full, short = _DEFAULTS[name]
    return os.environ.get(name) or (short if quick() else full)


def number(name: str) -> float:
    return float(setting(name))


def numbers(name: str) -> list[float]:
    return [float(x) for x in setting(name).split(",") if x.strip()]


def median(xs: list[float]) -> float:
    return statistics.median(xs)


def load_avg() -> str:
    """The 1-minute load average (other work on the machine skews the timings)."""
    try:
        return f"{os.getloadavg()[0]:.2f}"
    except OSError:  # pragma: no cover
        return "?"
