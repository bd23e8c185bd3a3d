"""This tree against another checkout of the project, on the reference scenario: speed and byte identity.

Speed: alternating pairs of fresh subprocesses, one per tree (``PYTHONPATH`` and the working directory set to the
tree, the same interpreter, the same ``nice``), each timing the same cut of the reference scenario with
``time.process_time`` (CPU time: the machine is shared, and CPU time is what other processes disturb least). Prints
each pair, the per-pair speed-up (other's CPU / this tree's CPU) and its median.

Identity (``--cmp``): the same cut run once in each tree; every file of the two run directories compared byte for
byte, ``summary.json`` and ``clock.json`` without their wall-clock fields, the capture record by record with its
header but for the scenario directory (the tree's path) (:func:`compare_run_dirs`).

The other tree is any checkout, e.g. ``git worktree add --detach /tmp/base 800dabd`` or
``git archive 800dabd | tar -x -C /tmp/base``. Usage (docs/performance.md section 5.6)::

    .venv/bin/python -m studies.scripts.compare_trees OTHER_TREE [duration_s] [pairs] [--nice N] [--cmp]
"""

from __future__ import annotations

import itertools
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path
from statistics import median
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
#: summary fields that differ between any two runs (wall clock, where the run was written)
WALL_FIELDS = ("wall_s", "realtime_factor", "run_dir")
#: per JSON file of a run directory, its fields that differ between any two runs (the wall-clock origin)
JSON_WALL_FIELDS = {"summary.json": WALL_FIELDS, "clock.json": ("t0_monotonic_s",)}
#: capture header fields that name the tree the run was made in (the scenario's directory)
CAPTURE_TREE_FIELDS = ("scenario_base_dir",)


#: what each child runs, with the tree's own packages (the other tree need not have this module): one run of the
#: reference cut, timed in CPU time; prints one JSON line
_CHILD = """
import json, sys, tempfile, time
from pathlib import Path
sys.path.insert(0, ".")
from emulator.assembly.session import run_scenario
from emulator.scenario import load_scenario
duration_s, out = float(sys.argv[1]), (sys.argv[2] if len(sys.argv) > 2 else None)
scn = load_scenario(Path("scenarios/bench_vehicle_loop_10min.yaml")).model_copy(update={"duration_s": duration_s})
with tempfile.TemporaryDirectory() as d:
    c0 = time.process_time()
    s = run_scenario(scn, Path(out) if out else Path(d) / "run", mode="fast")
    cpu = time.process_time() - c0
ticks = round(s["sim_duration_s"] * scn.sensors.imu.rate_hz)
print(json.dumps({"cpu_s": cpu, "sim_s": s["sim_duration_s"], "passed": bool(s.get("passed")),
                  "us_per_tick": cpu / ticks * 1e6}))
"""


def run_child(tree: Path, child: str, args: list[str], nice: int = 0) -> dict[str, Any]:
    """Run the program ``child`` (Python source) with ``args`` in a fresh process on ``tree``'s packages (its
    working directory and ``PYTHONPATH``), under ``nice``; its last output line, parsed as JSON."""
    env = dict(os.environ, PYTHONPATH=str(tree))
    cmd = ["nice", "-n", str(nice), sys.executable, "-c", child, *args]
    res = subprocess.run(cmd, cwd=tree, env=env, capture_output=True, text=True, check=True)
    return dict(json.loads(res.stdout.strip().splitlines()[-1]))


def _spawn(tree: Path, duration_s: float, nice: int, out: Path | None = None) -> dict[str, Any]:
    return run_child(tree, _CHILD, [str(duration_s)] + ([str(out)] if out else []), nice)


def compare_run_dirs(a: Path, b: Path) -> list[str]:
    """The files that differ between two run directories: byte for byte, except ``summary.json`` and
    ``clock.json`` without their wall-clock fields (:data:`JSON_WALL_FIELDS`) and ``capture.psnscap``, whose
    records must be equal and whose header may differ only in the tree's path (:data:`CAPTURE_TREE_FIELDS`)."""
    diff = []
    for name in sorted({p.name for p in a.iterdir()} | {p.name for p in b.iterdir()}):
        fa, fb = a / name, b / name
        if not (fa.is_file() and fb.is_file()):
            diff.append(name)
        elif fa.read_bytes() == fb.read_bytes():
            continue
        elif name in JSON_WALL_FIELDS:
            skip = JSON_WALL_FIELDS[name]
            sa, sb = (json.loads(f.read_text()) for f in (fa, fb))
            if _without(sa, skip) != _without(sb, skip):
                diff.append(name)
        elif name.endswith(".psnscap"):
            if not _same_capture(fa, fb):
                diff.append(name)
        else:
            diff.append(name)
    return diff


def _same_capture(fa: Path, fb: Path) -> bool:
    """Two captures with the same records, in order, and the same header but for :data:`CAPTURE_TREE_FIELDS`."""
    from emulator.recording.capture import iter_capture

    ha, ra = iter_capture(fa)
    hb, rb = iter_capture(fb)
    if _without(ha, CAPTURE_TREE_FIELDS) != _without(hb, CAPTURE_TREE_FIELDS):
        return False
    return all(x == y for x, y in itertools.zip_longest(ra, rb, fillvalue=None))


def _without(d: dict[str, Any], keys: tuple[str, ...]) -> dict[str, Any]:
    """``d`` without ``keys``."""
    return {k: v for k, v in d.items() if k not in keys}


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    nice = int(argv[argv.index("--nice") + 1]) if "--nice" in argv else 10
    args = [a for i, a in enumerate(argv) if not a.startswith("--") and not (i and argv[i - 1] == "--nice")]
    if not args:
        print(__doc__)
        return 2
    other = Path(args[0]).resolve()
    duration_s = float(args[1]) if len(args) > 1 else 120.0
    pairs = int(args[2]) if len(args) > 2 else 5
    if "--cmp" in argv:
        with tempfile.TemporaryDirectory() as d:
            for tree, name in ((other, "other"), (ROOT, "this")):
                _spawn(tree, duration_s, nice, Path(d) / name)
            diff = compare_run_dirs(Path(d) / "other", Path(d) / "this")
            files = sorted(p.name for p in (Path(d) / "this").iterdir())
        print(f"{duration_s:g} s of the reference: {len(files) - len(diff)} of {len(files)} files identical"
              + (f"; DIFFERENT: {', '.join(diff)}" if diff else f" ({', '.join(files)})"))
        return 1 if diff else 0
    ratios = []
    for i in range(pairs):
        order = ((other, "other"), (ROOT, "this")) if i % 2 == 0 else ((ROOT, "this"), (other, "other"))
        r = {name: _spawn(tree, duration_s, nice) for tree, name in order}
        ratios.append(r["other"]["cpu_s"] / r["this"]["cpu_s"])
        print(f"pair {i + 1}: other {r['other']['cpu_s']:.2f} s CPU ({r['other']['us_per_tick']:.1f} us/tick, passed "
              f"{r['other']['passed']}), this {r['this']['cpu_s']:.2f} s CPU ({r['this']['us_per_tick']:.1f} us/tick, "
              f"passed {r['this']['passed']}): speed-up {ratios[-1]:.3f}; load {os.getloadavg()[0]:.2f}", flush=True)
    print(f"speed-up of this tree (other CPU / this CPU), {duration_s:g} s simulated: median {median(ratios):.3f} "
          f"({', '.join(f'{x:.3f}' for x in ratios)})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
