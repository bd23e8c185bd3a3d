"""CPU cost of the per-tick items of performance.md 5.7, this tree against another checkout (before/after).

Each item is timed in fresh subprocesses, one per tree, alternating (``PYTHONPATH`` and the working directory set
to the tree, the same interpreter, ``nice``), in CPU time (``time.process_time``), best of 7 repetitions:

* ``stim_build``: one STIM210 datagram (format ``m``) as the gyro model sends it, us;
* ``imu_build``: one FPGA IMU frame as the FPGA sends it, us;
* ``psns_points``: one 225-point POLARIZATION_OBS frame through the firmware's decoder to the ``(n, 4)`` points
  array, us per frame (5 frames per second: / 40 for us per 200 Hz tick);
* ``loop_timer``: the event loop per timer (2000 timers scheduled, every other one cancelled, the rest run), us;
* ``firmware_tick``: the firmware alone, ``receive`` + ``service`` per tick over 30 s of the firmware tests' static
  stream with POLARIZATION_OBS frames (``benchmarks.bench_firmware``), best of 5 runs, us.

Each item uses the API its tree has (the other tree may predate 5.7: objects built and encoded, points decoded to
objects). Usage::

    .venv/bin/python -m benchmarks.item_costs OTHER_TREE [runs]
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from statistics import median

ROOT = Path(__file__).resolve().parents[1]
ITEMS = ("stim_build", "imu_build", "psns_points", "loop_timer", "firmware_tick")

_CHILD = r"""
import asyncio, json, sys, time
sys.path.insert(0, ".")
import numpy as np
pt = time.process_time

def best(fn, n, rep=7):
    b = 1e9
    for _ in range(rep):
        t0 = pt()
        for _ in range(n):
            fn()
        b = min(b, (pt() - t0) / n)
    return b * 1e6

out = {}
from protocols import stim
fmt = stim.Stim210Format("m")
if hasattr(fmt, "build_values"):
    f1 = lambda: fmt.build_values((12345, -2345, 345), 0, 20, 516, (6400, 6400, 6400))
else:
    f1 = lambda: fmt.build(stim.StimDatagram(ident=0xA5, gyro=(12345, -2345, 345), status=0, counter=20,
                                             latency_us=516, temperature=(6400, 6400, 6400)))
out["stim_build"] = best(f1, 20000)
from protocols import imu_frame as im
if hasattr(im, "build_imu_frame"):
    f2 = lambda: im.build_imu_frame(7, 5000, 0, 1, (1, -1, 3), 0, 10, 516, (100, -200, 300), 0x10)
else:
    ff = im.ImuFrameFormat()
    f2 = lambda: ff.build(im.ImuFrame(seq=7, t_trigger_us=5000, t_pps_us=0, pps_count=1, gyro=(1, -1, 3),
                                      gyro_status=0, gyro_counter=10, gyro_latency_us=516, accel=(100, -200, 300),
                                      fpga_status=0x10))
out["imu_build"] = best(f2, 20000)
from protocols import psns as P
from firmware_model import psns as FP
rng = np.random.default_rng(1)
n = 225
cols = [rng.integers(1, 2000, n).tolist() for _ in range(2)] + [rng.integers(-9000, 9000, n).tolist(),
        rng.integers(0, 65535, n).tolist(), rng.integers(0, 4000, n).tolist()]
raw = P.encode_polarization_obs_columns(P.PsnsHeader(1, 2, 3, 1, n), *cols)
if hasattr(P, "PolarizationObsPacked"):
    pf = P.PsnsFormat(packed_points=True)
    f3 = lambda: FP.obs_points_array(pf.parse(raw).point_bytes)
else:
    pf = P.PsnsFormat()
    def f3():
        f = pf.parse(raw)
        return np.array([(p.x_px, p.y_px, p.aop_cdeg, p.dop) for p in f.points], dtype=np.float64)
out["psns_points"] = best(f3, 300)
from emulator.clock import EmulatorLoop
def f4():
    loop = EmulatorLoop("fast")
    sink = []
    hs = [loop.call_at(i * 0.001, sink.append, i) for i in range(2000)]
    for h in hs[::2]:
        h.cancel()
    loop.run_until_complete(asyncio.sleep(2.5))
    loop.close()
out["loop_timer"] = best(f4, 3) / 2000
from benchmarks.bench_firmware import _events, _total_us_per_tick
from firmware_model.config import FirmwareConfig
ev = _events("polarization_obs", 30.0)
out["firmware_tick"] = min(_total_us_per_tick(FirmwareConfig(initial_heading_deg=30.5), ev) for _ in range(5))
print(json.dumps(out))
"""


def _spawn(tree: Path) -> dict[str, float]:
    env = dict(os.environ, PYTHONPATH=str(tree))
    res = subprocess.run(["nice", "-n", "10", sys.executable, "-c", _CHILD], cwd=tree, env=env, capture_output=True,
                         text=True, check=True)
    return dict(json.loads(res.stdout.strip().splitlines()[-1]))


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if not argv:
        print(__doc__)
        return 2
    other = Path(argv[0]).resolve()
    runs = int(argv[1]) if len(argv) > 1 else 3
    got: dict[str, list[dict[str, float]]] = {"other": [], "this": []}
    for i in range(runs):
        order = ((other, "other"), (ROOT, "this")) if i % 2 == 0 else ((ROOT, "this"), (other, "other"))
        for tree, name in order:
            got[name].append(_spawn(tree))
        print(f"run {i + 1}: load {os.getloadavg()[0]:.2f}", flush=True)
    for k in ITEMS:
        o, t = (median(r[k] for r in got[name]) for name in ("other", "this"))
        print(f"{k:<14} other {o:8.2f} us  this {t:8.2f} us  (median of {runs})")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
