"""Run every benchmark, print one table and write ``benchmarks/results.json``.

Each benchmark module exposes ``run() -> list[dict]`` rows with at least ``name``, ``value``,
``unit`` and, where there is one, ``baseline`` (the peer or the limit measured in the same run)
and ``ratio``. ``PSNS_BENCH_QUICK=1`` (``make bench-quick``) shortens the long items; see
:mod:`benchmarks.common` and ``docs/performance.md``. ``PSNS_BENCH_ONLY=name,name`` runs only the
named modules (``bench_scaling``, ...) and merges their rows into the existing ``results.json``.
"""

from __future__ import annotations

import importlib
import json
import platform
import sys
import time
from pathlib import Path

MODULES = ["benchmarks.bench_realtime_factor", "benchmarks.bench_camera", "benchmarks.bench_decoders",
           "benchmarks.bench_pty_jitter", "benchmarks.bench_firmware", "benchmarks.bench_campaign",
           "benchmarks.bench_scaling", "benchmarks.bench_lockstep", "benchmarks.bench_viewers"]


def markdown(path: Path) -> str:
    """The table of an existing ``results.json`` as Markdown (``python -m benchmarks --markdown``)."""
    rows = json.loads(path.read_text())["results"]
    out = ["| benchmark | value | unit | baseline | ratio | note |", "|---|---|---|---|---|---|"]
    for r in rows:
        b = "" if r.get("baseline") is None else f"{r['baseline']:.4g}"
        q = "" if r.get("ratio") is None else f"{r['ratio']:.2f}"
        note = str(r.get("note", "")).replace("|", "/")
        out.append(f"| {r['name'].strip()} | {r['value']:.4g} | {r['unit']} | {b} | {q} | {note} |")
    return "\n".join(out)


def main() -> int:
    import os
    import traceback

    if "--markdown" in sys.argv[1:]:
        print(markdown(Path(__file__).with_name("results.json")))
        return 0

    only = [m.strip() for m in os.environ.get("PSNS_BENCH_ONLY", "").split(",") if m.strip()]
    modules = [m for m in MODULES if not only or m.rsplit(".", 1)[-1] in only or m in only]
    path = Path(__file__).with_name("results.json")
    rows: list[dict] = []
    for name in modules:
        t0 = time.perf_counter()
        try:
            mod = importlib.import_module(name)
            got = mod.run()
        except Exception as exc:
            traceback.print_exc()
            got = [{"name": name.rsplit(".", 1)[-1], "value": float("nan"), "unit": "", "baseline": None,
                    "ratio": None, "note": f"failed: {exc!r}"}]
        for r in got:
            r["module"] = name
        rows.extend(got)
        print(f"# {name}: {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    if only and path.exists():  # merge: keep the other modules' rows of the last full run
        old = json.loads(path.read_text()).get("results", [])
        done = set(modules)
        merged: list[dict] = []
        for name in MODULES:
            merged += [r for r in (rows if name in done else old) if r.get("module") == name]
        rows = merged + [r for r in old if r.get("module") not in MODULES]
    from rich.console import Console
    from rich.table import Table

    t = Table(title="psns-hil benchmarks")
    for col in ("benchmark", "value", "unit", "baseline", "ratio", "note"):
        t.add_column(col)
    for r in rows:
        t.add_row(r["name"], f"{r['value']:.4g}", r["unit"],
                  "" if r.get("baseline") is None else f"{r['baseline']:.4g}",
                  "" if r.get("ratio") is None else f"{r['ratio']:.2f}", r.get("note", ""))
    Console(width=max(200, Console().width)).print(t)
    out = {"python": sys.version.split()[0], "machine": platform.machine(), "time": time.time(), "results": rows}
    path.write_text(json.dumps(out, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
