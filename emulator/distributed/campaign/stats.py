"""Statistics over the members of a campaign: per numeric column n, mean, sigma (ddof 1), min, p5, p50, p95,
max over the completed members; expectation pass rates; failed members counted, never dropped."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = ["NAV_METRICS", "PERCENTILES", "PSNS_METRICS", "PSNS_STATS", "campaign_statistics", "describe",
           "psns_columns"]

#: the navigation error metrics of a run's summary that a campaign collects (``<metric>_rms``, ``<metric>_max``)
NAV_METRICS = ("attitude_deg", "heading_deg", "position_m", "velocity_mps")
#: the solved solar vector against truth that a campaign collects from a run's ``psns`` summary section (runs with a
#: polarization sensor only): ``<metric>_<stat>`` for each of the section's statistics, deg
PSNS_METRICS = ("solar_vector_error_deg", "azimuth_error_deg", "elevation_error_deg")
PSNS_STATS = ("median", "p95", "max")
#: percentiles in every column's statistics
PERCENTILES = (5, 50, 95)


def describe(values: Sequence[float | None]) -> dict[str, float | int | None]:
    """n, mean, sigma (ddof 1; 0 for one value), min, percentiles and max of the finite ``values``."""
    a = np.asarray([v for v in values if v is not None and math.isfinite(v)], dtype=float)
    if a.size == 0:
        return {"n": 0, "mean": None, "sigma": None, "min": None, **{f"p{p}": None for p in PERCENTILES},
                "max": None}
    pct = np.percentile(a, PERCENTILES)
    return {"n": int(a.size), "mean": float(a.mean()), "sigma": float(a.std(ddof=1)) if a.size > 1 else 0.0,
            "min": float(a.min()), **{f"p{p}": float(v) for p, v in zip(PERCENTILES, pct)}, "max": float(a.max())}


def psns_columns(rows: Sequence[dict[str, Any]]) -> list[str]:
    """The solar-vector columns (``<metric>_<stat>`` of :data:`PSNS_METRICS`) when any row has one, else none (a
    campaign without a polarization sensor gets no empty columns)."""
    cols = [f"{m}_{s}" for m in PSNS_METRICS for s in PSNS_STATS]
    return cols if any(r.get(c) is not None for r in rows for c in cols) else []


def campaign_statistics(rows: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Statistics over the completed members of a campaign (see module docstring)."""
    ok = [r for r in rows if r.get("ok")]
    cols = [f"{m}_{s}" for m in NAV_METRICS for s in ("rms", "max")]
    cols += psns_columns(ok)
    cols += ["deadline_misses", "cpu_load_pct_max", "nav_frames", "wall_s"]
    keys = sorted({k for r in rows for k in r.get("params", {})})
    stats = {c: describe([r.get(c) for r in ok]) for c in cols}
    for k in keys:
        vals = [r["params"][k] for r in rows if isinstance(r["params"].get(k), (int, float))
                and not isinstance(r["params"].get(k), bool)]
        if vals:
            stats[f"param:{k}"] = describe(vals)
    exp: dict[int, dict[str, Any]] = {}
    for r in ok:
        for e in r.get("expectations", []):
            d = exp.setdefault(e["index"], {"index": e["index"], "description": e["description"], "runs": 0,
                                            "passed": 0, "not_applied": 0})
            if e.get("applicable") is False:  # a campaign-level check in a member: not applied, never a pass
                d["not_applied"] += 1
                continue
            d["runs"] += 1
            d["passed"] += int(bool(e["passed"]))
    for d in exp.values():
        d["pass_rate"] = d["passed"] / d["runs"] if d["runs"] else None
        d["status"] = "not applied" if not d["runs"] else "pass" if d["passed"] == d["runs"] else "FAIL"
    n_pass = sum(1 for r in ok if r.get("passed"))
    return {
        "runs": len(rows),
        "completed": len(ok),
        "failed": len(rows) - len(ok),
        "passed": n_pass,
        "pass_rate": n_pass / len(ok) if ok else None,
        "pass_rate_all_runs": n_pass / len(rows) if rows else None,
        "metrics": stats,
        "expectations": [exp[i] for i in sorted(exp)],
    }
