"""Error budget of a scenario: solar-vector and heading error (and position, where the scenario has the windows)
with each error source alone, all of them, and none.

    python -m studies.scripts.error_budget [scenario.yaml] [--seeds 21 22 23] [--configs ideal field ...]
                                      [--after-s 15] [--jobs 2] [--expectations]

Every row names every sensor's preset itself (``sensors.preset`` and ``sensors.imu.preset``,
``sensors.gnss.preset``, ``sensors.camera.preset``: a scenario that names a sensor's own preset would otherwise
keep it) and the firmware's calibration source. ``ideal`` is the perfect IMU and GNSS, the ideal camera (no noise,
ideal polarizers, the scenario's optics), a perfect calibration and the clear Rayleigh sky; each single-source row
switches one thing of ``ideal`` on; ``paper`` and ``field`` are the whole suites (clear sky / realistic sky, the
calibration as a calibrated unit: truth plus residuals). The scenario's other settings (camera fidelity, grid,
firmware) stay.

Columns, over the seeds: the solar-vector error after alignment (``--after-s``; the firmware's solved vector
against the world's sun in the body frame, ``psns.csv``), median and 95th percentile of all seeds' solves
together, and the medians of its azimuth and elevation parts (``err_az_deg``, ``err_el_deg``: the azimuth is
what a sun-referenced heading inherits, the elevation maps into tilt); the heading error after alignment, RMS
and maximum (mean over seeds, range in brackets); and, when the
run covers them, the maximum position error in the GNSS outage window (``--outage``) and the RMS position error
while GNSS is back (``--aided``). ``--expectations`` prints each scenario expectation's measured values.
docs/sensors.md, "Error budget", has the tables of the library scenarios.
"""

from __future__ import annotations

import argparse
import csv
import math
import statistics
import sys
import tempfile
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from emulator.assembly.session import run_scenario  # noqa: E402
from emulator.testing import load_test_scenario  # noqa: E402

CLEAR = {"sky.model": "rayleigh"}
REALISTIC = {"sky.model": "realistic"}


def suite(name: str, camera: str | None = None, calibration: str = "residuals") -> dict[str, Any]:
    """Every sensor on the suite preset ``name`` (``ideal``, ``paper``, ``field``), named per sensor so that a
    scenario's own per-sensor preset does not win; the firmware's calibration source."""
    imu, gnss, cam = {"ideal": ("perfect", "perfect", "ideal"), "paper": ("paper", "paper", "reference"),
                      "field": ("field", "field", "reference")}[name]
    return {"sensors.preset": name, "sensors.imu.preset": imu, "sensors.gnss.preset": gnss,
            "sensors.camera.preset": camera or cam, "firmware.calibration.source": calibration}


