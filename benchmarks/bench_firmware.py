"""Firmware model wall time per 200 Hz tick (total and by part), and the PSNS solve rate.

The stream is the firmware tests' synthetic static stream (IMU 200 Hz rate words, GNSS NMEA 1 Hz, PSNS
frames at 5 Hz, NAV_SOLUTION out at 100 Hz), fed through ``Firmware.receive`` / ``Firmware.service`` exactly
as the virtual DSP does. Rows:

* ``Firmware.service per tick (static, GNSS, PSNS <kind>)``: service() alone (the cyclic executive), best
  of 3 (the historical rows, docs/variants.md compares against them);
* ``Firmware per tick, base filter, nav <dtype> (receive + service)``: everything the firmware does per
  tick, decoding of every UART included; CPU time (``time.process_time``), median of ``REPEAT`` runs;
* ``... part: <part>``: the same run split by part (median of ``REPEAT`` instrumented runs): ``decode``
  (receive(): framing, CRC, parse of every UART), ``strapdown`` (``NavCore.mechanize``: bias compensation,
  coning/sculling, mechanization, INS history), ``kf_predict`` (``NavCore.predict``: the filter's time update,
  every 20th tick), ``updates`` (GNSS / PSNS measurement tasks, solve, feedback), ``output`` (NAV_SOLUTION build and
  encode, every 2nd tick), ``rest`` (the tick's own bookkeeping: time, PPS, counters, raw-to-SI, load
  window). ``cycle meter`` is the cost of the tick's CycleMeter calls replayed on a fresh meter
  (already contained in the parts above; shown for its own sake). The parts are wall time
  (``perf_counter`` around each call: a CPU-time clock costs 1.5 us per read here), so on a loaded machine
  their sum can exceed the CPU-time total. The parts are timed by wrapping the methods of
  :data:`PART_METHODS` at their classes (:func:`timed_methods`), so :func:`firmware_in_replay` times the same parts
  of the firmware inside a replay of the reference's capture (the reference's own input: ``benchmarks
  .bench_realtime_factor``'s rows ``reference's firmware ...``).

Wall times on a shared 2-core machine are noisy: compare medians, not single runs.
Run: ``.venv/bin/python -c "from benchmarks.bench_firmware import main; main()"``.
"""

from __future__ import annotations

import contextlib
import functools
import math
import statistics
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from firmware_model import Firmware, FirmwareConfig, psns  # noqa: E402
from firmware_model.c674x import CycleMeter  # noqa: E402
from firmware_model.psns_geometry import CameraGeometry  # noqa: E402
from firmware_model.tasks.navigation import NavCore  # noqa: E402
from firmware_model.tasks.output import OutputTask  # noqa: E402
from tests.firmware_model.sky import observe_sky  # noqa: E402
from tests.firmware_model.synth import SensorErrors, StaticTruth, StreamConfig, static_stream  # noqa: E402

ERR = SensorErrors(gyro_bias_dph=(5, -3, 4), gyro_arw_deg_rt_h=0.15, accel_bias_mg=(1, -1, 0.5),
                   accel_noise_ug_rt_hz=100, gnss_pos_sigma_m=3, gnss_vel_sigma_mps=0.03, psns_sigma_deg=0.03)
#: Runs per median.
REPEAT = 5
#: Simulated seconds per run (the first ~2 s are the coarse alignment).
SECONDS = 30.0
PARTS = ("decode", "strapdown", "kf_predict", "updates", "output", "rest")


def _events(psns_kind: str | None, seconds: float) -> list[tuple[float, int, bytes]]:
    return list(static_stream(StaticTruth(), ERR, StreamConfig(psns=psns_kind), seconds))


def _service_us_per_tick(psns_kind: str | None, seconds: float = 60.0) -> float:
    events = _events(psns_kind, seconds)
    best = math.inf
    for _ in range(3):
        fw = Firmware(FirmwareConfig(initial_heading_deg=30.5))
        n, ts = 0, 0.0
        for t, uart, data in events:
            fw.receive(uart, data, t)
            if uart == 1:
                t0 = time.perf_counter()
                n += len(fw.service())
                ts += time.perf_counter() - t0
        best = min(best, ts / n)
    return best * 1e6


