"""Wall time of one fast-mode run of the performance reference (or its world alone), for A/B runs across trees.

Usage (one run per call, so trees can alternate; ``PYTHONPATH`` picks the tree)::

    PYTHONPATH=$TREE .venv/bin/python -m studies.scripts.reference_wall full 600 LABEL
    PYTHONPATH=$TREE .venv/bin/python -m studies.scripts.reference_wall world 600 LABEL

``full``: ``scenarios/bench_vehicle_loop_10min.yaml`` as it is; ``world``: with the DSP taken out
(``benchmarks.bench_realtime_factor.WORLD_ONLY``). The second argument is the simulated duration (s). Prints one
line: label, kind, duration, wall time (s) of ``run_scenario`` and the real-time factor -- the call
``benchmarks/bench_realtime_factor.py`` times, without its repetitions.
"""

from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path


def wall_s(kind: str, duration_s: float) -> float:
    """Wall time (s) of one fast-mode run of the reference, ``kind`` ``full`` or ``world``, ``duration_s`` simulated."""
    from benchmarks.bench_realtime_factor import WORLD_ONLY
    from benchmarks.common import REFERENCE
    from emulator.assembly.session import run_scenario
    from emulator.scenario import load_scenario

    if kind not in ("full", "world"):
        raise SystemExit(f"kind must be full or world, got {kind!r}")
    scn = load_scenario(REFERENCE, WORLD_ONLY if kind == "world" else ())
    scn = scn.model_copy(update={"duration_s": duration_s})
    with tempfile.TemporaryDirectory() as d:
        t0 = time.perf_counter()
        run_scenario(scn, Path(d) / "run", mode="fast")
        return time.perf_counter() - t0


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 3:
        raise SystemExit("usage: python -m studies.scripts.reference_wall full|world DURATION_S LABEL")
    kind, duration, label = args[0], float(args[1]), args[2]
    w = wall_s(kind, duration)
    print(f"{label} {kind} {duration:.0f}s wall {w:.2f} s rtf {duration / w:.1f}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