IDEAL = {**suite("ideal", calibration="perfect"), **CLEAR}
#: configuration -> overrides (dotted paths) on top of the scenario
CONFIGS: dict[str, dict[str, Any]] = {
    "ideal": IDEAL,
    "sky (realistic, T=3)": {**IDEAL, **REALISTIC},
    "gyro (STIM210 field)": {**IDEAL, "sensors.imu.gyro": "FIELD_GYRO"},
    "accelerometers (MS1030)": {**IDEAL, "sensors.imu.accel": "FIELD_ACCEL"},
    "gyro filter delay (262 Hz)": {**IDEAL, "sensors.imu.lp_filter_hz": 262},
    "IMU warm-up (12 degC, 10 min)": {**IDEAL, "sensors.imu.temperature": {"warmup_c": 12.0, "warmup_tau_s": 600.0},
                                      "sensors.imu.gyro": {"bias_temp_gradient_deg_h": 10.0}},
    "vibration (field profile)": {**IDEAL, "sensors.imu.vibration": "FIELD_VIBRATION",
                                  "sensors.imu.accel": {"vre_ug_per_g2": "FIELD_VRE"},
                                  "sensors.imu.gyro": {"g_sensitivity_deg_h_per_g": 10.0}},
    "GNSS (field)": {**IDEAL, "sensors.gnss.preset": "field"},
    "camera (reference: noise, polarizers, lens)": {**IDEAL, "sensors.camera.preset": "reference"},
    "camera calibration residuals": {**IDEAL, "firmware.calibration.source": "residuals"},
    "paper": {**suite("paper"), **CLEAR},
    "field, clear sky": {**suite("field"), **CLEAR},
    "field": {**suite("field"), **REALISTIC},
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
    """One fast-mode run: its summary, the navigating rows of nav.csv and the rows of psns.csv."""
    scn = load_test_scenario(path, {**_expand(overrides), "seed": seed})
    with tempfile.TemporaryDirectory() as tmp:
        run = Path(tmp) / "run"
        summary = run_scenario(scn, run, mode="fast")
        with open(run / "nav.csv", newline="") as f:
            nav = [r for r in csv.DictReader(f) if r["err_heading_deg"]]
        psns: list[dict[str, str]] = []
        if (run / "psns.csv").exists():
            with open(run / "psns.csv", newline="") as f:
                psns = list(csv.DictReader(f))
    return {"summary": summary, "nav": nav, "psns": psns}


def _job(args: tuple[str, str, int]) -> tuple[str, int, dict[str, Any]]:
    path, name, seed = args
    return name, seed, run_one(Path(path), CONFIGS[name], seed)


def _window(nav: list[dict[str, str]], col: str, lo: float, hi: float) -> list[float]:
    return [abs(float(r[col])) for r in nav if lo <= float(r["time_s"]) <= hi and r[col]]


def percentile(xs: list[float], q: float) -> float:
    """The ``q``-th percentile with linear interpolation between order statistics (numpy's default)."""
    s = sorted(xs)
    k = (len(s) - 1) * q / 100.0
    lo = math.floor(k)
    hi = min(lo + 1, len(s) - 1)
    return s[lo] + (s[hi] - s[lo]) * (k - lo)


def row(name: str, runs: list[dict[str, Any]], after_s: float, outage: tuple[float, float],
        aided: tuple[float, float]) -> dict[str, Any]:
    """The table's numbers of one configuration over its runs (see module docstring)."""
    sv = [float(r["err_deg"]) for run in runs for r in run["psns"] if float(r["time_s"]) >= after_s]
    sv_az = [abs(float(r["err_az_deg"])) for run in runs for r in run["psns"] if float(r["time_s"]) >= after_s]
    sv_el = [abs(float(r["err_el_deg"])) for run in runs for r in run["psns"] if float(r["time_s"]) >= after_s]
    hmax, hrms, pmax, prms = [], [], [], []
    for run in runs:
        h = _window(run["nav"], "err_heading_deg", after_s, math.inf)
        hmax.append(max(h))
        hrms.append(math.sqrt(sum(x * x for x in h) / len(h)))
        po = _window(run["nav"], "err_pos_m", *outage)
        if po:
            pmax.append(max(po))
        pa = _window(run["nav"], "err_pos_m", *aided)
        if pa:
            prms.append(math.sqrt(sum(x * x for x in pa) / len(pa)))
    return {"name": name, "solves": len(sv), "sv_median": statistics.median(sv) if sv else None,
            "sv_p95": percentile(sv, 95.0) if sv else None,
            "sv_az_median": statistics.median(sv_az) if sv_az else None,
            "sv_el_median": statistics.median(sv_el) if sv_el else None,
            "hrms": hrms, "hmax": hmax, "pmax": pmax, "prms": prms}


def _m(xs: list[float]) -> str:
    if not xs:
        return "-"
    return f"{sum(xs) / len(xs):.3g} ({min(xs):.3g}-{max(xs):.3g})"


def _g(x: float | None) -> str:
    return "-" if x is None else f"{x:.3g}"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("scenario", nargs="?", default=str(ROOT / "scenarios" / "vehicle_loop_gnss_outage.yaml"))
    ap.add_argument("--seeds", type=int, nargs="+", default=[21, 22, 23])
    ap.add_argument("--configs", nargs="+", default=list(CONFIGS), choices=list(CONFIGS), metavar="CONFIG")
    ap.add_argument("--after-s", type=float, default=15.0, help="statistics after this time (alignment), s")
    ap.add_argument("--outage", type=float, nargs=2, default=[55.0, 86.0], help="GNSS outage window, s")
    ap.add_argument("--aided", type=float, nargs=2, default=[100.0, 150.0], help="GNSS-aided window, s")
    ap.add_argument("--jobs", type=int, default=1, help="runs in parallel (processes)")
    ap.add_argument("--expectations", action="store_true", help="print every expectation's measured values")
    a = ap.parse_args(argv)
    path = Path(a.scenario)
    todo = [(str(path), name, seed) for name in a.configs for seed in a.seeds]
    results: dict[str, list[dict[str, Any]]] = {name: [] for name in a.configs}
    print(f"| sources ({path.stem}, seeds {' '.join(map(str, a.seeds))}) | solar vector median (deg) "
          f"| solar vector p95 (deg) | of it azimuth, median (deg) | of it elevation, median (deg) "
          f"| heading rms (deg) | heading max (deg) | position max in outage (m) "
          f"| position rms aided (m) |")
    print("|---|---|---|---|---|---|---|---|---|", flush=True)

    def emit(name: str) -> None:
        runs = results[name]
        r = row(name, runs, a.after_s, (a.outage[0], a.outage[1]), (a.aided[0], a.aided[1]))
        print(f"| {name} | {_g(r['sv_median'])} | {_g(r['sv_p95'])} | {_g(r['sv_az_median'])} "
              f"| {_g(r['sv_el_median'])} | {_m(r['hrms'])} | {_m(r['hmax'])} "
              f"| {_m(r['pmax'])} | {_m(r['prms'])} |", flush=True)
        if a.expectations:
            exp: dict[int, list[Any]] = {}
            for run in runs:
                for e in run["summary"]["expectations"]:
                    exp.setdefault(e["index"], [e["description"]]).append(e["value"])
            for _i, (desc, *vals) in sorted(exp.items()):
                print(f"    {desc}: {vals}", flush=True)

    if a.jobs > 1:
        with ProcessPoolExecutor(a.jobs) as ex:
            for name, _seed, res in ex.map(_job, todo):
                results[name].append(res)
                if len(results[name]) == len(a.seeds):
                    emit(name)
    else:
        for job in todo:
            name, _seed, res = _job(job)
            results[name].append(res)
            if len(results[name]) == len(a.seeds):
                emit(name)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
