"""Solar-vector error of the camera + firmware solve, per frame, for a camera preset and a calibration source.

``python -m benchmarks.solar_vector_error [--preset reference|ideal] [--calibration residuals|perfect|nominal]
[--units N] [--frames F] [--paper-lens] [--uncorrected]``: N camera units (seeds: fixed pattern, calibration
residuals, noise), F frames each at random headings and tilts (+-10 deg) in Beijing at 08:14 UTC (sun elevation
23 deg), binned, 15 x 15 points; the firmware inverts with its calibration file (``firmware_model.psns``,
float32): the polarizer-angle correction (``--uncorrected`` skips it), the E-vectors through the calibrated lens,
the solve; ``--sky realistic`` the scenario default sky (built from the scenario's sky section, as a run builds it:
turbidity 3, neutral points 20 deg from the sun and the antisun) instead of the clear Rayleigh sky, ``--day`` one row
per hour of a day of sun elevations. Prints the median and the 95th percentile of the angle between the solved and
the true sun vector in the body frame (deg), and of its azimuth and elevation parts in ENU
(:func:`emulator.recording.psns_error.azimuth_elevation_error`: the azimuth is what a heading inherits).
docs/sensors.md quotes its output.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import replace

import numpy as np

from emulator.devices.camera import PolarizationCameraModel
from emulator.devices.camera.optics import SensorDefects
from emulator.devices.sensors import camera_config
from emulator.dsp.firmware_setup import calibration_for, firmware_config
from emulator.recording.psns_error import azimuth_elevation_error, line_angle_deg
from emulator.scenario.loader import validate_scenario_data
from emulator.world.sky import sky_from_spec
from emulator.world.sun import SunModel
from emulator.world.trajectory import StaticTrajectory
from firmware_model import psns

SCENARIO = {
    "name": "solar_vector_error", "epoch": "2019-09-18T08:14:00Z", "duration_s": 1,
    "origin": {"lat_deg": 39.979, "lon_deg": 116.339, "height_m": 50.0},
    "links": {"psns": {"url": "mem://psns", "baud": 115200}},
}


def errors(preset: str, calibration: str, units: int, frames: int, paper_lens: bool = False,
           uncorrected: bool = False, sky: str = "rayleigh", epoch: str | None = None) -> np.ndarray:
    """(frames, 3): the angle, |azimuth error| and |elevation error| of each valid solve, deg."""
    out = []
    for unit in range(units):
        scn = validate_scenario_data({**SCENARIO, "seed": unit, "sensors": {"camera": {"preset": preset}},
                                      "firmware": {"calibration": {"source": calibration}}, "sky": {"model": sky},
                                      **({"epoch": epoch} if epoch else {})}, {})
        cc = camera_config(scn, unit)
        cam = firmware_config(scn, calibration_for(scn, unit)).camera
        if paper_lens:  # the old shared contract: the paper's lens on both sides, no sensor defects
            cc = replace(cc, cx_px=None, cy_px=None, k1=0.0, k2=0.0, exit_pupil_m=None, defects=SensorDefects())
            cam = replace(cam, cx_px=None, cy_px=None, k1=0.0, k2=0.0, exit_pupil_m=None, c_c_b=cc.mounting_c_b)
        rng = np.random.default_rng(1000 + unit)
        for _ in range(frames):
            hd, p, r = rng.uniform(0, 360), rng.uniform(-10, 10), rng.uniform(-10, 10)
            traj = StaticTrajectory(39.979, 116.339, 50.0, hd, p, r)
            sun = SunModel(scn.epoch, 69.0)
            m = PolarizationCameraModel(cc, sky_from_spec(scn.sky), sun, traj, rng)
            obs = m.observe(0.0)
            aop, dop = obs.aop.astype(np.float32), obs.dop.astype(np.float32)
            if not uncorrected:
                aop, dop = psns.correct_polarizer(aop, dop, cam, dtype=np.float32)
            e = psns.evectors_camera(obs.x_px.astype(float), obs.y_px.astype(float), aop, cam, dtype=np.float32)
            sol = psns.solve_solar_vector(e, dop, 0.05)
            if not sol.valid:
                continue
            st = traj.state(0.0)
            s_n_true = sun.sun_enu(0.0, *st.pos)
            s_b_true = st.c_bn.T @ s_n_true
            s_b = cam.c_c_b @ np.asarray(sol.s, dtype=np.float64)
            d_az, d_el = azimuth_elevation_error(st.c_bn @ s_b, s_n_true)
            out.append((line_angle_deg(s_b, s_b_true), abs(d_az), abs(d_el)))
    return np.array(out).reshape(-1, 3)


def _stats(x: np.ndarray, sep: str = " / ") -> str:
    return f"{np.median(x):.3f}{sep}{np.percentile(x, 95):.3f}"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--preset", default="reference")
    ap.add_argument("--calibration", default="residuals", choices=["residuals", "perfect", "nominal"])
    ap.add_argument("--units", type=int, default=10)
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--paper-lens", action="store_true", help="the old shared contract (paper lens, no defects)")
    ap.add_argument("--uncorrected", action="store_true",
                    help="skip the firmware's polarizer-angle correction (the AOP as the camera sends it)")
    ap.add_argument("--sky", default="rayleigh", choices=["rayleigh", "realistic", "berry"],
                    help="the world's sky (realistic: the scenario default, Preetham turbidity 3)")
    ap.add_argument("--day", action="store_true",
                    help="a day of sun elevations: one row per UTC hour 23:00-10:00 (Beijing 07-18 h local)")
    a = ap.parse_args()
    if a.day:
        print(f"preset={a.preset} calibration={a.calibration} sky={a.sky}, Beijing 2019-09-18")
        print("| UTC | sun elevation (deg) | frames | median (deg) | p95 (deg) | azimuth median / p95 (deg) "
              "| elevation median / p95 (deg) |\n|---|---|---|---|---|---|---|")
        for hour in (23, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10):
            day = "2019-09-17" if hour == 23 else "2019-09-18"
            ep = f"{day}T{hour:02d}:00:00Z"
            scn = validate_scenario_data({**SCENARIO, "seed": 0, "epoch": ep}, {})
            st = StaticTrajectory(39.979, 116.339, 50.0).state(0.0)
            el = math.degrees(math.asin(float(SunModel(scn.epoch, 69.0).sun_enu(0.0, *st.pos)[2])))
            e = errors(a.preset, a.calibration, a.units, a.frames, a.paper_lens, a.uncorrected, a.sky, ep)
            if len(e):
                print(f"| {hour:02d}:00 | {el:.1f} | {len(e)} | {_stats(e[:, 0], ' | ')} | {_stats(e[:, 1])} "
                      f"| {_stats(e[:, 2])} |", flush=True)
            else:
                print(f"| {hour:02d}:00 | {el:.1f} | 0 | - | - | - | - |")
        return
    e = errors(a.preset, a.calibration, a.units, a.frames, a.paper_lens, a.uncorrected, a.sky)
    print(f"preset={a.preset} calibration={a.calibration} sky={a.sky} paper_lens={a.paper_lens} "
          f"uncorrected={a.uncorrected} frames={len(e)}: median {np.median(e[:, 0]):.3f} deg, "
          f"p95 {np.percentile(e[:, 0], 95):.3f} deg; azimuth {_stats(e[:, 1])}, elevation {_stats(e[:, 2])} deg "
          "(median / p95)")


if __name__ == "__main__":
    main()
