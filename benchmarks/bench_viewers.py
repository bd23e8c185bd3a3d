"""The cost of the viewer outputs (issue 39) as a ratio to the run: raw sensor tables and run.mcap on quickstart.

The quickstart (120 s simulated; ``make bench-quick``: 30 s) runs in this process in fast mode; the CPU time
(``time.process_time``: user + system of this process) of the run, of :func:`~emulator.postrun.sensor_tables.
write_sensor_tables` and of :func:`~emulator.postrun.mcap_out.write_run_mcap` on its run directory are taken,
the median of ``PSNS_BENCH_REPEAT`` repeats each. The 10 % of the run that an output may cost to be on by default
(docs/decisions/emulator-runtime.md D-7.15) is the ratio's bound.
"""

from __future__ import annotations

import statistics
import tempfile
import time
from pathlib import Path

from benchmarks.common import ROOT, quick, setting


def run() -> list[dict]:
    from emulator.assembly.session import run_scenario
    from emulator.postrun.mcap_out import write_run_mcap
    from emulator.postrun.sensor_tables import write_sensor_tables
    from emulator.scenario import load_scenario

    duration = 30.0 if quick() else 120.0
    repeat = int(setting("PSNS_BENCH_REPEAT"))
    runs, tables, mcaps = [], [], []
    messages = 0
    with tempfile.TemporaryDirectory() as d:
        for i in range(repeat):
            scn = load_scenario(ROOT / "scenarios" / "quickstart.yaml")
            scn.duration_s = duration
            rd = Path(d) / f"run{i}"
            t0 = time.process_time()
            run_scenario(scn, rd)
            t1 = time.process_time()
            write_sensor_tables(rd)
            t2 = time.process_time()
            messages = sum(write_run_mcap(rd).messages.values())
            t3 = time.process_time()
            runs.append(t1 - t0)
            tables.append(t2 - t1)
            mcaps.append(t3 - t2)
    r, tb, mc = statistics.median(runs), statistics.median(tables), statistics.median(mcaps)
    note = f"quickstart {duration:g} s fast, CPU s, median of {repeat}; bound for on-by-default: ratio 0.10"
    return [
        {"name": "viewers: run (quickstart)", "value": r, "unit": "CPU s", "baseline": None, "ratio": None,
         "note": note},
        {"name": "viewers: raw sensor tables", "value": tb, "unit": "CPU s", "baseline": r, "ratio": tb / r,
         "note": "imu.csv, gnss.csv, psns_frames.csv from the capture; on by default"},
        {"name": "viewers: run.mcap", "value": mc, "unit": "CPU s", "baseline": r, "ratio": mc / r,
         "note": f"{messages} messages; psns-hil run --mcap (a switch: over the bound)"},
    ]
