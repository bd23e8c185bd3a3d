"""The opt-in compiled path (``make compiled``) against pure Python, on the reference scenario.

Alternating pairs of fresh subprocesses run the same cut of the reference scenario: one with the compiled
modules (whatever ``tools/build_compiled.py`` built), one with them imported from their ``.py`` sources
(``tools/build_compiled.py --pure``). Each child times its run with ``time.process_time`` (CPU time: the machine
is shared) and, with ``--profile``, adds the per-component breakdown of :mod:`benchmarks.profile_breakdown`
(scaled to its own unprofiled CPU time). The parent prints each run, the medians and the CPU-time ratio.

With ``--firmware`` the children time the firmware alone instead: :mod:`benchmarks.bench_firmware`'s
receive + service per tick (CPU time, median of its ``REPEAT`` runs of its synthetic static stream), navigation
state in float64 and in float32; ``duration_s`` is then the stream's length.

With ``--kernels`` the children time the compiled modules' per-tick kernels alone (``timeit``, CPU time, best of
5 x 20 000 calls; ``duration_s`` unused).

Usage (after ``make compiled``; docs/performance.md section 5.5)::

    .venv/bin/python -m benchmarks.bench_compiled [duration_s] [pairs] [--profile | --firmware | --kernels]
"""

from __future__ import annotations

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from statistics import median
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
REFERENCE = ROOT / "scenarios" / "bench_vehicle_loop_10min.yaml"


def _child(duration_s: float, profile: bool) -> dict[str, Any]:
    """One run in this process: CPU s, simulated s, expectations, which files the hot modules came from."""
    from benchmarks.profile_breakdown import breakdown
    from emulator.assembly.session import run_scenario
    from emulator.scenario import load_scenario
    from tools.build_compiled import modules

    scn = load_scenario(REFERENCE)
    scn = scn.model_copy(update={"duration_s": duration_s})
    with tempfile.TemporaryDirectory() as d:
        c0 = time.process_time()
        s = run_scenario(scn, Path(d) / "run", mode="fast")
        cpu = time.process_time() - c0
    ticks = round(s["sim_duration_s"] * scn.sensors.imu.rate_hz)
    out: dict[str, Any] = {"cpu_s": cpu, "sim_s": s["sim_duration_s"], "passed": bool(s.get("passed")),
                           "us_per_tick": cpu / ticks * 1e6,
                           "files": [Path(sys.modules[m].__file__ or "").name for m in modules()]}
    if profile:
        rows, _ = breakdown(scn, cpu, ticks)
        out["breakdown"] = {r["component"]: r["us_per_tick"] for r in rows}
    return out


def _child_firmware(seconds: float) -> dict[str, Any]:
    """Firmware receive + service per tick, us of CPU time (median), float64 and float32 navigation state."""
    from benchmarks.bench_firmware import ERR, REPEAT, _total_us_per_tick
    from firmware_model import FirmwareConfig
    from tests.firmware_model.synth import StaticTruth, StreamConfig, static_stream
    from tools.build_compiled import modules

    events = list(static_stream(StaticTruth(), ERR, StreamConfig(psns="polarization_obs"), seconds))
    out: dict[str, Any] = {"files": [Path(sys.modules[m].__file__ or "").name for m in modules()]}
    for prec in ("float64", "float32"):
        cfg = FirmwareConfig(initial_heading_deg=30.5, nav_state_precision=prec)
        out[prec] = median(_total_us_per_tick(cfg, events) for _ in range(REPEAT))
    return out


def _child_kernels() -> dict[str, Any]:
    """CPU us per call of the compiled modules' per-tick kernels, best of 5 x 20 000."""
    import timeit

    import numpy as np

    from firmware_model import c674x, strapdown
    from firmware_model.nav_state import NavState
    from protocols import crc
    from tools.build_compiled import modules

    def best(f: Any) -> float:
        return min(timeit.repeat(f, number=20000, repeat=5, timer=time.process_time)) / 20000 * 1e6

    out: dict[str, Any] = {"files": [Path(sys.modules[m].__file__ or "").name for m in modules()]}
    for dt in (np.float64, np.float32):
        s = NavState(np.array([1.0, 0, 0, 0], dt), np.array([1.0, 2.0, 0.1], dt), np.array([0.7, 2.0, 50.0]),
                     a_prev=np.zeros(3, dt), f_n=np.zeros(3, dt))
        phi, dv = np.array([1e-4, 2e-4, -1e-4], dt).tolist(), np.array([0.01, 0.02, 0.049], dt).tolist()
        out[f"coning_sculling_fast {dt.__name__}"] = best(
            lambda phi=phi, dv=dv, dt=dt: strapdown.coning_sculling_fast(phi, dv, dt))
        out[f"strapdown_step_fast {dt.__name__}"] = best(
            lambda s=s, phi=phi, dv=dv, dt=dt: strapdown.strapdown_step_fast(s, phi, dv, 0.005, dt))
    m = c674x.CycleMeter(300e6, 200.0)

    def tick() -> None:
        m.begin("imu_tick", 0.005)
        m.begin("imu", 0.005)
        m.charge("a", 10)
        m.charge("b", 20)
        m.end()
        m.end()

    out["CycleMeter 2 begin + 2 charge + 2 end"] = best(tick)
    b20, b48 = bytes(range(20)), bytes(48)
    out["crc8_stim 20 B"] = best(lambda: crc.crc8_stim(b20))
    out["crc32_mpeg2 48 B"] = best(lambda: crc.crc32_mpeg2(b48))
    return out


