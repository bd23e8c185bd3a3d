"""Error budget of a scenario: heading and position error with each error source alone, all of them, and none.

    python benchmarks/error_budget.py [scenario.yaml] [--seeds 21 22 23] [--configs ideal field ...] [--markdown]

Each configuration starts from ``sensors.preset: ideal`` on a clear Rayleigh sky and switches on one source
(``field`` and ``ideal`` are the whole suites on the realistic / clear sky). For every configuration and seed the
scenario runs in fast mode; the table gives, over seeds, the mean of: the maximum heading error after alignment
(``after_s``), the RMS position error while GNSS is available and the maximum position error in the GNSS outage
window (taken from the scenario's own ``nav_error`` expectations), and each expectation's measured value, so the
numbers that scenario expectations are derived from are printed too (docs/sensors.md, "Error budget").
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
import tempfile
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from emulator.assembly.runner import run_scenario  # noqa: E402
from emulator.testing import load_test_scenario  # noqa: E402

CLEAR = {"sky.model": "rayleigh"}
#: the scenario's camera with the ideal camera preset (the scenario names its own preset, which would win)
IDEAL_CAMERA = {"sensors.camera.preset": "ideal"}
#: configuration -> overrides (dotted paths) on top of the scenario
CONFIGS: dict[str, dict[str, Any]] = {
    "ideal": {"sensors.preset": "ideal", **CLEAR, **IDEAL_CAMERA},
    "sky (realistic, T=3)": {"sensors.preset": "ideal", "sky.model": "realistic", **IDEAL_CAMERA},
    "gyro (STIM210 field)": {"sensors.preset": "ideal", **CLEAR, **IDEAL_CAMERA, "sensors.imu.gyro": "FIELD_GYRO"},
    "accelerometers (MS1030)": {"sensors.preset": "ideal", **CLEAR, **IDEAL_CAMERA,
                                "sensors.imu.accel": "FIELD_ACCEL"},
    "accelerometers (MS1030) + realistic sky": {"sensors.preset": "ideal", "sky.model": "realistic", **IDEAL_CAMERA,
                                                "sensors.imu.accel": "FIELD_ACCEL"},
    "gyro filter delay (262 Hz)": {"sensors.preset": "ideal", **CLEAR, **IDEAL_CAMERA,
                                   "sensors.imu.lp_filter_hz": 262},
    "IMU warm-up (12 degC, 10 min)": {"sensors.preset": "ideal", **CLEAR, **IDEAL_CAMERA,
                                      "sensors.imu.temperature": {"warmup_c": 12.0, "warmup_tau_s": 600.0},
                                      "sensors.imu.gyro": {"bias_temp_gradient_deg_h": 10.0}},
    "vibration (field profile)": {"sensors.preset": "ideal", **CLEAR, **IDEAL_CAMERA,
                                  "sensors.imu.vibration": "FIELD_VIBRATION",
                                  "sensors.imu.accel": {"vre_ug_per_g2": "FIELD_VRE"},
                                  "sensors.imu.gyro": {"g_sensitivity_deg_h_per_g": 10.0}},
    "GNSS (field)": {"sensors.preset": "ideal", **CLEAR, **IDEAL_CAMERA, "sensors.gnss.preset": "field"},
    "camera (reference noise; ideal optics in the rest)": {"sensors.preset": "ideal", **CLEAR,
                                                           "sensors.camera.preset": "reference"},
    "paper": {"sensors.preset": "paper", **CLEAR},
    "field, clear sky": {"sensors.preset": "field", **CLEAR},
    "field": {"sensors.preset": "field", "sky.model": "realistic"},
}


def _field(kind: str) -> dict[str, Any]:
    from emulator.scenario.presets import preset

    return preset("imu", "field")[kind]


def _expand(ov: dict[str, Any]) -> dict[str, Any]:
    out = dict(ov)
    for k, v in ov.items():
        if v == "FIELD_GYRO":
            out[k] = _field("gyro")
        elif v == "FIELD_ACCEL":
            out[k] = _field("accel")
        elif v == "FIELD_VIBRATION":
            out[k] = {**_field("vibration"), "enabled": True}  # the preset carries it switched off
        elif isinstance(v, dict) and v.get("vre_ug_per_g2") == "FIELD_VRE":
            out[k] = {**v, "vre_ug_per_g2": _field("accel")["vre_ug_per_g2"]}
    return out


def run_one(path: Path, overrides: dict[str, Any], seed: int) -> dict[str, Any]:
    scn = load_test_scenario(path, {**_expand(overrides), "seed": seed})
    with tempfile.TemporaryDirectory() as tmp:
        summary = run_scenario(scn, Path(tmp) / "run", mode="fast")
        with open(Path(tmp) / "run" / "nav.csv", newline="") as f:
            nav = [r for r in csv.DictReader(f) if r["err_heading_deg"]]
    return {"summary": summary, "nav": nav}


def _window(nav: list[dict[str, str]], col: str, lo: float, hi: float) -> list[float]:
    return [abs(float(r[col])) for r in nav if lo <= float(r["time_s"]) <= hi and r[col]]


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenario", nargs="?", default=str(ROOT / "scenarios" / "vehicle_loop_gnss_outage.yaml"))
    ap.add_argument("--seeds", type=int, nargs="+", default=[21, 22, 23])
    ap.add_argument("--configs", nargs="+", default=list(CONFIGS))
    ap.add_argument("--after-s", type=float, default=15.0, help="heading statistics after this time (alignment)")
    ap.add_argument("--outage", type=float, nargs=2, default=[55.0, 86.0], help="GNSS outage window, s")
    ap.add_argument("--aided", type=float, nargs=2, default=[100.0, 150.0], help="GNSS-aided window, s")
    ap.add_argument("--expectations", action="store_true", help="print every expectation's measured values")
    a = ap.parse_args(argv)
    path = Path(a.scenario)
    print(f"| sources ({path.stem}, seeds {' '.join(map(str, a.seeds))}) | heading max (deg) | heading rms (deg) "
          f"| position max in outage (m) | position rms aided (m) |")
    print("|---|---|---|---|---|")
    for name in a.configs:
        hmax, hrms, pmax, prms = [], [], [], []
        exp: dict[int, list[Any]] = {}
        for seed in a.seeds:
            r = run_one(path, CONFIGS[name], seed)
            h = _window(r["nav"], "err_heading_deg", a.after_s, math.inf)
            hmax.append(max(h))
            hrms.append(math.sqrt(sum(x * x for x in h) / len(h)))
            pmax.append(max(_window(r["nav"], "err_pos_m", *a.outage)))
            p = _window(r["nav"], "err_pos_m", *a.aided)
            prms.append(math.sqrt(sum(x * x for x in p) / len(p)))
            for e in r["summary"]["expectations"]:
                exp.setdefault(e["index"], [e["description"]]).append(e["value"])

        def m(xs: list[float]) -> str:
            return f"{sum(xs) / len(xs):.3g} ({min(xs):.3g}-{max(xs):.3g})"

        print(f"| {name} | {m(hmax)} | {m(hrms)} | {m(pmax)} | {m(prms)} |", flush=True)
        if a.expectations:
            for _i, (desc, *vals) in sorted(exp.items()):
                print(f"    {desc}: {vals}", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
