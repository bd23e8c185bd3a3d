"""Fast-mode real-time factor (simulated s per wall s) and where the time goes.

Reference (the performance work): ``scenarios/bench_vehicle_loop_10min.yaml``, 10 min of square loops
at 10 m/s with every sensor of the base box (STIM210 + accelerometers at 200 Hz, GNSS 1 Hz, camera
PSNS at 5 Hz in ``binned`` fidelity), byte-exact ``mem://`` links, base filter, one core (one
process, one thread). The run must pass its own expectations, so the number belongs to a run that
worked. Target >= 100x, i.e. 50 us of wall time per 5 ms IMU tick for everything.

The breakdown comes from a cProfile of the same scenario, aggregated by component
(:mod:`benchmarks.profile_breakdown`) and scaled to the unprofiled wall time: microseconds per
200 Hz tick per component. A second row gives the quickstart scenario (static, IMU + GNSS).

The cost of the world's fidelity (the realistic instrument models of issue 21) is measured in the same table:
the reference with that fidelity switched off by scenario overrides (:data:`FIDELITY_OFF`: no vibration, no
thermal warm-up, no low-pass group delay in the gyro, the camera's fixed pattern off and a fixed extinction
ratio instead of the spectral one; the sky is the reference's Rayleigh sky either way; docs/performance.md
section 2 says why this approximates the world before that work) against the reference as it is, alternating
off / on, each run's CPU time (``time.process_time``: the machine is shared, and CPU time is what the other
processes disturb least). The row is the ratio of the real-time factors, on / off (target >= 0.85).

What the world alone costs is measured in the same table: the reference with the DSP taken out by scenario
override (:data:`WORLD_ONLY`: ``dsp.external`` with UART0 bound to a pty that nobody opens and UART1-3 unbound, so
no firmware runs, the DSP side decodes nothing and the recorder has no nav row to compare with truth), the same
timed repeats as the reference. Everything else runs as in the reference: the trajectory, the sky and sun, the
IMU, GNSS and camera models, the virtual FPGA building every frame, the byte-exact baud-timed links and the
captures. Its real-time factor is the most the reference could reach with a firmware that cost nothing
(docs/performance.md section 5.14); the row gives it against the 100x target and, in its note, against the
reference measured above.

What the firmware alone allows (issue 43 item 4) is measured beside the reference: the capture of the last timed
reference run (``capture.psnscap``: every byte each DSP UART received, at its time) replayed in fast mode
(:func:`emulator.postrun.replay.run_replay`, ``psns-hil replay``): the DSP, its firmware, the FPGA-DSP UARTs'
receive side, the host port and the recorder, and nothing else (no trajectory, sky, sensors, FPGA or world-side
links). The replay's ``nav.csv`` must be the reference's, byte for byte, so the number belongs to the same work.
Its real-time factor is the most the reference could reach with a world that cost nothing; the row gives it beside
the reference's (its baseline), the same timed repeats.

Environment (see :mod:`benchmarks.common`): ``PSNS_BENCH_REF_S`` simulated seconds of the
reference run (default 600, the whole scenario), ``PSNS_BENCH_PROFILE_S`` of the profiled run,
``PSNS_BENCH_REPEAT`` timed repeats (the median is reported), ``PSNS_BENCH_FIDELITY_S`` simulated seconds of
each fidelity on / off run (``PSNS_BENCH_REPEAT`` pairs).
"""

from __future__ import annotations

import shutil
import tempfile
import time
from pathlib import Path
from typing import Any

from benchmarks.bench_firmware import PARTS, firmware_in_replay
from benchmarks.common import REFERENCE, ROOT, load_avg, median, number
from benchmarks.profile_breakdown import breakdown
from emulator.assembly.session import run_scenario
from emulator.scenario import load_scenario

