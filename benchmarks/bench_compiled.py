"""The opt-in compiled path (``make compiled``) against pure Python, on the reference scenario.

Alternating pairs of fresh subprocesses run the same cut of the reference scenario: one with the compiled
modules (whatever ``tools/build_compiled.py`` built), one with them imported from their ``.py`` sources
(``tools/build_compiled.py --pure``). Each child times its run with ``time.process_time`` (CPU time: the machine
is shared) and, with ``--profile``, adds the per-component breakdown of :mod:`benchmarks.profile_breakdown`
(scaled to its own unprofiled CPU time). The parent prints each run, the medians and the CPU-time ratio.

Usage (after ``make compiled``; docs/performance.md section 5.5)::

    .venv/bin/python -m benchmarks.bench_compiled [duration_s] [pairs] [--profile]
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from statistics import median
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "scenarios" / "bench_vehicle_loop_10min.yaml"


def _child(duration_s: float, profile: bool) -> dict[str, Any]:
    """One run in this process: CPU s, simulated s, expectations, which files the hot modules came from."""
    from benchmarks.profile_breakdown import breakdown
    from emulator.assembly.runner import run_scenario
    from emulator.scenario import load_scenario
    from tools.build_compiled import modules

    scn = load_scenario(REFERENCE)
    scn = scn.model_copy(update={"duration_s": duration_s})
    with tempfile.TemporaryDirectory() as d:
        c0 = time.process_time()
        s = run_scenario(scn, Path(d) / "run", mode="fast")
        cpu = time.process_time() - c0
    ticks = round(s["sim_duration_s"] * scn.sensors.imu.rate_hz)
    out: dict[str, Any] = {"cpu_s": cpu, "sim_s": s["sim_duration_s"], "passed": bool(s.get("passed")),
                           "us_per_tick": cpu / ticks * 1e6,
                           "files": [Path(sys.modules[m].__file__ or "").name for m in modules()]}
    if profile:
        rows, _ = breakdown(scn, cpu, ticks)
        out["breakdown"] = {r["component"]: r["us_per_tick"] for r in rows}
    return out


def _spawn(pure: bool, duration_s: float, profile: bool) -> dict[str, Any]:
    head = [sys.executable, str(ROOT / "tools" / "build_compiled.py"), "--pure"] if pure else [sys.executable]
    cmd = [*head, "-m", "benchmarks.bench_compiled", "--child", str(duration_s)] + (["--profile"] if profile else [])
    res = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, check=True)
    return dict(json.loads(res.stdout.strip().splitlines()[-1]))


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    profile = "--profile" in argv
    args = [a for a in argv if not a.startswith("--")]
    if "--child" in argv:
        print(json.dumps(_child(float(args[0]), profile)))
        return 0
    duration_s = float(args[0]) if args else 60.0
    pairs = int(args[1]) if len(args) > 1 else 3
    runs: dict[str, list[dict[str, Any]]] = {"pure": [], "compiled": []}
    for i in range(pairs):
        for kind in ("pure", "compiled") if i % 2 == 0 else ("compiled", "pure"):
            r = _spawn(kind == "pure", duration_s, profile)
            runs[kind].append(r)
            print(f"pair {i + 1} {kind:8s} CPU {r['cpu_s']:6.2f} s  RTF(CPU) {r['sim_s'] / r['cpu_s']:5.1f}  "
                  f"{r['us_per_tick']:6.1f} us/tick  passed {r['passed']}  {' '.join(r['files'])}", flush=True)
    med = {k: median(r["cpu_s"] for r in v) for k, v in runs.items()}
    ratios = [p["cpu_s"] / c["cpu_s"] for p, c in zip(runs["pure"], runs["compiled"])]
    print(f"median CPU s: pure {med['pure']:.2f}, compiled {med['compiled']:.2f}; RTF(CPU) pure "
          f"{duration_s / med['pure']:.1f}, compiled {duration_s / med['compiled']:.1f}; speed-up per pair "
          f"{', '.join(f'{x:.3f}' for x in ratios)} (median {median(ratios):.3f})")
    if profile:
        comps = sorted(runs["pure"][0]["breakdown"], key=lambda c: -runs["pure"][0]["breakdown"][c])
        print(f"{'component':58s} {'pure':>7s} {'compiled':>9s}  us/tick (median of {pairs})")
        for c in comps:
            p = median(r["breakdown"].get(c, 0.0) for r in runs["pure"])
            q = median(r["breakdown"].get(c, 0.0) for r in runs["compiled"])
            print(f"  {c:56s} {p:7.1f} {q:9.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
