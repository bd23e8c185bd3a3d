"""Scaling: wall time against simulated duration (1, 10, 60 min) and memory over a long run.

The reference scenario's sensors and links (``scenarios/bench_vehicle_loop_10min.yaml``) on a
motion of square laps long enough for each duration. Each duration runs in a fresh
``python`` subprocess (imports done before the clock starts), which reports its wall time and its
own peak resident set (``resource.getrusage(RUSAGE_SELF).ru_maxrss``), plus its RSS sampled every
simulated minute (``/proc/self/statm``), so a slow growth shows even under the start-up peak.

Targets (the performance work, scaling): wall time linear in simulated time (wall per simulated minute the same
at every duration) and flat memory (peak RSS at 60 min within 10 % of that at 10 min).

``PSNS_BENCH_SCALING_S``: the durations, comma-separated simulated seconds (default
``60,600,3600``; ``make bench-quick``: ``30,60,180``).
"""

from __future__ import annotations

import copy
import json
import math
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import yaml

from benchmarks.common import REFERENCE, ROOT, load_avg, numbers

LAP = [{"cruise": {"duration_s": 20}}, {"turn": {"rate_dps": 9, "angle_deg": 90}}]  # 30 s per side

_CHILD = r"""
import json, os, resource, sys, tempfile, time
from pathlib import Path
from emulator.assembly.session import run_scenario
from emulator.scenario import load_scenario
scn = load_scenario(sys.argv[1])
page = os.sysconf("SC_PAGE_SIZE")
rss = []
def progress(t, d):
    if int(t) % 60 == 0:
        with open("/proc/self/statm") as f:
            rss.append((t, int(f.read().split()[1]) * page / 1e6))
with tempfile.TemporaryDirectory() as d:
    t0 = time.perf_counter()
    s = run_scenario(scn, Path(d) / "run", mode="fast", progress=progress)
    wall = time.perf_counter() - t0
    cap = sum(p.stat().st_size for p in (Path(d) / "run").iterdir() if p.is_file())
ru = resource.getrusage(resource.RUSAGE_SELF)
print(json.dumps({"sim_s": s["sim_duration_s"], "wall_s": wall, "passed": s["passed"],
                  "maxrss_mb": ru.ru_maxrss / 1024.0, "rss_mb": rss, "run_dir_mb": cap / 1e6}))
"""


def scenario_for(duration_s: float) -> dict[str, Any]:
    """The reference scenario as a dict, its motion long enough for ``duration_s``."""
    data = yaml.safe_load(REFERENCE.read_text())
    sides = max(1, math.ceil((duration_s - 20.0) / 30.0))
    motion = [{"static": {"duration_s": 15}}, {"accelerate": {"duration_s": 5, "to_speed_mps": 10}}]
    for _ in range(sides):
        motion += copy.deepcopy(LAP)  # own copies: shared dicts would be dumped as YAML aliases (refused)
    data.update(name=f"bench_scaling_{int(duration_s)}s", duration_s=float(duration_s), motion=motion,
                tags=[], description=f"scaling: {duration_s:g} s of square loops")
    # the reference's expectations hold at any length >= 60 s; shorter runs keep only the link ones
    if duration_s < 60:
        data["expectations"] = [e for e in data["expectations"] if "link" in e or "dsp" in e]
    return data


def measure(duration_s: float) -> dict[str, Any]:
    with tempfile.TemporaryDirectory() as d:
        p = Path(d) / "scn.yaml"
        p.write_text(yaml.safe_dump(scenario_for(duration_s), sort_keys=False))
        out = subprocess.run([sys.executable, "-c", _CHILD, str(p)], cwd=ROOT, capture_output=True, text=True,
                             check=False)
    if out.returncode != 0:
        raise RuntimeError(f"scaling run of {duration_s} s failed:\n{out.stderr[-3000:]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def run() -> list[dict]:
    durs = sorted(numbers("PSNS_BENCH_SCALING_S"))
    res = {d: measure(d) for d in durs}
    mid = durs[len(durs) // 2]
    ref_rate = res[mid]["wall_s"] / res[mid]["sim_s"] * 60.0
    rows = []
    for d in durs:
        r = res[d]
        rate = r["wall_s"] / r["sim_s"] * 60.0
        rows.append({"name": f"scaling: wall per simulated minute, {d / 60:g} min run", "value": rate,
                     "unit": "wall s / sim min", "baseline": ref_rate, "ratio": rate / ref_rate,
                     "note": f"{r['wall_s']:.1f} s wall for {r['sim_s']:.0f} s; baseline: the {mid / 60:g} min run; "
                             f"linear = ratio 1; expectations passed: {r['passed']}; load avg {load_avg()}",
                     "result": r})
    lo, hi = durs[len(durs) // 2], durs[-1]
    a, b = res[lo]["maxrss_mb"], res[hi]["maxrss_mb"]
    samples = res[hi]["rss_mb"]
    growth = ""
    if len(samples) >= 2:
        growth = f"; RSS {samples[0][1]:.0f} MB at {samples[0][0]:.0f} s -> {samples[-1][1]:.0f} MB at " \
                 f"{samples[-1][0]:.0f} s"
    rows.append({"name": f"scaling: peak RSS, {hi / 60:g} min vs {lo / 60:g} min run", "value": b, "unit": "MB",
                 "baseline": a, "ratio": b / a,
                 "note": f"target ratio <= 1.10 (memory flat){growth}; run directory {res[hi]['run_dir_mb']:.0f} MB "
                         f"on disk"})
    return rows


if __name__ == "__main__":  # pragma: no cover
    for row in run():
        print({k: v for k, v in row.items() if k != "result"})