def _total_us_per_tick(cfg: FirmwareConfig, events: list[tuple[float, int, bytes]]) -> float:
    """receive() of every chunk plus service() of every tick, per tick (us of CPU time: robust against the
    other processes on the shared cores, which stretch wall time but not this process's CPU time)."""
    fw = Firmware(cfg)
    receive, service = fw.receive, fw.service
    n = 0
    t0 = time.process_time()
    for t, uart, data in events:
        receive(uart, data, t)
        if uart == 1:
            n += len(service())
    return (time.process_time() - t0) / n * 1e6


#: the parts of :data:`PARTS` as the methods that do them, for a run this module does not drive itself (the replay
#: of the reference's capture): ``kf_predict`` is ``NavCore.predict`` (the filter's time update with its schedule)
PART_METHODS: dict[str, tuple[type, str]] = {
    "decode": (Firmware, "receive"), "strapdown": (NavCore, "mechanize"), "kf_predict": (NavCore, "predict"),
    "updates": (Firmware, "_measurement_tasks"), "output": (OutputTask, "nav_solution")}
#: what a run split by part times: the parts and ``service``, which holds all of them but ``decode`` (:func:`_parts_of`)
_PARTS_TIMED = {**PART_METHODS, "service": (Firmware, "service")}


@contextlib.contextmanager
def timed_methods(methods: dict[str, tuple[type, str]]) -> Iterator[dict[str, float]]:
    """Each ``(class, method)`` of ``methods`` (a method the class itself defines) timed at its class, for every
    instance, while the block runs: the dict it yields holds, under the same keys, the wall seconds (``perf_counter``)
    spent in the calls, nested calls included; the classes get their methods back on exit."""
    acc = dict.fromkeys(methods, 0.0)
    saved = [(cls, name, cls.__dict__[name]) for cls, name in methods.values()]
    pc = time.perf_counter
    try:
        for key, (cls, name) in methods.items():
            orig = cls.__dict__[name]

            def timed(*a: Any, _orig: Callable[..., Any] = orig, _key: str = key, **k: Any) -> Any:
                t0 = pc()
                try:
                    return _orig(*a, **k)
                finally:
                    acc[_key] += pc() - t0

            setattr(cls, name, timed)
        yield acc
    finally:
        for cls, name, orig in saved:
            setattr(cls, name, orig)


def _parts_us_per_tick(cfg: FirmwareConfig, events: list[tuple[float, int, bytes]]) -> dict[str, float]:
    """One instrumented run: us per tick of each part (see module docstring; :data:`PART_METHODS` timed)."""
    fw = Firmware(cfg)
    n = 0
    with timed_methods(_PARTS_TIMED) as acc:
        for t, uart, data in events:
            fw.receive(uart, data, t)
            if uart == 1:
                n += len(fw.service())
    return _parts_of(acc, n)


def _parts_of(acc: dict[str, float], ticks: int) -> dict[str, float]:
    """us per tick of each part of :data:`PARTS` from the seconds :func:`timed_methods` accumulated for
    :data:`PART_METHODS` and ``service``: ``rest`` is ``service`` less the parts inside it."""
    out = {p: acc[p] / ticks * 1e6 for p in PART_METHODS}
    out["rest"] = acc["service"] / ticks * 1e6 - sum(v for p, v in out.items() if p != "decode")
    return out


def _meter_us_per_tick(cfg: FirmwareConfig, events: list[tuple[float, int, bytes]]) -> tuple[float, float]:
    """Cost of the CycleMeter calls of one run, replayed on a fresh meter: (us per tick, calls per tick)."""
    fw = Firmware(cfg)
    m = fw.meter
    calls: list[tuple[str, tuple[Any, ...]]] = []
    for name in ("begin", "charge", "end"):
        orig = getattr(m, name)

        def rec(*a: Any, _n: str = name, _f: Callable[..., Any] = orig) -> Any:
            calls.append((_n, a))
            return _f(*a)

        setattr(m, name, rec)
    n = 0
    for t, uart, data in events:
        fw.receive(uart, data, t)
        if uart == 1:
            n += len(fw.service())
    fresh = CycleMeter(cfg.clock_hz, cfg.imu_rate_hz)
    seq = [(getattr(fresh, name), a) for name, a in calls]
    noop = [(lambda *a: None, a) for _, a in calls]
    best = math.inf
    for _ in range(3):
        t0 = time.perf_counter()
        for f, a in seq:
            f(*a)
        t1 = time.perf_counter()
        for f, a in noop:
            f(*a)
        best = min(best, (t1 - t0) - (time.perf_counter() - t1))
    return max(best, 0.0) / n * 1e6, len(calls) / n


