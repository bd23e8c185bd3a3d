"""CPU cost of the per-tick items of performance.md 5.7 and 5.11, this tree against another checkout (before/after).

Each item is timed in fresh subprocesses, one per tree, alternating (``PYTHONPATH`` and the working directory set
to the tree, the same interpreter, ``nice``), in CPU time (``time.process_time``), best of 7 repetitions:

* ``stim_build``: one STIM210 datagram (format ``m``) as the gyro model sends it, us;
* ``imu_build``: one FPGA IMU frame as the FPGA sends it, us;
* ``psns_points``: one 225-point POLARIZATION_OBS frame through the firmware's decoder to the ``(n, 4)`` points
  array, us per frame (5 frames per second: / 40 for us per 200 Hz tick);
* ``loop_timer``: the event loop per timer (2000 timers scheduled, every other one cancelled, the rest run), us;
* ``firmware_tick``: the firmware alone, ``receive`` + ``service`` per tick over 30 s of the firmware tests' static
  stream with POLARIZATION_OBS frames (``benchmarks.bench_firmware``), best of 5 runs, us;

and those of 5.11:

* ``nav_rows``: one navigating NAV_SOLUTION against its truth state (``NavVsTruth._compare``: errors, nav.csv and
  truth.csv rows), full-precision values, the sigmas repeating in 4 frames of 5 as on the reference, us per frame
  (100 Hz: / 2 for us per 200 Hz tick);
* ``imu_parse``, ``stim_parse``, ``nav_parse``: one FPGA IMU frame, STIM210 datagram (format ``m``), NAV_SOLUTION
  through its format's ``parse`` (the decoders' frame objects), us;
* ``tap_chunk``: one chunk into the recorder's tap listener (a STIM210 datagram and an IMU frame alternately, inbound:
  captured and buffered for counting, the counting decoders included), us.

Each item uses the API its tree has (the other tree may predate 5.7: objects built and encoded, points decoded to
objects). Usage::

    .venv/bin/python -m studies.scripts.item_costs OTHER_TREE [runs]
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path
from statistics import median

ROOT = Path(__file__).resolve().parents[2]
ITEMS = ("stim_build", "imu_build", "psns_points", "loop_timer", "firmware_tick", "nav_rows", "imu_parse",
         "stim_parse", "nav_parse", "tap_chunk")

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
import math, tempfile, types
from pathlib import Path
from emulator.recording.nav_error import NavVsTruth
from protocols.host import HostFormat, NavMode, NavSolution, encode_nav_solution
f32 = lambda x: float(np.float32(x))
frames, states = [], []
for k in range(500):
    r = rng.normal(0.0, 1.0, 12).tolist()  # Python floats, as a decoded frame holds
    sig = tuple(f32(0.1 + 0.01 * (k // 5) + 0.001 * i) for i in range(9))
    frames.append((0.01 * k + 0.0012, NavSolution(
        seq=k, time_s=0.01 * k, lat_deg=39.98 + 1e-5 * r[0], lon_deg=116.34 + 1e-5 * r[1], height_m=f32(50 + r[2]),
        vel_enu_mps=(f32(r[3]), f32(r[4]), f32(r[5])), roll_deg=f32(r[6]), pitch_deg=f32(r[7]),
        heading_deg=f32(180 + 10 * r[8]), sigma=sig, mode=int(NavMode.NAVIGATING), gnss_status=1, psns_status=0,
        cpu_load_pct=2.94, deadline_misses=0)))
    h = math.radians(180 + 10 * r[9])
    states.append(types.SimpleNamespace(
        pos=np.array([math.radians(39.98 + 1e-5 * r[10]), math.radians(116.34 + 1e-5 * r[11]), 50.0 + r[2]]),
        v_enu=np.array([r[3] + 1e-3, r[4], r[5]]), roll=1e-3 * r[6], pitch=1e-3 * r[7], heading=h,
        c_bn=np.array([[math.cos(h), math.sin(h), 0.0], [-math.sin(h), math.cos(h), 0.0], [0.0, 0.0, 1.0]])))
def f5():
    c = NavVsTruth(None)._compare
    for (ta, n), st in zip(frames, states):
        c(ta, n, st)
out["nav_rows"] = best(f5, 10) / len(frames)
from protocols.stim import Stim210Format
from protocols.imu_frame import ImuFrameFormat
raw_stim = fmt.build_values((12345, -2345, 345), 0, 20, 516, (6400, 6400, 6400)) if hasattr(fmt, "build_values") \
    else fmt.build(stim.StimDatagram(ident=0xA5, gyro=(12345, -2345, 345), status=0, counter=20, latency_us=516,
                                     temperature=(6400, 6400, 6400)))
raw_imu = f2()
raw_nav = encode_nav_solution(frames[7][1])
imf, hf = ImuFrameFormat(), HostFormat()
out["imu_parse"] = best(lambda: imf.parse(raw_imu), 20000)
out["stim_parse"] = best(lambda: fmt.parse(raw_stim), 20000)
out["nav_parse"] = best(lambda: hf.parse(raw_nav), 20000)
from emulator.links.line import LineConfig
from emulator.recording.recorder import Recorder
from emulator.world.trajectory import StaticTrajectory
class _Link:
    def __init__(self):
        self.line = LineConfig(460800)
        self.listeners = []
        self.last_rx_pitch = self.line.byte_time
with tempfile.TemporaryDirectory() as d:
    rec = Recorder(Path(d) / "run", StaticTrajectory(39.98, 116.34, 50.0))
    gl, ul = _Link(), _Link()
    rec.tap("gyro", gl, {"in": [Stim210Format("m")]})
    rec.tap("uart1", ul, {"in": [ImuFrameFormat()]})
    rec.start({})
    lg, lu = gl.listeners[0], ul.listeners[0]
    def f6():
        for k in range(1000):
            lg.on_link_bytes(gl, "in", k * 0.005, raw_stim)
            lu.on_link_bytes(ul, "in", k * 0.005, raw_imu)
    out["tap_chunk"] = best(f6, 5) / 2000
    rec.close()
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