def _spawn(pure: bool, duration_s: float, flag: str) -> dict[str, Any]:
    head = [sys.executable, str(ROOT / "tools" / "build_compiled.py"), "--pure"] if pure else [sys.executable]
    cmd = [*head, "-m", "benchmarks.bench_compiled", "--child", str(duration_s)] + ([flag] if flag else [])
    res = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True, check=True)
    return dict(json.loads(res.stdout.strip().splitlines()[-1]))


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    profile, firmware, kernels = "--profile" in argv, "--firmware" in argv, "--kernels" in argv
    flag = "--profile" if profile else "--firmware" if firmware else ""
    args = [a for a in argv if not a.startswith("--")]
    if "--child" in argv:
        child = _child_kernels() if kernels else _child_firmware(float(args[0])) if firmware else \
            _child(float(args[0]), profile)
        print(json.dumps(child))
        return 0
    if kernels:
        for i in range(int(args[1]) if len(args) > 1 else 2):
            for kind in ("pure", "compiled") if i % 2 == 0 else ("compiled", "pure"):
                r = _spawn(kind == "pure", 0.0, "--kernels")
                print(f"{kind:8s} " + ", ".join(f"{k} {v:.2f} us" for k, v in r.items() if k != "files"), flush=True)
        return 0
    duration_s = float(args[0]) if args else 60.0
    pairs = int(args[1]) if len(args) > 1 else 3
    if firmware:
        return _firmware_pairs(duration_s, pairs)
    runs: dict[str, list[dict[str, Any]]] = {"pure": [], "compiled": []}
    for i in range(pairs):
        for kind in ("pure", "compiled") if i % 2 == 0 else ("compiled", "pure"):
            r = _spawn(kind == "pure", duration_s, flag)
            runs[kind].append(r)
            print(f"pair {i + 1} {kind:8s} CPU {r['cpu_s']:6.2f} s  RTF(CPU) {r['sim_s'] / r['cpu_s']:5.1f}  "
                  f"{r['us_per_tick']:6.1f} us/tick  passed {r['passed']}  {' '.join(r['files'])}", flush=True)
    med = {k: median(r["cpu_s"] for r in v) for k, v in runs.items()}
    ratios = [p["cpu_s"] / c["cpu_s"] for p, c in zip(runs["pure"], runs["compiled"])]
    print(f"median CPU s: pure {med['pure']:.2f}, compiled {med['compiled']:.2f}; RTF(CPU) pure "
          f"{duration_s / med['pure']:.1f}, compiled {duration_s / med['compiled']:.1f}; speed-up per pair "
          f"{', '.join(f'{x:.3f}' for x in ratios)} (median {median(ratios):.3f})")
    if profile:
        comps = sorted(runs["pure"][0]["breakdown"], key=lambda c: -runs["pure"][0]["breakdown"][c])
        print(f"{'component':58s} {'pure':>7s} {'compiled':>9s}  us/tick (median of {pairs})")
        for c in comps:
            p = median(r["breakdown"].get(c, 0.0) for r in runs["pure"])
            q = median(r["breakdown"].get(c, 0.0) for r in runs["compiled"])
            print(f"  {c:56s} {p:7.1f} {q:9.1f}")
    return 0


def _firmware_pairs(seconds: float, pairs: int) -> int:
    runs: dict[str, list[dict[str, Any]]] = {"pure": [], "compiled": []}
    for i in range(pairs):
        for kind in ("pure", "compiled") if i % 2 == 0 else ("compiled", "pure"):
            r = _spawn(kind == "pure", seconds, "--firmware")
            runs[kind].append(r)
            print(f"pair {i + 1} {kind:8s} firmware per tick: float64 {r['float64']:6.2f} us, float32 "
                  f"{r['float32']:6.2f} us  {' '.join(r['files'])}", flush=True)
    for prec in ("float64", "float32"):
        p = median(r[prec] for r in runs["pure"])
        c = median(r[prec] for r in runs["compiled"])
        print(f"{prec}: median pure {p:.2f} us, compiled {c:.2f} us per tick, saved {p - c:.2f} us ({p / c:.3f}x)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