def firmware_in_replay(capture: Path, out: Path, ticks: int) -> dict[str, float]:
    """The firmware's cost per tick on a recorded input: ``capture`` replayed in fast mode twice (into ``out``/a
    and ``out``/b, :func:`emulator.postrun.replay.run_replay`), ``ticks`` IMU ticks long. Returns us per tick of
    ``total`` (``Firmware.receive`` + ``Firmware.service``, the only two methods timed in the first replay) and of
    each part of :data:`PARTS` (the second replay, :data:`PART_METHODS` timed; ``rest`` is ``service`` less the
    parts inside it: the tick's own bookkeeping). Wall time (``perf_counter``), as the synthetic stream's parts."""
    from emulator.postrun.replay import run_replay

    with timed_methods({"receive": (Firmware, "receive"), "service": (Firmware, "service")}) as acc:
        run_replay(capture, out / "a", mode="fast")
    total = acc["receive"] + acc["service"]
    with timed_methods(_PARTS_TIMED) as acc:
        run_replay(capture, out / "b", mode="fast")
    return {"total": total / ticks * 1e6, **_parts_of(acc, ticks)}


def firmware_tick_rows(seconds: float = SECONDS, repeat: int = REPEAT) -> list[dict]:
    """Per-tick totals and parts for the base filter, nav state in float64 (default) and float32."""
    events = _events("solar_vector", seconds)
    rows = []
    for nav in ("float64", "float32"):
        cfg = functools.partial(FirmwareConfig, initial_heading_deg=30.5, nav_state_precision=nav)
        tot = statistics.median(_total_us_per_tick(cfg(), events) for _ in range(repeat))
        rows.append({"name": f"Firmware per tick, base filter, nav {nav} (receive + service)", "value": tot,
                     "unit": "us", "baseline": 20.0, "ratio": tot / 20.0,
                     "note": f"median of {repeat}; baseline: the 20 us share of a 5 ms tick at 100x real time"})
        runs = [_parts_us_per_tick(cfg(), events) for _ in range(repeat)]
        for p in PARTS:
            v = statistics.median(r[p] for r in runs)
            rows.append({"name": f"  nav {nav} part: {p}", "value": v, "unit": "us", "baseline": tot,
                         "ratio": v / tot, "note": "us per tick (median, instrumented); ratio: share of the total"})
        us, ncalls = _meter_us_per_tick(cfg(), events)
        rows.append({"name": f"  nav {nav} part: cycle meter (inside the parts)", "value": us, "unit": "us",
                     "baseline": tot, "ratio": us / tot, "note": f"{ncalls:.1f} begin/charge/end calls per tick"})
    return rows


def _solves_per_s(n_points_stride: int) -> tuple[float, int]:
    cam = CameraGeometry()
    s = np.array([-0.876416, -0.282797, 0.389770])
    obs = observe_sky(s / np.linalg.norm(s), cam, stride_px=n_points_stride)
    x, y = obs.x_px, obs.y_px
    aop = (obs.aop_deg * math.pi / 180).astype(np.float32)
    dop = obs.dop.astype(np.float32)
    reps = 200
    t0 = time.perf_counter()
    for _ in range(reps):
        psns.solve_solar_vector(psns.evectors_camera(x, y, aop, cam), dop)
    return reps / (time.perf_counter() - t0), len(x)


def run() -> list[dict]:
    rows = []
    for kind in ("solar_vector", "polarization_obs"):
        us = _service_us_per_tick(kind)
        rows.append({"name": f"Firmware.service per tick (static, GNSS, PSNS {kind})", "value": us, "unit": "us",
                     "baseline": 5000.0, "ratio": us / 5000.0, "note": "baseline: the 5 ms tick period"})
    rows.extend(firmware_tick_rows())
    for stride in (160, 16):
        rate, n = _solves_per_s(stride)
        rows.append({"name": f"PSNS solve, {n} points (E-vectors + K + eigen)", "value": rate, "unit": "solves/s",
                     "baseline": 5.0, "ratio": rate / 5.0, "note": "baseline: 5 Hz frame rate"})
    return rows


def main() -> None:
    """Print the per-tick rows only (the quick check while optimising)."""
    for r in firmware_tick_rows():
        print(f"{r['name']:<62}{r['value']:>9.2f} {r['unit']:<3} {r['note']}")


if __name__ == "__main__":
    main()
