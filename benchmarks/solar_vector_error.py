"""Solar-vector error of the camera + firmware solve, per frame, for a camera preset and a calibration source.

``python -m benchmarks.solar_vector_error [--preset reference|ideal] [--calibration residuals|perfect|nominal]
[--units N] [--frames F] [--paper-lens] [--uncorrected]``: N camera units (seeds: fixed pattern, calibration
residuals, noise), F frames each at random headings and tilts (+-10 deg) in Beijing at 08:14 UTC (sun elevation
23 deg), binned, 15 x 15 points; the firmware inverts with its calibration file (``firmware_model.psns``,
float32): the polarizer-angle correction (``--uncorrected`` skips it), the E-vectors through the calibrated lens,
the solve; ``--sky realistic`` the scenario default sky (built from the scenario's sky section, as a run builds it:
turbidity 3, neutral points 20 deg from the sun and the antisun) instead of the clear Rayleigh sky, ``--day`` one row
per hour of a day of sun elevations, ``--series`` the sky test (:func:`series`: static level units at a few
headings logged over a day; the local-level error's spread and correlation times, :func:`series_statistics`; D-5.33).
Prints the median and the 95th percentile of the angle between the solved and the true sun vector in the body frame
(deg), and of its azimuth and elevation parts in ENU
(:func:`emulator.recording.psns_error.azimuth_elevation_error`: the azimuth is what a heading inherits).
docs/sensors.md quotes its output.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import replace
from typing import Any

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


def _unit(preset: str, calibration: str, unit: int, paper_lens: bool, sky: str, epoch: str | None) -> Any:
    """One camera unit (its seed = ``unit``): the validated scenario, the world's camera and the firmware's camera."""
    scn = validate_scenario_data({**SCENARIO, "seed": unit, "sensors": {"camera": {"preset": preset}},
                                  "firmware": {"calibration": {"source": calibration}}, "sky": {"model": sky},
                                  **({"epoch": epoch} if epoch else {})}, {})
    cc = camera_config(scn, unit)
    cam = firmware_config(scn, calibration_for(scn, unit)).camera
    if paper_lens:  # the old shared contract: the paper's lens on both sides, no sensor defects
        cc = replace(cc, cx_px=None, cy_px=None, k1=0.0, k2=0.0, exit_pupil_m=None, defects=SensorDefects())
        cam = replace(cam, cx_px=None, cy_px=None, k1=0.0, k2=0.0, exit_pupil_m=None, c_c_b=cc.mounting_c_b)
    return scn, cc, cam


def solve_error(m: PolarizationCameraModel, cam: Any, traj: StaticTrajectory, sun: SunModel, t: float,
                uncorrected: bool = False) -> tuple[float, float, float, float] | None:
    """One frame at scenario time ``t`` (s) through the firmware's solve: the angle to the true sun (deg), the
    signed azimuth and elevation errors in ENU (deg, :func:`azimuth_elevation_error`) and the true sun elevation
    (deg); None when the solve is invalid."""
    obs = m.observe(t)
    aop, dop = obs.aop.astype(np.float32), obs.dop.astype(np.float32)
    if not uncorrected:
        aop, dop = psns.correct_polarizer(aop, dop, cam, dtype=np.float32)
    e = psns.evectors_camera(obs.x_px.astype(float), obs.y_px.astype(float), aop, cam, dtype=np.float32)
    sol = psns.solve_solar_vector(e, dop, 0.05)
    if not sol.valid:
        return None
    st = traj.state(t)
    s_n_true = sun.sun_enu(t, *st.pos)
    s_b = cam.c_c_b @ np.asarray(sol.s, dtype=np.float64)
    d_az, d_el = azimuth_elevation_error(st.c_bn @ s_b, s_n_true)
    el = math.degrees(math.asin(max(-1.0, min(1.0, float(s_n_true[2])))))
    return line_angle_deg(s_b, st.c_bn.T @ s_n_true), d_az, d_el, el


def errors(preset: str, calibration: str, units: int, frames: int, paper_lens: bool = False,
           uncorrected: bool = False, sky: str = "rayleigh", epoch: str | None = None) -> np.ndarray:
    """(frames, 3): the angle, |azimuth error| and |elevation error| of each valid solve, deg."""
    out = []
    for unit in range(units):
        scn, cc, cam = _unit(preset, calibration, unit, paper_lens, sky, epoch)
        rng = np.random.default_rng(1000 + unit)
        for _ in range(frames):
            hd, p, r = rng.uniform(0, 360), rng.uniform(-10, 10), rng.uniform(-10, 10)
            traj = StaticTrajectory(39.979, 116.339, 50.0, hd, p, r)
            sun = SunModel(scn.epoch, 69.0)
            m = PolarizationCameraModel(cc, sky_from_spec(scn.sky), sun, traj, rng)
            res = solve_error(m, cam, traj, sun, 0.0, uncorrected)
            if res is not None:
                out.append((res[0], abs(res[1]), abs(res[2])))
    return np.array(out).reshape(-1, 3)


#: the sky test's day: from 23:00 UTC (07:00 local) for 11 h, every ``--step-min`` minutes
SERIES_EPOCH = "2019-09-17T23:00:00Z"
SERIES_HOURS = 11.0


def series(preset: str, calibration: str, units: int, headings: list[float], step_min: float, sky: str,
           hours: float = SERIES_HOURS) -> np.ndarray:
    """The sky test as a team logs it: each of ``units`` static, level cameras at each heading (deg) looks at the sky
    from :data:`SERIES_EPOCH` for ``hours``, one frame every ``step_min`` minutes, and its solved sun is compared
    with the ephemeris through the reference attitude. Returns (units, headings, times, 2): the solar-vector error as
    a local-level rotation, across the sun's azimuth (``d_az cos(el)``, the sun's move across the solar meridian)
    and along it (``d_el``, a rotation about the horizontal axis across the meridian), deg; NaN where the solve is
    invalid or the sun is below 5 deg."""
    n_t = math.floor(hours * 60.0 / step_min + 1e-9) + 1
    out = np.full((units, len(headings), n_t, 2), np.nan)
    for unit in range(units):
        scn, cc, cam = _unit(preset, calibration, unit, False, sky, SERIES_EPOCH)
        sun = SunModel(scn.epoch, 69.0)
        for j, hd in enumerate(headings):
            traj = StaticTrajectory(39.979, 116.339, 50.0, hd, 0.0, 0.0)
            m = PolarizationCameraModel(cc, sky_from_spec(scn.sky), sun, traj,
                                        np.random.default_rng(1000 + 37 * unit + j))
            for k in range(n_t):
                res = solve_error(m, cam, traj, sun, k * step_min * 60.0)
                if res is not None and res[3] >= 5.0:
                    out[unit, j, k] = (res[1] * math.cos(math.radians(res[3])), res[2])
    return out


def series_statistics(err: np.ndarray, step_min: float, headings: list[float]) -> dict[str, np.ndarray]:
    """Statistics of :func:`series`' (units, headings, times, 2) errors (deg), per axis (across / along the meridian):

    * ``rms``, ``mean``, ``std`` over every valid frame (deg);
    * ``rho_time`` (lags, 2): the normalised lagged product ``sum e(t) e(t + L) / sqrt(sum e(t)^2 sum e(t + L)^2)``
      over every unit, heading and valid pair, about zero (the filter's Gauss-Markov is zero-mean: a sky error
      that stays is correlation, not a mean to remove), lag ``L`` = 1, 2, ... steps;
    * ``tau_slope_min``: the first-order Gauss-Markov's correlation time from the first lag,
      ``L / (1 - rho(L))`` (min): what sets ``Q`` over a short step; ``tau_e_min``: the first lag where
      ``rho <= 1/e`` (min; NaN if not reached within the day);
    * ``rho_heading``: the same product between the same unit's frames at the same time and different headings (the
      error that stays when a vehicle turns, in the local-level frame); ``rho_heading_sep`` (separations, 2) per
      heading separation ``heading_sep_deg``, and ``psi_slope_deg``: the turn angle of a Gauss-Markov in heading
      from the smallest separation, ``sep / (1 - rho(sep))`` (deg).
    """
    flat = err.reshape(-1, 2)
    ok = np.isfinite(flat[:, 0])
    v = flat[ok]
    stats: dict[str, np.ndarray] = {"rms": np.sqrt(np.mean(v ** 2, axis=0)), "mean": v.mean(axis=0),
                                    "std": v.std(axis=0), "frames": np.array([len(v), len(v)])}
    n_t = err.shape[2]
    rho = []
    for lag in range(1, n_t):
        a, b = err[:, :, :-lag].reshape(-1, 2), err[:, :, lag:].reshape(-1, 2)
        m = np.isfinite(a[:, 0]) & np.isfinite(b[:, 0])
        if m.sum() < 10:
            break
        rho.append(np.sum(a[m] * b[m], axis=0) / np.sqrt(np.sum(a[m] ** 2, axis=0) * np.sum(b[m] ** 2, axis=0)))
    r = np.array(rho).reshape(-1, 2)
    stats["rho_time"] = r
    stats["tau_slope_min"] = step_min / np.maximum(1.0 - r[0], 1e-9)
    tau_e = []
    for ax in range(2):
        below = np.nonzero(r[:, ax] <= math.exp(-1.0))[0]
        tau_e.append((below[0] + 1) * step_min if len(below) else math.nan)
    stats["tau_e_min"] = np.array(tau_e)
    sums: dict[float, np.ndarray] = {}  # heading separation (deg) -> [num, da, db] per axis
    for i in range(err.shape[1]):
        for j in range(i + 1, err.shape[1]):
            sep = abs((headings[j] - headings[i] + 180.0) % 360.0 - 180.0)
            a, b = err[:, i].reshape(-1, 2), err[:, j].reshape(-1, 2)
            m = np.isfinite(a[:, 0]) & np.isfinite(b[:, 0])
            acc = sums.setdefault(round(sep, 3), np.zeros((3, 2)))
            acc += (np.sum(a[m] * b[m], axis=0), np.sum(a[m] ** 2, axis=0), np.sum(b[m] ** 2, axis=0))
    tot = sum(sums.values(), np.zeros((3, 2)))
    stats["rho_heading"] = tot[0] / np.sqrt(tot[1] * tot[2])
    seps = sorted(sums)
    stats["heading_sep_deg"] = np.array(seps)
    stats["rho_heading_sep"] = np.array([sums[k][0] / np.sqrt(sums[k][1] * sums[k][2]) for k in seps]).reshape(-1, 2)
    if seps:
        # the turn angle over which a Gauss-Markov in heading would lose this much: sep / (1 - rho) at the smallest
        stats["psi_slope_deg"] = seps[0] / np.maximum(1.0 - stats["rho_heading_sep"][0], 1e-9)
    return stats


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
    ap.add_argument("--series", action="store_true",
                    help="the sky test: static level cameras logged over a day (see series()); prints the "
                         "local-level error's spread and correlation times")
    ap.add_argument("--headings", default="0,90,180,270", help="--series: headings (deg), comma-separated")
    ap.add_argument("--step-min", type=float, default=10.0, help="--series: minutes between logged frames")
    ap.add_argument("--hours", type=float, default=SERIES_HOURS, help="--series: hours logged from 23:00 UTC")
    a = ap.parse_args()
    if a.series:
        headings = [float(h) for h in a.headings.split(",")]
        err = series(a.preset, a.calibration, a.units, headings, a.step_min, a.sky, a.hours)
        stats = series_statistics(err, a.step_min, headings)
        print(f"sky test: preset={a.preset} calibration={a.calibration} sky={a.sky}, {a.units} units x headings "
              f"{a.headings} deg, level, one frame every {a.step_min:g} min from {SERIES_EPOCH} for {a.hours:g} h "
              f"(sun >= 5 deg), {int(stats['frames'][0])} valid frames")
        print("| local-level axis | rms (deg) | mean (deg) | std (deg) | rho at 1 / 3 / 6 steps "
              "| tau from the first lag (min) | tau at 1/e (min) | rho across headings |\n"
              "|---|---|---|---|---|---|---|---|")
        r = stats["rho_time"]
        for ax, name in enumerate(("across the meridian (d_az cos el)", "along it (d_el)")):
            lags = " / ".join(f"{r[i, ax]:.3f}" if i < len(r) else "-" for i in (0, 2, 5))
            print(f"| {name} | {stats['rms'][ax]:.3f} | {stats['mean'][ax]:+.3f} | {stats['std'][ax]:.3f} | {lags} "
                  f"| {stats['tau_slope_min'][ax]:.0f} | {stats['tau_e_min'][ax]:.0f} "
                  f"| {stats['rho_heading'][ax]:.3f} |")
        print("\n| heading separation (deg) | rho across the meridian | rho along it |\n|---|---|---|")
        for sep, rr in zip(stats["heading_sep_deg"], stats["rho_heading_sep"]):
            print(f"| {sep:g} | {rr[0]:.3f} | {rr[1]:.3f} |")
        if "psi_slope_deg" in stats:
            print(f"turn angle of a Gauss-Markov in heading (first separation): {stats['psi_slope_deg'][0]:.0f} / "
                  f"{stats['psi_slope_deg'][1]:.0f} deg (across / along)")
        t_h = np.arange(err.shape[2]) * a.step_min / 60.0
        print("\n| UTC hour from | frames | rms across (deg) | rms along (deg) |\n|---|---|---|---|")
        for h0 in range(math.ceil(a.hours)):
            sel = err[:, :, (t_h >= h0) & (t_h < h0 + 1)].reshape(-1, 2)
            sel = sel[np.isfinite(sel[:, 0])]
            if len(sel):
                rms = np.sqrt(np.mean(sel ** 2, axis=0))
                print(f"| {(23 + h0) % 24:02d}:00 | {len(sel)} | {rms[0]:.3f} | {rms[1]:.3f} |")
        return
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
