"""Python expectation hooks of the scenario library (``expectations: - python: {file: checks.py, ...}``).

A hook is ``function(summary, run_dir, **args)``: ``summary`` is the run's summary (a copy, without
the expectation results), ``run_dir`` the run directory (``nav.csv``, ``events.jsonl``,
``timeline.csv``...). It returns ``bool``, ``(passed, value[, message])`` or
``{"passed", "value", "message"}``. See docs/scenarios.md.
"""

from __future__ import annotations

import csv
import itertools
from pathlib import Path
from typing import Any


def _nav_times(run_dir: Path, column: str = "arrival_s") -> list[float]:
    with open(run_dir / "nav.csv", newline="", encoding="utf-8") as f:
        return [float(r[column]) for r in csv.DictReader(f)]


def nav_gap(summary: dict[str, Any], run_dir: Path, after_s: float, until_s: float, min_gap_s: float
            ) -> tuple[bool, float, str]:
    """The host saw no navigation frame for at least ``min_gap_s`` inside ``[after_s, until_s]``
    (by the frames' arrival times at the host)."""
    times = [t for t in _nav_times(run_dir) if after_s - 1.0 <= t <= until_s + 1.0]
    best, at = 0.0, after_s
    for a, b in itertools.pairwise(times):
        lo, hi = max(a, after_s), min(b, until_s)
        if hi - lo > best:
            best, at = hi - lo, lo
    return best >= min_gap_s, round(best, 4), f"largest gap {best:.3f} s from t = {at:.3f} s"


def nav_rate(summary: dict[str, Any], run_dir: Path, rate_hz: float, tolerance: float = 0.01
             ) -> tuple[bool, float, str]:
    """The host received navigation frames at ``rate_hz`` on average (within ``tolerance``, relative)."""
    times = _nav_times(run_dir)
    if len(times) < 2:
        return False, 0.0, "fewer than two navigation frames"
    rate = (len(times) - 1) / (times[-1] - times[0])
    return abs(rate / rate_hz - 1.0) <= tolerance, round(rate, 3), f"{len(times)} frames"
