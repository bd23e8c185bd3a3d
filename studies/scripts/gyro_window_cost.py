"""CPU cost of the STIM210 gyro's datagrams, this tree against another checkout (issue 43 item 1, D-10.E21).

Each item is timed in fresh subprocesses, one per tree, alternating (``PYTHONPATH`` and the working directory set
to the tree, the same interpreter, ``nice``), in CPU time (``time.process_time``), best of 7 repetitions:

* ``trigger``: the gyro device per trigger (:meth:`Stim210Gyro.trigger`: truth increments, error model, words,
  STATUS, datagram, handed to the link), 2 000 triggers on the 200 Hz grid of the reference scenario
  (``scenarios/bench_vehicle_loop_10min.yaml``, its trajectory and gyro errors; ``t_prev = t - period`` as the
  FPGA gives it), after 200 triggers of warm-up,
  a fresh device per repetition, us per datagram;
* ``encode_1``: one datagram (format ``m``) through ``Stim210Format.build_values``, us;
* ``encode_200``, ``encode_2000``: a window of 200 / 2 000 datagrams through ``Stim210Format.build_window``, us
  per datagram (absent in a tree without it).

The ``trigger`` item also hashes the datagrams it sent, so the two trees' bytes are compared in the same run.
Usage::

    .venv/bin/python -m studies.scripts.gyro_window_cost OTHER_TREE [runs]
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from statistics import median

ROOT = Path(__file__).resolve().parents[2]
ITEMS = ("trigger", "encode_1", "encode_200", "encode_2000")

_CHILD = r"""
import hashlib, json, sys, time, types
sys.path.insert(0, ".")
import numpy as np
from pathlib import Path
pt = time.process_time

def best(fn, n, rep=7):
    b = 1e9
    for _ in range(rep):
        t0 = pt()
        for _ in range(n):
            fn()
        b = min(b, (pt() - t0) / n)
    return b * 1e6

from emulator.devices.imu import ImuTruthTap, Stim210Gyro
from emulator.devices.sensors import gyro_errors
from emulator.scenario import load_scenario
from emulator.world.build import build_trajectory
from protocols import stim

class Link:
    def __init__(self):
        self.loop = types.SimpleNamespace(time=lambda: 0.0)
        self.out = []
    def send_at(self, t, data, atomic=False):
        self.out.append(data)
        return len(data)

scn = load_scenario(Path("scenarios/bench_vehicle_loop_10min.yaml"))
traj = build_trajectory(scn)
period = 1.0 / 200.0
b = 1e9
digest = ""
for _ in range(7):
    link = Link()
    gyro = Stim210Gyro(link, ImuTruthTap(traj), np.random.default_rng(5), gyro_errors(scn))
    for k in range(1, 201):
        gyro.trigger(k * period, k * period - period)
    t0 = pt()
    for k in range(201, 2201):
        gyro.trigger(k * period, k * period - period)
    b = min(b, (pt() - t0) / 2000)
    digest = hashlib.sha256(b"".join(link.out)).hexdigest()[:16]
out = {"trigger": b * 1e6, "digest": digest}
fmt = stim.Stim210Format("m")
out["encode_1"] = best(lambda: fmt.build_values((12345, -2345, 345), 0, 20, 516, (6400, 6400, 6400)), 20000)
if hasattr(fmt, "build_window"):
    for n in (200, 2000):
        g = [(12345 + i, -2345, 345 - i) for i in range(n)]
        st, c, lat, tw = [0] * n, [(10 * i) & 0xFF for i in range(n)], [516] * n, [(6400, 6400, 6400)] * n
        out[f"encode_{n}"] = best(lambda: fmt.build_window(g, st, c, lat, tw), max(1, 20000 // n)) / n
print(json.dumps(out))
"""


def _spawn(tree: Path) -> dict[str, float | str]:
    env = dict(os.environ, PYTHONPATH=str(tree))
    res = subprocess.run(["nice", "-n", "10", sys.executable, "-c", _CHILD], cwd=tree, env=env, capture_output=True,
                         text=True, check=False)
    if res.returncode != 0:
        raise SystemExit(f"{tree}: {res.stderr.strip()[-2000:]}")
    result: dict[str, float | str] = json.loads(res.stdout.strip().splitlines()[-1])
    return result


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if not args:
        print(__doc__.strip().splitlines()[-1].strip(), file=sys.stderr)
        return 2
    other = Path(args[0]).resolve()
    runs = int(args[1]) if len(args) > 1 else 3
    res: dict[str, list[dict[str, float | str]]] = {"this": [], "other": []}
    for _ in range(runs):
        res["other"].append(_spawn(other))
        res["this"].append(_spawn(ROOT))
    print(f"{'item':<12} {'other us':>10} {'this us':>10} {'ratio':>7}")
    for item in ITEMS:
        o = [float(r[item]) for r in res["other"] if item in r]
        t = [float(r[item]) for r in res["this"] if item in r]
        mo, mt = (median(o) if o else float("nan")), (median(t) if t else float("nan"))
        print(f"{item:<12} {mo:>10.3f} {mt:>10.3f} {mt / mo if o and t else float('nan'):>7.3f}")
    digests = {str(r["digest"]) for side in res.values() for r in side}
    print("trigger bytes: " + ("identical in both trees" if len(digests) == 1 else f"DIFFER {sorted(digests)}"))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