TARGET_RTF = 100.0
#: the firmware's share of a 5 ms tick at 100x (us; docs/performance.md section 4)
FIRMWARE_TARGET_US = 20.0
#: the fidelity row's target: the world's instrument fidelity may cost at most 15 % of the real-time factor
TARGET_FIDELITY_RATIO = 0.85
#: scenario overrides that switch the world's instrument fidelity off (docs/performance.md section 2)
FIDELITY_OFF = (
    "sensors.imu.vibration.enabled=false",
    "sensors.imu.temperature.warmup_c=0",
    "sensors.imu.lp_filter_hz=0",
    "sensors.camera.extinction_ratio=300",
    "sensors.camera.defects.orientation_sigma_deg=0",
    "sensors.camera.defects.orientation_bias_deg=[0, 0, 0, 0]",
    "sensors.camera.defects.extinction_spread=0",
    "sensors.camera.defects.prnu=0",
    "sensors.camera.defects.crosstalk=0",
    "sensors.camera.defects.vignetting=false",
)

#: scenario override that takes the DSP out of the reference (the world-only row): no firmware, no nav output
WORLD_ONLY = ('dsp.external={"uarts": {"uart0": "pty://bench-no-dsp"}, "silence_s": 3600}',)


def _timed(scn: Any, repeat: int, keep: Path | None = None,
           cpus: list[float] | None = None) -> tuple[float, list[float], dict[str, Any]]:
    """Median wall time of ``repeat`` fast-mode runs; ``keep``: a directory that receives the last run's capture
    and nav.csv; ``cpus``: a list that receives each run's CPU time (s)."""
    walls = []
    s: dict[str, Any] = {}
    for _ in range(repeat):
        with tempfile.TemporaryDirectory() as d:
            t0, c0 = time.perf_counter(), time.process_time()
            s = run_scenario(scn, Path(d) / "run", mode="fast")
            walls.append(time.perf_counter() - t0)
            if cpus is not None:
                cpus.append(time.process_time() - c0)
            if keep is not None:
                for f in ("capture.psnscap", "nav.csv"):
                    shutil.copyfile(Path(d) / "run" / f, keep / f)
    return median(walls), walls, s


def firmware_alone(kept: Path, repeat: int,
                   cpus: list[float] | None = None) -> tuple[float, list[float], dict[str, Any], bool]:
    """The reference's capture in ``kept`` replayed in fast mode ``repeat`` times: median wall time, the walls,
    the last summary, and whether every replay's nav.csv was the reference's byte for byte; ``cpus`` receives each
    replay's CPU time (s)."""
    from emulator.postrun.replay import run_replay, same_file

    walls = []
    same = True
    s: dict[str, Any] = {}
    for _ in range(repeat):
        with tempfile.TemporaryDirectory() as d:
            t0, c0 = time.perf_counter(), time.process_time()
            s = run_replay(kept / "capture.psnscap", Path(d) / "replay", mode="fast")
            walls.append(time.perf_counter() - t0)
            if cpus is not None:
                cpus.append(time.process_time() - c0)
            same = same and same_file(kept / "nav.csv", Path(d) / "replay" / "nav.csv")
    return median(walls), walls, s, same


def _cut(scn: Any, duration_s: float) -> Any:
    return scn if duration_s >= scn.duration_s else scn.model_copy(update={"duration_s": duration_s})


def _cpu_run(scn: Any) -> tuple[float, dict[str, Any]]:
    """One fast-mode run: its CPU time (s) and summary."""
    with tempfile.TemporaryDirectory() as d:
        c0 = time.process_time()
        s = run_scenario(scn, Path(d) / "run", mode="fast")
        return time.process_time() - c0, s


def fidelity_ratio(duration_s: float, pairs: int) -> dict[str, Any]:
    """The reference with the world's fidelity off (:data:`FIDELITY_OFF`) and on, ``pairs`` alternating
    off / on runs of ``duration_s`` simulated seconds each: CPU-time real-time factors and their ratio on / off
    (median over the pairs; each pair ran back to back, so it shares the machine's load)."""
    on = _cut(load_scenario(REFERENCE), duration_s)
    off = _cut(load_scenario(REFERENCE, FIDELITY_OFF), duration_s)
    rows = []
    for _ in range(pairs):
        c_off, s_off = _cpu_run(off)
        c_on, s_on = _cpu_run(on)
        rows.append((s_off["sim_duration_s"] / c_off, s_on["sim_duration_s"] / c_on,
                     bool(s_off.get("passed")) and bool(s_on.get("passed"))))
    ratios = [r_on / r_off for r_off, r_on, _ok in rows]
    return {"ratio": median(ratios), "ratios": ratios, "rtf_off": [r[0] for r in rows],
            "rtf_on": [r[1] for r in rows], "passed": all(r[2] for r in rows), "sim_s": on.duration_s}


