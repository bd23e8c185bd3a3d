"""The navigation cost of 1 s of near-rail or over-range gyro (issue 41 item 6; studies/2026-12-07-near-rail-gyro.md).

Two measurements, each with the firmware as it is and, with ``--before``, as it was before issue 41 (the STIM STATUS
byte not read, no range check: ``firmware_model.input_guard.check_gyro_status`` and ``check_imu_range`` replaced by
functions that accept everything; the 24-bit rail check stays):

* ``corpus``: the hostile corpus cases ``imu_gyro_near_rail_1s`` (words one LSB inside the rail, 512 deg/s) and
  ``imu_gyro_overload_status_1s`` (300 deg/s, STATUS overload on Z) on every filter variant (the static synthetic
  stream of ``tests/firmware_model/hostile.py``); recovery = seconds after the window until every later 1 Hz
  sample is within heading 1 deg, level 0.2 deg, horizontal position 15 m;
* ``e2e``: the quickstart scenario (150 s static, base filter, camera) with a gyro bias step of 500 deg/s on z for
  [60, 61) s, through the whole emulator (the STIM210 model clips at its +-400 deg/s range and, now, flags
  overload); recovery from ``nav.csv``: the last time after 61 s with heading error > 1 deg or position error
  > 15 m, minus 61 s.

Usage::

    PSNS_HIL_STRICT=1 .venv/bin/python -m studies.scripts.near_rail_gyro corpus [--before]
    PSNS_HIL_STRICT=1 .venv/bin/python -m studies.scripts.near_rail_gyro e2e OUT_DIR [--before]
"""

from __future__ import annotations

import csv
import math
import sys
import time
from pathlib import Path

import yaml

from firmware_model import input_guard

VARIANTS = ("base", "dual_vector", "federated", "kmeans_3d", "sun_elevation")
CASES = ("imu_gyro_near_rail_1s", "imu_gyro_overload_status_1s")


def _as_before() -> None:
    input_guard.check_gyro_status = lambda status: None
    input_guard.check_imu_range = lambda g, a, gm, am: (None, None)  # type: ignore[assignment]


def _counters(c: dict[str, int]) -> dict[str, int]:
    return {k: v for k, v in c.items() if v and (k.startswith("input_rejected") or k.startswith("fdir"))}


def corpus() -> None:
    import importlib

    hostile = importlib.import_module("tests.firmware_model.hostile")  # the test corpus (not type-checked here)
    T_BAD, run_case = hostile.T_BAD, hostile.run_case

    for case in CASES:
        for v in VARIANTS:
            r = run_case(case, v)
            during = [s for s in r.samples if T_BAD[0] <= s[0] < T_BAD[1] + 31.0 and s[3] < 1e8]
            worst = max((abs(s[1]) for s in during), default=math.nan)
            print(f"{case} {v}: recovery {r.recovery_s(1.0, 0.2, 15.0):.0f} s, worst heading error while "
                  f"navigating {worst:.1f} deg, {_counters(r.counters)}", flush=True)


def e2e(out: Path) -> None:
    from emulator.assembly.session import run_scenario
    from emulator.scenario import load_scenario

    data = yaml.safe_load(Path("scenarios/quickstart.yaml").read_text())
    data.update(name="near_rail_gyro", duration_s=150, expectations=[])
    data["motion"] = [{"static": {"duration_s": 150}}]
    data["faults"] = [{"imu_bias_step": {"start_s": 60.0, "duration_s": 1.0,
                                         "gyro_deg_h": [0.0, 0.0, 500.0 * 3600.0]}}]
    out.mkdir(parents=True, exist_ok=True)
    (out / "s.yaml").write_text(yaml.safe_dump(data, sort_keys=False))
    t0 = time.time()
    s = run_scenario(load_scenario(out / "s.yaml"), out / "run")
    rows = list(csv.DictReader((out / "run" / "nav.csv").open()))

    def f(r: dict[str, str], k: str) -> float:
        return float(r[k]) if r[k] not in ("", "nan") else math.nan

    pre = [r for r in rows if 40.0 <= f(r, "time_s") < 60.0]
    post = [r for r in rows if f(r, "time_s") >= 60.0]
    bad = [f(r, "time_s") for r in post if not (abs(f(r, "err_heading_deg")) <= 1.0 and f(r, "err_pos_m") <= 15.0)]
    rec = max(0.0, max(bad) - 61.0) if bad else 0.0
    h_post = max(abs(f(r, "err_heading_deg")) for r in post if not math.isnan(f(r, "err_heading_deg")))
    print(f"recovery {rec:.2f} s; max heading error after 60 s {h_post:.2f} deg (40-60 s: "
          f"{max(abs(f(r, 'err_heading_deg')) for r in pre):.2f} deg); {_counters(s['firmware']['counters'])}; "
          f"wall {time.time() - t0:.0f} s")


if __name__ == "__main__":
    if "--before" in sys.argv:
        _as_before()
    args = [a for a in sys.argv[1:] if a != "--before"]
    if args and args[0] == "corpus":
        corpus()
    elif len(args) == 2 and args[0] == "e2e":
        e2e(Path(args[1]))
    else:
        sys.exit(__doc__)
