"""Per-component cost breakdown of a fast-mode run, from a cProfile of it.

Every profiled function has a *home* component decided by its source file (firmware, world/truth,
each device, links, FPGA, DSP host, recorder, asyncio loop, ...). Library code (numpy, the
standard library, builtins) has no home: its own time is charged to its callers, split in
proportion to the time each caller spent in it, recursively up to the nearest function that has a
home. So ``np.clip`` called by the IMU model counts as IMU time, ``bytes.join`` in the recorder as
recorder time.

cProfile adds a fixed cost per call, so call-heavy components look somewhat more expensive than
they are; the shares are therefore applied to the wall time of an *unprofiled* run of the same
scenario (:func:`breakdown` ``wall_s``) to give microseconds per 200 Hz tick.

Usage::

    .venv/bin/python -m benchmarks.profile_breakdown scenarios/bench_vehicle_loop_10min.yaml [duration_s] \
        [--set KEY=VALUE ...]
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

RECORDER = "recorder (captures, nav vs truth)"
#: (path fragment, component), first match wins; paths use "/" separators
HOMES: tuple[tuple[str, str], ...] = (
    ("/firmware_model/", "firmware (firmware_model)"),
    ("/protocols/", "protocols (frame build / stream decode)"),
    ("/emulator/world/", "world / truth (trajectory, sun, sky)"),
    ("/emulator/devices/imu/", "device: IMU (STIM210 + accelerometers)"),
    ("/emulator/devices/gnss.py", "device: GNSS receiver"),
    ("/emulator/devices/camera/", "device: camera (PSNS)"),
    ("/emulator/devices/compass.py", "device: compass"),
    ("/emulator/devices/magnetometer.py", "device: magnetometer"),
    ("/emulator/devices/fpga.py", "FPGA"),
    ("/emulator/dsp/host.py", "DSP host (UART RX, tick timing)"),
    ("/emulator/devices/", "devices: other (sensors, recorded)"),
    ("/emulator/links/", "links (line model, mem transport)"),
    # the recorder's per-run-time work: the listener, the capture file, nav vs truth, solar vectors vs truth, the
    # counting decoders and the CSV cells; the rest of recording/ (summary) and postrun/ (report, golden, replay)
    # are the runner's
    ("/emulator/recording/recorder.py", RECORDER),
    ("/emulator/recording/capture.py", RECORDER),
    ("/emulator/recording/nav_error.py", RECORDER),
    ("/emulator/recording/psns_error.py", RECORDER),
    ("/emulator/recording/counting.py", RECORDER),
    ("/emulator/recording/formatting.py", RECORDER),
    ("/emulator/clock.py", "asyncio loop (incl. emulator.clock)"),
    ("/asyncio/", "asyncio loop (incl. emulator.clock)"),
    ("/selectors.py", "asyncio loop (incl. emulator.clock)"),
    ("/emulator/faults/", "faults"),
    ("/emulator/", "runner (setup, 1 Hz samples, summary, expectations)"),
)
OTHER = "other (library code without an own caller)"


def home_of(func: tuple[str, int, str]) -> str | None:
    """The component a function belongs to, or None for library code."""
    path = func[0].replace("\\", "/")
    for frag, comp in HOMES:
        if frag in path:
            if frag in ("/asyncio/", "/selectors.py") and "site-packages" in path:
                continue
            return comp
    return None


def attribute(stats: pstats.Stats) -> dict[str, float]:
    """Seconds of own time per component (library time charged to callers, see module docstring)."""
    raw: dict[Any, Any] = stats.stats  # type: ignore[attr-defined]
    memo: dict[Any, dict[str, float]] = {}
    busy: set[Any] = set()

    def dist(func: Any) -> dict[str, float]:
        h = home_of(func)
        if h is not None:
            return {h: 1.0}
        if func in memo:
            return memo[func]
        if func in busy:  # recursion through library code
            return {OTHER: 1.0}
        busy.add(func)
        callers = raw[func][4]
        total = sum(v[3] for v in callers.values()) or sum(v[2] for v in callers.values())
        out: dict[str, float] = {}
        if not callers or total <= 0:
            out = {OTHER: 1.0}
        else:
            for c, v in callers.items():
                w = (v[3] if total else v[2]) / total
                if w <= 0 or c not in raw:
                    continue
                for comp, f in dist(c).items():
                    out[comp] = out.get(comp, 0.0) + w * f
            if not out:
                out = {OTHER: 1.0}
        busy.discard(func)
        memo[func] = out
        return out

    acc: dict[str, float] = {}
    for func, (_cc, _nc, tt, _ct, _callers) in raw.items():
        if tt <= 0:
            continue
        for comp, f in dist(func).items():
            acc[comp] = acc.get(comp, 0.0) + tt * f
    return acc


def profile_run(scn: Any, mode: str = "fast") -> tuple[dict[str, float], dict[str, Any], int]:
    """cProfile one run of ``scn``; returns (seconds per component, summary, event-loop callbacks run)."""
    from emulator.assembly.session import run_scenario

    prof = cProfile.Profile()
    with tempfile.TemporaryDirectory() as d:
        prof.enable()
        summary = run_scenario(scn, Path(d) / "run", mode=mode)
        prof.disable()
    st = pstats.Stats(prof)
    callbacks = 0  # Context.run calls: the event-loop callbacks (timers and call_soon) run, by the emulator's loop
    for func, v in st.stats.items():  # type: ignore[attr-defined]  # (D-10.E22) or by asyncio's Handle._run
        if func[2] == "<method 'run' of '_contextvars.Context' objects>":
            callbacks = v[1]
    return attribute(st), summary, callbacks


def breakdown(scn: Any, wall_s: float, ticks: int) -> tuple[list[dict[str, Any]], int]:
    """Rows ``{component, share, us_per_tick}`` (largest first) and the event-loop callbacks run.

    ``wall_s``: wall time of an unprofiled run of the same scenario; ``ticks``: 200 Hz ticks in it.
    """
    acc, _summary, iters = profile_run(scn)
    total = sum(acc.values())
    rows = [{"component": c, "share": s / total, "us_per_tick": s / total * wall_s / ticks * 1e6,
             "profiled_s": s} for c, s in sorted(acc.items(), key=lambda kv: -kv[1])]
    return rows, iters


def main(argv: list[str] | None = None) -> int:
    from emulator.assembly.session import run_scenario
    from emulator.scenario import load_scenario

    ap = argparse.ArgumentParser(prog="python -m benchmarks.profile_breakdown",
                                 description="Per-component cost of a fast-mode run: an unprofiled run for the wall "
                                             "time, then a cProfile of the same run, each function charged to its "
                                             "component (HOMES), in us per 200 Hz tick.")
    ap.add_argument("scenario", help="scenario file (e.g. scenarios/bench_vehicle_loop_10min.yaml)")
    ap.add_argument("duration_s", nargs="?", type=float, help="simulated seconds (default: the scenario's)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                    help="scenario override, as psns-hil run --set (repeatable); e.g. the world-only row's "
                         "dsp.external=... of benchmarks.bench_realtime_factor.WORLD_ONLY")
    args = ap.parse_args(sys.argv[1:] if argv is None else argv)
    scn = load_scenario(args.scenario, tuple(args.set))
    if args.duration_s is not None:
        scn = scn.model_copy(update={"duration_s": args.duration_s})
    with tempfile.TemporaryDirectory() as d:
        t0 = time.perf_counter()
        s = run_scenario(scn, Path(d) / "run", mode="fast")
        wall = time.perf_counter() - t0
    ticks = round(s["sim_duration_s"] * scn.sensors.imu.rate_hz)
    rows, iters = breakdown(scn, wall, ticks)
    print(f"{scn.name}: {s['sim_duration_s']:.0f} s simulated in {wall:.2f} s wall, real-time factor "
          f"{s['sim_duration_s'] / wall:.1f}, {wall / ticks * 1e6:.1f} us per tick, "
          f"{iters / ticks:.2f} event-loop callbacks per tick")
    for r in rows:
        print(f"  {r['component']:58s} {100 * r['share']:5.1f} %  {r['us_per_tick']:6.1f} us/tick")
    return 0


if __name__ == "__main__":
    sys.exit(main())
