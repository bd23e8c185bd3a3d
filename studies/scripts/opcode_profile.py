"""Bytecodes per 200 Hz tick, per Python function, over a window of a scenario run (no timing).

``sys.settrace`` with opcode events (``frame.f_trace_opcodes``) from ``t0`` to ``t1`` of scenario time (callbacks the
loop schedules at those instants turn the tracer on and off; frames already running when it starts are not
counted); each executed bytecode is counted for the function it belongs to. The simulation's own work gives the
same counts on any machine and load; the recorder drains its nav rows and counted taps on a wall-clock schedule (its
flush), so their share of a short window varies between runs (use windows of several seconds), and module-level
caches warm up on a process's first run. Unlike :mod:`studies.scripts.sample_profile` the counts are not biased towards
small functions entered often (a ``SIGPROF`` sample is taken at the next function entry or backward jump). What
they do not see: the work of C code (numpy, ``repr`` of floats, CRCs in C, allocation), for which
``valgrind --tool=cachegrind`` and ``cg_diff`` of two run lengths give the C functions (docs/performance.md 5.12).

Usage (docs/performance.md section 5.12)::

    .venv/bin/python -m studies.scripts.opcode_profile [scenario.yaml] [t0_s] [t1_s] [--top N]   # default 30 31
"""

from __future__ import annotations

import collections
import sys
import tempfile
from pathlib import Path
from types import FrameType
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
REFERENCE = ROOT / "scenarios" / "bench_vehicle_loop_10min.yaml"


def count(scenario: Path, t0: float, t1: float) -> collections.Counter[tuple[str, int, str]]:
    """Bytecodes executed per function ``(file, first line, name)`` between scenario times ``t0`` and ``t1`` (s)."""
    from emulator.assembly.session import run_scenario
    from emulator.scenario import load_scenario

    ops: collections.Counter[tuple[str, int, str]] = collections.Counter()

    def local(frame: FrameType, event: str, _arg: Any) -> Any:
        if event == "opcode":
            co = frame.f_code
            ops[(co.co_filename, co.co_firstlineno, co.co_name)] += 1
        return local

    def tracer(frame: FrameType, event: str, _arg: Any) -> Any:
        if event == "call":
            frame.f_trace_opcodes = True
            frame.f_trace_lines = False
            return local
        return None

    def started(emu: Any) -> None:
        emu.loop.call_at(t0, sys.settrace, tracer)
        emu.loop.call_at(t1, sys.settrace, None)

    scn = load_scenario(scenario).model_copy(update={"duration_s": t1 + 1.0})
    with tempfile.TemporaryDirectory() as d:
        run_scenario(scn, Path(d) / "run", mode="fast", on_started=started)
    return ops


def _short(fn: str) -> str:
    for root in (str(ROOT) + "/", "site-packages/", "python3.11/"):
        if root in fn:
            return fn.split(root, 1)[1]
    return fn


def main(argv: list[str] | None = None) -> int:
    args = list(sys.argv[1:] if argv is None else argv)
    if "-h" in args or "--help" in args:
        print(__doc__)
        return 0
    top = 60
    if "--top" in args:
        i = args.index("--top")
        top = int(args[i + 1])
        del args[i:i + 2]
    scenario = Path(args[0]) if args else REFERENCE
    t0 = float(args[1]) if len(args) > 1 else 30.0
    t1 = float(args[2]) if len(args) > 2 else t0 + 1.0
    ops = count(scenario, t0, t1)
    ticks = (t1 - t0) * 200.0
    total = sum(ops.values())
    print(f"{scenario.stem}: {t0:g}-{t1:g} s, {total / ticks:.0f} bytecodes per 200 Hz tick")
    for (fn, line, name), n in ops.most_common(top):
        print(f"{n / ticks:8.1f} {100.0 * n / total:5.1f} %  {_short(fn)}:{line} {name}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
