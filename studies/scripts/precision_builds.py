"""The firmware's arithmetic precision: the C6747 build against an all-double and an all-single build.

    python -m studies.scripts.precision_builds [--duration 3600] [--seed 10] [--markdown]

Three builds of the same firmware run on the same world (same scenario, same seed, so every sensor byte is the
same; only the firmware's arithmetic differs):

* ``c6747``: the build the C6747 runs (docs/firmware.md "Precision"): single-precision kernels (IMU conversion,
  coning/sculling, Kalman filter, PSNS solve), the attitude quaternion and velocity accumulators, latitude,
  longitude and time in double precision (decision D-L.1), the strapdown charged at DP prices;
* ``float64``: every kernel in double precision (the reference);
* ``float32``: single precision everywhere except latitude, longitude and time.

Two worlds: 1 h static (``static_psns_camera.yaml``) and 1 h manoeuvring (``bench_vehicle_loop_10min.yaml``'s
square laps repeated for the hour), both with the ``field`` presets of their scenario files. For each build the
table gives the largest difference of its NAV_SOLUTION frames from the float64 build's (attitude: the rotation
angle between the two; position: horizontal metres; velocity: m/s) and its own error against truth (heading RMS,
horizontal position RMS after alignment). Runs in fast mode: about 2-3 minutes per build per hour on this machine.
"""

from __future__ import annotations

import argparse
import csv
import math
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial.transform import Rotation

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from emulator.assembly.session import run_scenario  # noqa: E402
from emulator.testing import load_test_scenario  # noqa: E402

BUILDS: dict[str, dict[str, str]] = {
    "c6747": {"firmware.precision": "float32", "firmware.nav_state_precision": "float64"},
    "float64": {"firmware.precision": "float64", "firmware.nav_state_precision": "float64"},
    "float32": {"firmware.precision": "float32", "firmware.nav_state_precision": "float32"},
}
WORLDS = {"static": "scenarios/static_psns_camera.yaml", "manoeuvring": "scenarios/bench_vehicle_loop_10min.yaml"}
#: WGS-84 semi-major axis (m): metres per radian of latitude/longitude to the precision a difference needs
_A_M = 6_378_137.0


def laps(duration_s: float) -> list[dict[str, Any]]:
    """The reference's motion stretched to ``duration_s``: 15 s static, accelerate to 10 m/s, square laps (20 s
    cruise, 90 deg right turn at 9 deg/s), a final cruise that fills the rest."""
    seg: list[dict[str, Any]] = [{"static": {"duration_s": 15}},
                                 {"accelerate": {"duration_s": 5, "to_speed_mps": 10}}]
    t = 20.0
    while t + 30.0 <= duration_s:
        seg += [{"cruise": {"duration_s": 20}}, {"turn": {"rate_dps": 9, "angle_deg": 90}}]
        t += 30.0
    if duration_s - t > 0:
        seg.append({"cruise": {"duration_s": round(duration_s - t, 3)}})
    return seg


def run_build(world: str, build: str, duration_s: float, seed: int) -> list[dict[str, str]]:
    """nav.csv rows of one build in one world."""
    overrides: dict[str, Any] = {**BUILDS[build], "duration_s": duration_s, "seed": seed, "expectations": []}
    overrides["motion"] = laps(duration_s) if world == "manoeuvring" else [{"static": {"duration_s": duration_s}}]
    scn = load_test_scenario(ROOT / WORLDS[world], overrides)
    with tempfile.TemporaryDirectory() as tmp:
        run_scenario(scn, Path(tmp) / "run", mode="fast")
        with open(Path(tmp) / "run" / "nav.csv", newline="") as f:
            return list(csv.DictReader(f))


def _att(r: dict[str, str]) -> Rotation:
    return Rotation.from_euler("ZXY", [-float(r["heading_deg"]), float(r["pitch_deg"]), float(r["roll_deg"])],
                               degrees=True)


def differences(rows: list[dict[str, str]], ref: list[dict[str, str]]) -> dict[str, float]:
    """Largest differences of ``rows`` from ``ref`` frame by frame (matched by time): attitude (deg, the angle of the
    relative rotation), horizontal position (m), velocity (m/s)."""
    by_t = {r["time_s"]: r for r in ref}
    att, pos, vel = [0.0], [0.0], [0.0]
    for r in rows:
        q = by_t.get(r["time_s"])
        if q is None:
            continue
        att.append(math.degrees((_att(r).inv() * _att(q)).magnitude()))
        dn = math.radians(float(r["lat_deg"]) - float(q["lat_deg"])) * _A_M
        coslat = math.cos(math.radians(float(q["lat_deg"])))
        de = math.radians(float(r["lon_deg"]) - float(q["lon_deg"])) * _A_M * coslat
        pos.append(math.hypot(dn, de))
        vel.append(math.dist([float(r[f"vel_{c}_mps"]) for c in "enu"], [float(q[f"vel_{c}_mps"]) for c in "enu"]))
    return {"att_deg": max(att), "pos_m": max(pos), "vel_mps": max(vel), "frames": len(att) - 1}


def errors(rows: list[dict[str, str]], after_s: float = 120.0) -> dict[str, float]:
    """The build's own error against truth after ``after_s``: heading RMS (deg), horizontal position RMS (m)."""
    h = np.array([float(r["err_heading_deg"]) for r in rows if r["err_heading_deg"] and float(r["time_s"]) >= after_s])
    p = np.array([math.hypot(float(r["err_pos_e_m"]), float(r["err_pos_n_m"])) for r in rows
                  if r["err_pos_e_m"] and float(r["time_s"]) >= after_s])
    return {"heading_rms_deg": float(np.sqrt(np.mean(h**2))) if h.size else math.nan,
            "pos_rms_m": float(np.sqrt(np.mean(p**2))) if p.size else math.nan}


def measure(duration_s: float, seed: int, worlds: list[str]) -> list[dict[str, Any]]:
    out = []
    for world in worlds:
        runs = {b: run_build(world, b, duration_s, seed) for b in BUILDS}
        for b, rows in runs.items():
            out.append({"world": world, "build": b, **differences(rows, runs["float64"]), **errors(rows)})
    return out


def markdown(rows: list[dict[str, Any]], duration_s: float) -> str:
    lines = [f"| world ({duration_s / 3600:g} h) | build | attitude vs float64 (deg, max) "
             "| position vs float64 (m, max) | velocity vs float64 (m/s, max) | heading error RMS (deg) "
             "| position error RMS (m) |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        lines.append(f"| {r['world']} | {r['build']} | {r['att_deg']:.2g} | {r['pos_m']:.2g} | {r['vel_mps']:.2g} "
                     f"| {r['heading_rms_deg']:.3g} | {r['pos_rms_m']:.3g} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--duration", type=float, default=3600.0, help="simulated seconds per run")
    ap.add_argument("--seed", type=int, default=10)
    ap.add_argument("--worlds", nargs="+", default=list(WORLDS), choices=list(WORLDS))
    args = ap.parse_args(argv)
    print(markdown(measure(args.duration, args.seed, args.worlds), args.duration))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
