"""Campaign throughput of the envelope certification (issue 43 item 5): runs per minute on 1 and 2 workers.

The certification (docs/sensors.md "The envelope") is, for each of the three consistency scenarios
(:data:`SCENARIOS`), ``psns-hil campaign SCENARIO --seeds 1-31 --envelope published --consistency``. Here each
scenario's campaign runs as that command (a fresh ``python -m emulator`` process, its own TLS LocalCluster on
127.0.0.1) with ``--seeds 1-K`` (``PSNS_BENCH_CAMPAIGN_SEEDS``, default 4, quick 2), ``--no-plots --quiet``, once
with ``--workers 1`` and once with ``--workers 2``. Per scenario and worker count two figures:

* *runs/min*: the members' throughput, ``campaign.json``'s ``runs_per_min`` (members completed over the wall time
  from the first submitted member to the last result; what more workers divide);
* *fixed cost*: the command's whole wall time minus that member time (interpreter and imports, the cluster with its
  certificates, start-up and shutdown, the statistics, consistency and output files): paid once per campaign,
  whatever the number of members or machines.

Rows: each scenario at 1 and 2 workers (the 2-worker row against the 1-worker one: ideally 2 on 2 cores), and the
whole certification (3 x 31 members) predicted from them: the measured per-machine rate (2 workers) and the
**extrapolation, labelled as such**, to a Dask cluster of N machines of 2 workers each (:data:`CLUSTER_SIZES`),
``wall(N) = fixed + members / (N x rate_2)``, i.e. linear in machines, with the campaign's fixed cost kept and the
scheduler, network and a shared file system's costs left out: an upper bound on the throughput, not a measurement.
Such a cluster runs it with ``--scheduler tcp://HOST:8786`` (docs/distributed.md).
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from benchmarks.common import ROOT, load_avg, number

#: the three consistency scenarios of the envelope certification (docs/sensors.md "The envelope")
SCENARIOS = ("quickstart", "static_psns_camera_field", "vehicle_loop_gnss_outage")
#: members per scenario of the real certification (``--seeds 1-31``)
CERTIFICATION_SEEDS = 31
#: machines of the extrapolated Dask cluster (2 workers each, as measured here)
CLUSTER_SIZES = (1, 4, 16)


def seeds() -> int:
    """Members per measured campaign (``PSNS_BENCH_CAMPAIGN_SEEDS``, :mod:`benchmarks.common`)."""
    return max(1, int(number("PSNS_BENCH_CAMPAIGN_SEEDS")))


def command(scenario: str, n_seeds: int, workers: int, out: Path) -> list[str]:
    """The certification's command for one scenario, cut to ``n_seeds`` members."""
    return [sys.executable, "-m", "emulator", "campaign", str(ROOT / "scenarios" / f"{scenario}.yaml"),
            "--seeds", f"1-{n_seeds}", "--envelope", "published", "--consistency", "--workers", str(workers),
            "--no-plots", "--quiet", "--out", str(out)]


def measure(scenario: str, n_seeds: int, workers: int, out: Path) -> dict[str, Any]:
    """Run one campaign command; its whole wall time, the members' throughput and what it reported."""
    t0 = time.perf_counter()
    p = subprocess.run(command(scenario, n_seeds, workers, out), cwd=ROOT, capture_output=True, text=True,
                       timeout=3600)
    wall = time.perf_counter() - t0
    if p.returncode not in (0, 1):  # 1: a member or a consistency bound failed, which is a result; else an error
        raise RuntimeError(f"campaign {scenario} --workers {workers} exited {p.returncode}: {p.stderr[-2000:]}")
    doc = json.loads((out / "campaign.json").read_text())  # {"campaign": info, "statistics": ...} (outputs.py)
    members_s = float(doc["campaign"]["wall_s"])
    return {"scenario": scenario, "workers": workers, "runs": n_seeds, "wall_s": wall, "members_s": members_s,
            "runs_per_min": 60.0 * n_seeds / members_s, "fixed_s": wall - members_s, "exit": p.returncode,
            "failed": doc.get("statistics", {}).get("failed")}


def certification_wall(per: dict[str, dict[int, dict[str, Any]]], workers: int, machines: int = 1) -> float:
    """Predicted wall time (s) of the whole certification (every scenario with :data:`CERTIFICATION_SEEDS`
    members, one campaign after the other) from the measured rates: fixed cost + members / (machines x rate)."""
    total = 0.0
    for by_w in per.values():
        m = by_w[workers]
        total += m["fixed_s"] + CERTIFICATION_SEEDS * 60.0 / (machines * m["runs_per_min"])
    return total


def run() -> list[dict]:
    k = seeds()
    per: dict[str, dict[int, dict[str, Any]]] = {}
    with tempfile.TemporaryDirectory() as d:
        for s in SCENARIOS:
            per[s] = {w: measure(s, k, w, Path(d) / f"{s}-w{w}") for w in (1, 2)}
    rows: list[dict[str, Any]] = []
    for s, by_w in per.items():
        one, two = by_w[1], by_w[2]
        rows.append({"name": f"certification campaign {s}, 1 worker", "value": one["runs_per_min"],
                     "unit": "runs/min", "baseline": None, "ratio": None,
                     "note": f"--seeds 1-{k} --envelope published --consistency --workers 1: members "
                             f"{one['members_s']:.1f} s, fixed cost {one['fixed_s']:.1f} s (command "
                             f"{one['wall_s']:.1f} s), exit {one['exit']}, load avg {load_avg()}",
                     "measured": one})
        rows.append({"name": f"certification campaign {s}, 2 workers", "value": two["runs_per_min"],
                     "unit": "runs/min", "baseline": one["runs_per_min"],
                     "ratio": two["runs_per_min"] / one["runs_per_min"],
                     "note": f"baseline = 1 worker, ideal ratio 2 on 2 cores; members {two['members_s']:.1f} s, "
                             f"fixed cost {two['fixed_s']:.1f} s (command {two['wall_s']:.1f} s), exit {two['exit']}",
                     "measured": two})
    members = CERTIFICATION_SEEDS * len(SCENARIOS)
    w1, w2 = certification_wall(per, 1), certification_wall(per, 2)
    rows.append({"name": "certification (3 scenarios x 31 seeds), predicted, 2 workers", "value": 60.0 * members / w2,
                 "unit": "runs/min", "baseline": 60.0 * members / w1, "ratio": w1 / w2,
                 "note": f"from the rows above: {members} members, fixed costs included: {w2 / 60:.1f} min on 2 "
                         f"workers, {w1 / 60:.1f} min on 1 (baseline)", "wall_s": w2, "wall_1_s": w1})
    for n in CLUSTER_SIZES[1:]:
        wn = certification_wall(per, 2, n)
        rows.append({"name": f"certification, EXTRAPOLATED to a Dask cluster of {n} machines x 2 workers",
                     "value": 60.0 * members / wn, "unit": "runs/min", "baseline": 60.0 * members / w2,
                     "ratio": w2 / wn,
                     "note": f"extrapolation, not a measurement: fixed cost + members / ({n} x the 2-worker rate), "
                             f"{wn / 60:.1f} min; no scheduler, network or file-system cost (upper bound); "
                             "command: psns-hil campaign SCENARIO --seeds 1-31 --envelope published --consistency "
                             "--scheduler tcp://HOST:8786", "wall_s": wn, "machines": n})
    return rows


if __name__ == "__main__":
    for r in run():
        print({k: v for k, v in r.items() if k != "measured"})
