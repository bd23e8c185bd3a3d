"""Fast-mode real-time factor of a foreign firmware in lockstep (docs/icd.md section 10): the example C firmware
(examples/c_firmware, psns_nav) behind the virtual DSP's UARTs, in-process (the shared library) and out-of-process
(the lockstep program on a pipe), on its own scenario (examples/c_firmware/lockstep_lib.yaml: static, IMU and
GNSS, 200 NAV_SOLUTION frames/s), against the same scenario with the built-in firmware in the virtual DSP.
Target: at least 10x real time for both transports (issue 40). The value is simulated seconds per CPU second of
the emulator and the firmware process together (``time.process_time`` plus the children's CPU time from
``resource.getrusage``: the machine is shared, and CPU time is what the other processes disturb least); the
wall-clock factor of the same runs and the machine's load average go in the note. Median of ``PSNS_BENCH_REPEAT``
runs of ``PSNS_BENCH_LOCKSTEP_S`` simulated seconds.
"""

from __future__ import annotations

import os
import resource
import shutil
import subprocess
import tempfile
import time
from pathlib import Path
from typing import Any

from benchmarks.common import ROOT, load_avg, median, number
from emulator.assembly.session import run_scenario
from emulator.dsp.lockstep import ALLOW_FIRMWARE_ENV
from emulator.scenario import load_scenario

TARGET_RTF = 10.0
EXAMPLE = ROOT / "examples" / "c_firmware"


def _children_cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def _rtf(path: Path, duration_s: float, repeat: int, builtin: bool = False) -> tuple[float, float, list[float]]:
    """(simulated s per CPU s, per wall s, the wall times) of ``repeat`` runs (medians)."""
    sets = (f"duration_s={duration_s:g}", f"motion.0.static.duration_s={duration_s:g}")
    scn = load_scenario(path, sets)
    if builtin:
        scn = scn.model_copy(update={"dsp": scn.dsp.model_copy(update={"external": None})})
    walls: list[float] = []
    cpus: list[float] = []
    for _ in range(repeat):
        with tempfile.TemporaryDirectory() as d:
            t0, c0, k0 = time.perf_counter(), time.process_time(), _children_cpu()
            s = run_scenario(scn, Path(d) / "run", mode="fast")
            walls.append(time.perf_counter() - t0)
            cpus.append(time.process_time() - c0 + _children_cpu() - k0)
            lock = s.get("lockstep")
            if lock is not None and lock["failed"]:
                raise RuntimeError(f"the lockstep firmware failed: {lock['failure']}")
    return duration_s / median(cpus), duration_s / median(walls), walls


def run() -> list[dict[str, Any]]:
    if shutil.which(os.environ.get("CC", "gcc")) is None:
        return [{"name": "lockstep C firmware", "value": float("nan"), "unit": "x real time", "baseline": None,
                 "ratio": None, "note": "no C compiler (gcc): examples/c_firmware not built"}]
    duration = number("PSNS_BENCH_LOCKSTEP_S")
    repeat = int(number("PSNS_BENCH_REPEAT"))
    os.environ[ALLOW_FIRMWARE_ENV] = "1"
    rows: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as d:
        dd = Path(d)
        subprocess.run(["make", "-s", "-C", str(EXAMPLE), f"BUILD={dd / 'build'}"], check=True, timeout=300)
        for name in ("lockstep_lib.yaml", "lockstep_proc.yaml"):
            shutil.copy2(EXAMPLE / name, dd / name)
        builtin, _, _ = _rtf(dd / "lockstep_lib.yaml", duration, repeat, builtin=True)
        for label, name in (("in-process (ctypes)", "lockstep_lib.yaml"),
                            ("out-of-process (pipe)", "lockstep_proc.yaml")):
            rtf, rtf_wall, walls = _rtf(dd / name, duration, repeat)
            rows.append({"name": f"lockstep C firmware, {label}", "value": rtf, "unit": "x real time (CPU)",
                         "baseline": TARGET_RTF, "ratio": rtf / TARGET_RTF,
                         "note": f"examples/c_firmware/{name}, {duration:g} s simulated, median of {len(walls)}; "
                                 f"wall clock {rtf_wall:.1f}x ({', '.join(f'{w:.2f}' for w in walls)} s); the same "
                                 f"scenario with the built-in firmware: {builtin:.1f}x (CPU); load {load_avg()}"})
    return rows