def run() -> list[dict]:
    repeat = max(1, int(number("PSNS_BENCH_REPEAT")))
    ref = load_scenario(REFERENCE)
    scn = _cut(ref, number("PSNS_BENCH_REF_S"))
    kept_dir = tempfile.TemporaryDirectory()
    kept = Path(kept_dir.name)
    ref_cpus: list[float] = []
    wall, walls, s = _timed(scn, repeat, keep=kept, cpus=ref_cpus)
    sim = s["sim_duration_s"]
    rtf = sim / wall
    ticks = round(sim * scn.sensors.imu.rate_hz)
    us_tick = wall / ticks * 1e6
    passed = s.get("passed")
    load = load_avg()
    # the firmware alone, right after the reference it replays (the same load on the machine)
    fw_cpus: list[float] = []
    fwall, fwalls, fs, same = firmware_alone(kept, repeat, fw_cpus)
    with tempfile.TemporaryDirectory() as d:
        fw_parts = firmware_in_replay(kept / "capture.psnscap", Path(d), ticks)
    kept_dir.cleanup()
    frtf = fs["sim_duration_s"] / fwall
    # profile (a shorter cut is as representative per tick, and cProfile doubles the run time)
    pscn = _cut(ref, number("PSNS_BENCH_PROFILE_S"))
    if pscn is scn:
        pwall = wall
    else:
        pwall, _w, _s = _timed(pscn, 1)
    pticks = round(pscn.duration_s * scn.sensors.imu.rate_hz)
    parts, iters = breakdown(pscn, pwall, pticks)
    top = ", ".join(f"{p['component'].split(' (')[0]} {p['us_per_tick']:.0f}" for p in parts[:5])
    rows: list[dict[str, Any]] = [
        {"name": "reference fast-mode real-time factor", "value": rtf, "unit": "sim s / wall s",
         "baseline": TARGET_RTF, "ratio": rtf / TARGET_RTF,
         "note": f"{scn.name}, {sim:.0f} s simulated, median of {repeat} ({', '.join(f'{w:.1f}' for w in walls)} s "
                 f"wall), expectations passed: {passed}, load avg {load}; target >= 100x",
         "walls_s": walls, "sim_s": sim, "passed": passed},
        {"name": "reference wall time per 200 Hz tick", "value": us_tick, "unit": "us/tick",
         "baseline": 1e6 / 200 / TARGET_RTF, "ratio": us_tick / (1e6 / 200 / TARGET_RTF),
         "note": f"baseline: the whole budget at 100x; {iters / pticks:.2f} event-loop callbacks per tick; "
                 f"top: {top} us/tick",
         "breakdown": parts, "loop_callbacks_per_tick": iters / pticks, "profiled_sim_s": pscn.duration_s},
    ]
    for p in parts:
        if p["share"] < 0.002:
            continue
        rows.append({"name": f"  breakdown: {p['component']}", "value": p["us_per_tick"], "unit": "us/tick",
                     "baseline": None, "ratio": None,
                     "note": f"{100 * p['share']:.1f} % of the profiled run ({pscn.duration_s:.0f} s simulated)"})
    rows.append({"name": "reference real-time factor, the firmware alone (replay of its capture)", "value": frtf,
                 "unit": "sim s / wall s", "baseline": rtf, "ratio": frtf / rtf,
                 "note": f"baseline: the reference above; its capture replayed (psns-hil replay, fast): DSP, firmware, "
                         f"DSP UARTs, host port, recorder, no world; {fs['sim_duration_s']:.0f} s simulated, median of "
                         f"{repeat} ({', '.join(f'{w:.1f}' for w in fwalls)} s wall), {fwall / ticks * 1e6:.0f} us per "
                         f"tick, nav.csv identical to the reference's: {same}, load avg {load_avg()}; CPU time "
                         f"{median(fw_cpus):.1f} s against the reference's {median(ref_cpus):.1f} s "
                         f"({median(ref_cpus) / median(fw_cpus):.2f} x); the most a world of zero cost would give",
                 "walls_s": fwalls, "cpu_s": fw_cpus, "reference_cpu_s": ref_cpus, "sim_s": fs["sim_duration_s"],
                 "nav_identical": same, "vs_reference": frtf / rtf})
    fw_total = fw_parts["total"]
    rows.append({"name": "reference's firmware per tick, on its own input (receive + service)", "value": fw_total,
                 "unit": "us", "baseline": FIRMWARE_TARGET_US, "ratio": fw_total / FIRMWARE_TARGET_US,
                 "note": f"its capture replayed once more, Firmware.receive and .service timed (wall); baseline: the "
                         f"firmware's {FIRMWARE_TARGET_US:.0f} us share of a 5 ms tick at 100x (the synthetic "
                         f"stream's rows: benchmarks.bench_firmware); alone it caps the reference at "
                         f"{5000.0 / fw_total:.0f}x",
                 "parts": fw_parts})
    for part in PARTS:
        rows.append({"name": f"  reference's firmware part: {part}", "value": fw_parts[part], "unit": "us",
                     "baseline": fw_total, "ratio": fw_parts[part] / fw_total,
                     "note": "us per tick (a second replay, the parts timed); ratio: share of the total"})
    fid = fidelity_ratio(number("PSNS_BENCH_FIDELITY_S"), repeat)
    rows.append({"name": "reference real-time factor, world fidelity on / off", "value": fid["ratio"],
                 "unit": "ratio", "baseline": TARGET_FIDELITY_RATIO, "ratio": fid["ratio"] / TARGET_FIDELITY_RATIO,
                 "note": f"{fid['sim_s']:.0f} s simulated per run, CPU time, {repeat} alternating off/on pairs: "
                         f"off {', '.join(f'{r:.1f}' for r in fid['rtf_off'])} x, on "
                         f"{', '.join(f'{r:.1f}' for r in fid['rtf_on'])} x, expectations passed: {fid['passed']}, "
                         f"load avg {load_avg()}; target >= {TARGET_FIDELITY_RATIO} (docs/performance.md 2)",
                 "ratios": fid["ratios"], "rtf_off": fid["rtf_off"], "rtf_on": fid["rtf_on"]})
    world = _cut(load_scenario(REFERENCE, WORLD_ONLY), number("PSNS_BENCH_REF_S"))
    wwall, wwalls, ws = _timed(world, repeat)
    wrtf = ws["sim_duration_s"] / wwall
    rows.append({"name": "reference real-time factor, the world without the DSP (ceiling)", "value": wrtf,
                 "unit": "sim s / wall s", "baseline": TARGET_RTF, "ratio": wrtf / TARGET_RTF,
                 "note": f"the reference with no firmware (dsp.external, docs/performance.md 5.14): trajectory, sky, "
                         f"sensors, FPGA, byte-exact links and captures only; {ws['sim_duration_s']:.0f} s simulated, "
                         f"median of {repeat} ({', '.join(f'{w:.1f}' for w in wwalls)} s wall); {wrtf / rtf:.2f} x "
                         f"the reference's {rtf:.1f}x above; nav frames {ws.get('nav_frames') or 0}, load avg "
                         f"{load_avg()}; the most a firmware of zero cost would give; target >= 100x",
                 "walls_s": wwalls, "sim_s": ws["sim_duration_s"], "vs_reference": wrtf / rtf})
    q = load_scenario(ROOT / "scenarios" / "quickstart.yaml")
    qwall, qwalls, qs = _timed(q, repeat)
    qrtf = qs["sim_duration_s"] / qwall
    rows.append({"name": "quickstart fast-mode real-time factor", "value": qrtf, "unit": "sim s / wall s",
                 "baseline": TARGET_RTF, "ratio": qrtf / TARGET_RTF,
                 "note": f"static, IMU + GNSS, {qs['sim_duration_s']:.0f} s simulated, median of {repeat} "
                         f"({', '.join(f'{w:.1f}' for w in qwalls)} s wall)",
                 "walls_s": qwalls})
    return rows


if __name__ == "__main__":  # pragma: no cover
    for row in run():
        print({k: v for k, v in row.items() if k != "breakdown"})
