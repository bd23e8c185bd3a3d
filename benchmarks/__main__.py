"""Run every benchmark, print one table and write ``benchmarks/results.json``.

Each benchmark module exposes ``run() -> list[dict]`` rows with at least ``name``, ``value``,
``unit`` and, where there is one, ``baseline`` (the peer or the limit measured in the same run)
and ``ratio``.
"""

from __future__ import annotations

import importlib
import json
import platform
import sys
import time
from pathlib import Path

MODULES = ["benchmarks.bench_realtime_factor", "benchmarks.bench_camera", "benchmarks.bench_decoders",
           "benchmarks.bench_pty_jitter", "benchmarks.bench_firmware", "benchmarks.bench_campaign"]


def main() -> int:
    rows: list[dict] = []
    for name in MODULES:
        mod = importlib.import_module(name)
        t0 = time.perf_counter()
        rows.extend(mod.run())
        print(f"# {name}: {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    from rich.console import Console
    from rich.table import Table

    t = Table(title="psns-hil benchmarks")
    for col in ("benchmark", "value", "unit", "baseline", "ratio", "note"):
        t.add_column(col)
    for r in rows:
        t.add_row(r["name"], f"{r['value']:.4g}", r["unit"],
                  "" if r.get("baseline") is None else f"{r['baseline']:.4g}",
                  "" if r.get("ratio") is None else f"{r['ratio']:.2f}", r.get("note", ""))
    Console().print(t)
    out = {"python": sys.version.split()[0], "machine": platform.machine(), "time": time.time(), "results": rows}
    Path(__file__).with_name("results.json").write_text(json.dumps(out, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
