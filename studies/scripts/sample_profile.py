"""A sampling profile of a scenario run: where the CPU time goes, per function, without cProfile's per-call cost.

``SIGPROF`` every ``interval`` s of the process's CPU time (``setitimer(ITIMER_PROF)``); each sample is charged to
the Python function running (``own``: C functions, numpy included, count for the Python function that called them)
and, once per sample, to every function on the stack (``inclusive``). Shares are scaled to the run's CPU time and
given in microseconds per 200 Hz tick. cProfile (:mod:`benchmarks.profile_breakdown`) charges its own overhead to
every call, which inflates code of many small calls (the event loop, the links, the frame objects); samples do
not, at the price of their statistics (~1 000 samples for 120 s of the reference: a row of n samples is good to
about 1/sqrt(n)). ``callers`` lists who called the generated ``__init__`` of the frame dataclasses (``<string>``),
the CSV rows and the enum operators, the per-object costs that hide behind a generic name.

Usage (docs/performance.md section 5.6)::

    .venv/bin/python -m studies.scripts.sample_profile [scenario.yaml] [duration_s] [--top N]
"""

from __future__ import annotations

import collections
import signal
import sys
import tempfile
import time
from pathlib import Path
from types import FrameType

ROOT = Path(__file__).resolve().parents[2]
REFERENCE = ROOT / "scenarios" / "bench_vehicle_loop_10min.yaml"
#: functions whose callers are listed (generic names behind which per-object costs hide)
WATCH = ("__init__", "csv_row_fast", "__or__", "__and__", "__call__")


def _key(f: FrameType) -> str:
    fn = f.f_code.co_filename
    for root in (str(ROOT) + "/", "site-packages/", "python3.11/"):
        if root in fn:
            fn = fn.split(root, 1)[1]
    return f"{fn}:{f.f_code.co_name}"


def sample(scenario: Path, duration_s: float,
           interval_s: float = 0.0005) -> tuple[float, int, dict[str, collections.Counter[str]]]:
    """Run ``scenario`` for ``duration_s`` (fast mode) under the sampler: (CPU s, samples, counters)."""
    from emulator.assembly.session import run_scenario
    from emulator.scenario import load_scenario

    own: collections.Counter[str] = collections.Counter()
    incl: collections.Counter[str] = collections.Counter()
    callers: collections.Counter[str] = collections.Counter()
    n = 0

    def on_sample(_sig: int, frame: FrameType | None) -> None:
        nonlocal n
        if frame is None:
            return
        n += 1
        leaf = _key(frame)
        own[leaf] += 1
        if frame.f_code.co_name in WATCH and frame.f_back is not None:
            callers[f"{leaf} <- {_key(frame.f_back)}"] += 1
        seen = set()
        f: FrameType | None = frame
        while f is not None:
            k = _key(f)
            if k not in seen:
                incl[k] += 1
                seen.add(k)
            f = f.f_back

    scn = load_scenario(scenario).model_copy(update={"duration_s": duration_s})
    with tempfile.TemporaryDirectory() as d:
        old = signal.signal(signal.SIGPROF, on_sample)
        signal.setitimer(signal.ITIMER_PROF, interval_s, interval_s)
        try:
            c0 = time.process_time()
            run_scenario(scn, Path(d) / "run", mode="fast")
            cpu = time.process_time() - c0
        finally:
            signal.setitimer(signal.ITIMER_PROF, 0.0, 0.0)
            signal.signal(signal.SIGPROF, old)
    return cpu, n, {"own": own, "inclusive": incl, "callers": callers}


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    top = int(argv[argv.index("--top") + 1]) if "--top" in argv else 40
    args = [a for i, a in enumerate(argv) if not a.startswith("--") and not (i and argv[i - 1] == "--top")]
    scenario = Path(args[0]) if args else REFERENCE
    duration_s = float(args[1]) if len(args) > 1 else 120.0
    cpu, n, counters = sample(scenario, duration_s)
    ticks = duration_s * 200.0
    scale = cpu / max(n, 1) / ticks * 1e6
    print(f"{scenario.stem}: {duration_s:g} s simulated, {cpu:.2f} s CPU, {cpu / ticks * 1e6:.1f} us per 200 Hz tick, "
          f"{n} samples")
    for name, c in counters.items():
        print(f"== {name} (us/tick)")
        for k, v in c.most_common(top):
            print(f"{v * scale:8.2f}  {k}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
