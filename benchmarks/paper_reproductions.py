"""Like-for-like reproductions of the variants' papers (issue 15 item 4, issue 36 item 5): one function per paper.

    python benchmarks/paper_reproductions.py zhang [--seeds 1-10] [--skies rayleigh,realistic,envelope] [--json F]
    python benchmarks/paper_reproductions.py ge    [--seeds 1-10] [--figures paper|field] [--json F]
    python benchmarks/paper_reproductions.py yang  [--seeds 1-10] [--sky realistic|rayleigh] [--json F]
    python benchmarks/paper_reproductions.py PAPER --merge F1 [F2 ...]     # the table of stored members, no runs

Every member runs the library scenario in fast mode with the run seed (``seed`` of the scenario replaced), one after
the other on one core; ``--json`` writes the members after every seed (a stopped run keeps what it measured). The
tables of docs/variants.md section 6 are ``--merge`` outputs of the files in ``benchmarks/paper_results/``, each
giving the median and inter-quartile range over the seeds beside the paper's one run (D-6.11);
``tests/benchmarks/test_paper_reproductions.py`` prints them again and compares them with the page.

* :func:`zhang`: ``scenarios/sun_elevation_paper_like_for_like.yaml`` (Zhang et al. 2021, Table 1 sensors, Table 2
  compass residuals, GNSS for the initial fix only): pure SINS once per seed and the sun-elevation filter under each
  sky of :data:`ZHANG_SKIES`; latitude / longitude MAE over the 20 GNSS-free minutes, the change against pure SINS and
  the error along / across the Sun's azimuth, next to the paper's 0.058 / 0.009 deg and -59.4 % / -98.1 %.
* :func:`ge`: ``scenarios/federated_paper_comparison.yaml`` under the paper's figures (:data:`GE_PAPER`) or the
  ``field`` presets, the master fusing both sub-filters, polarization/MIMU only and SINS/GNSS only, on the same stream
  (``subfilters``): heading RMS / max and how many seeds keep the paper's ordering fused < pol/MIMU < SINS/GNSS.
* :func:`yang`: ``scenarios/kmeans_field_tilt_series.yaml`` (realistic or Rayleigh sky, the ``field`` camera, a
  magnetometer with hard and soft iron the firmware does not know): the single K-means fixes (``kmeans_fix`` events)
  against the truth at their exposure, beside the paper's field table (RMS 0.23 / 0.43 deg), and the navigation
  output's pitch / roll error apart.
"""

from __future__ import annotations

import argparse
import csv
import json
import math
import statistics
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from protocols.constants import DEG

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from emulator.numeric_baseline import pin, pinned  # noqa: E402

pin()  # before numpy loads: the arithmetic of psns-hil and of the tests (emulator.numeric_baseline)

from emulator.assembly.session import run_scenario  # noqa: E402
from emulator.testing import load_test_scenario  # noqa: E402

SCENARIOS = ROOT / "scenarios"
#: WGS-84
_A, _E2 = 6378137.0, 6.69437999014e-3

#: Zhang et al. 2021 (Sensors 21:1055), section 4.2 / Figs. 12-13: MAE of the SINS/PNS model and its reduction
#: against their SINS model
ZHANG_PAPER = {"lat_mae_deg": 0.058, "lon_mae_deg": 0.009, "lat_change": -0.594, "lon_change": -0.981}
#: Yang et al. 2020 field table (pitch / roll RMS, deg)
YANG_PAPER = {"pitch_rms_deg": 0.23, "roll_rms_deg": 0.43}


#: where the members are written after every seed (``--json``), so that a stopped run keeps what it measured
CHECKPOINT: Path | None = None


def numerics() -> str:
    """``baseline`` when this process runs the pinned numeric baseline (:mod:`emulator.numeric_baseline`, as the
    tests and ``psns-hil`` do), else ``native`` (the machine's own kernels: the last bits differ)."""
    return "baseline" if pinned() else "native"


def _checkpoint(seeds: list[int], per: list[dict[str, Any]]) -> None:
    if CHECKPOINT is not None:
        CHECKPOINT.write_text(json.dumps({"seeds": seeds, "members": per, "numerics": numerics()}, indent=1))


def parse_seeds(text: str) -> list[int]:
    """``"1-10"`` or ``"1,4,7"`` -> seeds."""
    out: list[int] = []
    for part in text.split(","):
        if "-" in part:
            a, b = part.split("-", 1)
            out.extend(range(int(a), int(b) + 1))
        elif part.strip():
            out.append(int(part))
    return out


def parse_overrides(items: list[str]) -> dict[str, Any]:
    """``--set KEY=JSON`` items -> dotted scenario overrides (values parsed as JSON)."""
    return {k: json.loads(v) for k, v in (x.split("=", 1) for x in items)}


def run_nav(name: str, seed: int, overrides: dict[str, Any]) -> tuple[dict, list[dict], list[dict]]:
    """Run ``scenarios/<name>.yaml`` with ``seed`` and dotted ``overrides``: (summary, nav rows, firmware events)."""
    scn = load_test_scenario(SCENARIOS / f"{name}.yaml", {"seed": seed, "expectations": [], **overrides})
    with tempfile.TemporaryDirectory(prefix="paper-") as tmp:
        run_dir = Path(tmp) / name
        summary = run_scenario(scn, run_dir, mode="fast", seed=seed)
        with open(run_dir / "nav.csv", newline="") as f:
            rows = list(csv.DictReader(f))
        events = [json.loads(line) for line in (run_dir / "events.jsonl").read_text().splitlines() if line.strip()]
    return summary, rows, [e for e in events if e.get("source") == "firmware"]


def _f(r: dict, k: str) -> float | None:
    v = r.get(k, "")
    return float(v) if v not in ("", None) else None


def degrees_of_position(lat_deg: float, height_m: float) -> tuple[float, float]:
    """Metres per degree of latitude and of longitude on WGS-84 at ``lat_deg``."""
    s = math.sin(lat_deg * DEG)
    w = math.sqrt(1.0 - _E2 * s * s)
    m = _A * (1.0 - _E2) / w**3
    n = _A / w
    return (m + height_m) * DEG, (n + height_m) * math.cos(lat_deg * DEG) * DEG


def _stats(xs: list[float]) -> tuple[float, float, float]:
    return statistics.fmean(xs), min(xs), max(xs)


def _fmt(xs: list[float], digits: int = 3, scale: float = 1.0) -> str:
    m, lo, hi = _stats([x * scale for x in xs])
    return f"{m:.{digits}f} ({lo:.{digits}f} .. {hi:.{digits}f})"


# -------------------------------------------------------------------------------------------------------- Zhang
#: the paper's pure SINS at the end of its 20 minutes (section 4.2: longitude 116.339 -> 114.903 deg, latitude
#: 39.979 -> 39.411 deg), and its sun-elevation filter's largest excursions (116.339 -> 116.304, 39.979 -> 39.868)
ZHANG_PAPER_SINS_END_DEG = (-1.436, -0.568)  # (longitude, latitude) error, deg
ZHANG_PAPER_SE_MAX_DEG = (-0.035, -0.111)
#: the like-for-like scenario's start (its epoch) and the paper's test start, 16:14 Beijing time
ZHANG_EPOCH = "2019-09-18T08:13:50+00:00"
#: "paper-like" pure-SINS drift: its end point's line within this angle of the paper's (13 deg to the left of the
#: Sun's azimuth line, :func:`zhang_paper_drift`; a drift and its opposite are equally likely draws of the same
#: errors). About the paper's own angle off the azimuth line: the subset's drift is as much along the azimuth as the
#: paper's, with its across part on the same side, so that, as in the paper, the along and across parts of the
#: latitude error add (on the other side they cancel and pure SINS's latitude error is small; docs/variants.md 6.4)
ZHANG_PAPER_LIKE_DEG = 15.0


def sun_azimuth_rad(t_s: float, lat_deg: float = 39.979, lon_deg: float = 116.339) -> float:
    """The Sun's azimuth (rad, clockwise from North) ``t_s`` seconds after :data:`ZHANG_EPOCH` at the test site."""
    import datetime as dt

    from firmware_model.sun import grena_days_from_datetime, sun_az_el

    t = dt.datetime.fromisoformat(ZHANG_EPOCH) + dt.timedelta(seconds=t_s)
    return sun_az_el(grena_days_from_datetime(t), lat_deg * DEG, lon_deg * DEG)[0]


def along_across(e_m: float, n_m: float, az: float) -> tuple[float, float]:
    """A horizontal error (E, N, m) as its components along the Sun's azimuth (the direction one sun elevation
    observes) and across it (to the right of the azimuth, unobserved), m."""
    sa, ca = math.sin(az), math.cos(az)
    return e_m * sa + n_m * ca, e_m * ca - n_m * sa


def drift_off_azimuth_deg(along_m: float, across_m: float) -> float:
    """Angle (deg, 0..90) between a horizontal error and the line of the Sun's azimuth."""
    return math.degrees(math.atan2(abs(across_m), abs(along_m)))


def drift_line_deg(along_m: float, across_m: float) -> float:
    """The line of a horizontal error against the Sun's azimuth line (deg, -90..90, positive to the right): the
    direction with its sign folded (an error and its opposite lie on one line)."""
    a = math.degrees(math.atan2(across_m, along_m))
    return (a + 90.0) % 180.0 - 90.0


def line_separation_deg(a_deg: float, b_deg: float) -> float:
    """Angle (deg, 0..90) between two lines given as :func:`drift_line_deg`."""
    d = abs(a_deg - b_deg) % 180.0
    return min(d, 180.0 - d)


def zhang_paper_drift() -> dict[str, float]:
    """The paper's pure-SINS end point and its sun-elevation filter's largest excursion along / across the Sun's
    azimuth (km) and the SINS drift's angle off the azimuth line (deg), from the figures of section 4.2."""
    m_lat, m_lon = degrees_of_position(39.979, 50.0)
    az = sun_azimuth_rad(1200.0)
    a, c = along_across(ZHANG_PAPER_SINS_END_DEG[0] * m_lon, ZHANG_PAPER_SINS_END_DEG[1] * m_lat, az)
    sa, sc = along_across(ZHANG_PAPER_SE_MAX_DEG[0] * m_lon, ZHANG_PAPER_SE_MAX_DEG[1] * m_lat, az)
    return {"sins_along_km": a / 1e3, "sins_across_km": c / 1e3, "sins_off_azimuth_deg": drift_off_azimuth_deg(a, c),
            "sins_line_deg": drift_line_deg(a, c), "se_along_km": sa / 1e3, "se_across_km": sc / 1e3}


def zhang_paper_like(row: dict[str, Any]) -> bool:
    """Whether a member's pure SINS ended on a line within :data:`ZHANG_PAPER_LIKE_DEG` of the paper's."""
    ins = row["sins"]
    line = drift_line_deg(ins["end_along_km"], ins["end_across_km"])
    return line_separation_deg(line, zhang_paper_drift()["sins_line_deg"]) <= ZHANG_PAPER_LIKE_DEG


def zhang_member(seed: int, elevation_update: bool, after_s: float = 10.0,
                 overrides: dict[str, Any] | None = None) -> dict[str, float]:
    """One member: latitude / longitude MAE (deg) over the GNSS-free part, sampled at 1 Hz; the same error along and
    across the Sun's azimuth (MAE, km) and the end point's angle off the azimuth line (deg). ``overrides``: dotted
    scenario keys for an attribution run (e.g. ``sensors.compass.aop_offset_deg``)."""
    name = "sun_elevation_paper_like_for_like"
    summary, nav, _ev = run_nav(name, seed, {**(overrides or {}),
                                             "firmware.variants.sun_elevation.elevation_update": elevation_update})
    m_lat, m_lon = degrees_of_position(39.979, 50.0)
    lat, lon, along, across, last = [], [], [], [], -1.0
    end = (0.0, 0.0)
    for r in nav:
        t = float(r["time_s"])
        n, e = _f(r, "err_pos_n_m"), _f(r, "err_pos_e_m")
        if t < after_s or n is None or e is None or t - last < 1.0 - 1e-6:
            continue
        last = t
        lat.append(abs(n) / m_lat)
        lon.append(abs(e) / m_lon)
        end = along_across(e, n, sun_azimuth_rad(t))
        along.append(abs(end[0]) / 1e3)
        across.append(abs(end[1]) / 1e3)
    return {"lat_mae_deg": statistics.fmean(lat), "lon_mae_deg": statistics.fmean(lon),
            "lat_max_deg": max(lat), "lon_max_deg": max(lon), "samples": len(lat),
            "along_mae_km": statistics.fmean(along), "across_mae_km": statistics.fmean(across),
            "end_along_km": end[0] / 1e3, "end_across_km": end[1] / 1e3,
            "end_off_azimuth_deg": drift_off_azimuth_deg(*end), **_envelope_of(summary)}


def _envelope_of(summary: dict[str, Any]) -> dict[str, Any]:
    """``{"envelope": the drawn values as flat columns}`` of a run drawn from an envelope, else ``{}``."""
    env = summary.get("envelope")
    if not env:
        return {}
    from emulator.world.envelope import flat_draws

    return {"envelope": flat_draws(env.get("draws") or {})}


def merge_zhang(members: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Members of several ``zhang --json`` files joined by seed (each file may carry other skies of the same seeds);
    a seed's pure SINS must be the same in every file (the run is deterministic), else ValueError."""
    by: dict[int, dict[str, Any]] = {}
    for m in members:
        r = by.setdefault(m["seed"], {"seed": m["seed"], "sins": m["sins"], "se": {}})
        if r["sins"] != m["sins"]:
            raise ValueError(f"seed {m['seed']}: the pure-SINS members of the merged files differ")
        r["se"].update(m["se"])
    return [by[k] for k in sorted(by)]


#: the skies of the Zhang comparison (scenario overrides on top of the like-for-like file): ``rayleigh`` the file's
#: own (clear single scattering, the sky the firmware's compass model inverts exactly), ``realistic`` the emulator's
#: default sky, ``envelope`` the published sky envelope (docs/sensors.md "The envelope": neutral points 10-30 deg from
#: the sun, turbidity 2-6, aerosol, thin cloud), only its ``sky`` group: the paper's own sensors stay (Table 1), the
#: condition is drawn (D-6.11)
ZHANG_SKIES: dict[str, dict[str, Any]] = {
    "rayleigh": {},
    "realistic": {"sky": {"model": "realistic"}},
    "envelope": {"sky": {"model": "realistic"}, "envelope": {"preset": "published", "groups": ["sky"]}},
}


def zhang(seeds: list[int], log: Callable[[str], None] = print, overrides: dict[str, Any] | None = None,
          skies: list[str] | None = None, sins: dict[int, dict[str, Any]] | None = None) -> dict[str, Any]:
    """Zhang et al. like for like: per seed pure SINS once (its world without the update: no sky reaches it) and the
    sun-elevation filter under each of ``skies`` (:data:`ZHANG_SKIES`, default all three). ``sins``: pure-SINS members
    by seed already run (``--sins-from``), taken instead of running them again."""
    skies = list(ZHANG_SKIES) if skies is None else skies
    per: list[dict[str, Any]] = []
    for seed in seeds:
        t0 = time.monotonic()
        ins = sins[seed] if sins and seed in sins else zhang_member(seed, False, overrides=overrides)
        row: dict[str, Any] = {"seed": seed, "sins": ins, "se": {}}
        for sky in skies:
            se = zhang_member(seed, True, overrides={**ZHANG_SKIES[sky], **(overrides or {})})
            se["lat_change"] = se["lat_mae_deg"] / ins["lat_mae_deg"] - 1.0
            se["lon_change"] = se["lon_mae_deg"] / ins["lon_mae_deg"] - 1.0
            row["se"][sky] = se
            log(f"seed {seed} {sky}: SE lat/lon MAE {se['lat_mae_deg']:.4f}/{se['lon_mae_deg']:.4f} deg, SINS "
                f"{ins['lat_mae_deg']:.4f}/{ins['lon_mae_deg']:.4f} deg, change {se['lat_change']:+.0%}/"
                f"{se['lon_change']:+.0%}; along/across MAE SE {se['along_mae_km']:.1f}/{se['across_mae_km']:.1f} "
                f"km, SINS {ins['along_mae_km']:.1f}/{ins['across_mae_km']:.1f} km")
        per.append(row)
        _checkpoint(seeds, per)
        log(f"seed {seed}: SINS drift {ins['end_off_azimuth_deg']:.0f} deg off the azimuth "
            f"({time.monotonic() - t0:.0f} s)")
    return {"seeds": seeds, "members": per, "markdown": zhang_table(per)}


def quartiles(xs: list[float]) -> tuple[float, float, float]:
    """(first quartile, median, third quartile) of ``xs``, linear interpolation between order statistics
    (``statistics.quantiles(method="inclusive")``, numpy's default)."""
    if len(xs) == 1:
        return xs[0], xs[0], xs[0]
    q1, q2, q3 = statistics.quantiles(xs, n=4, method="inclusive")
    return q1, q2, q3


def _med(xs: list[float], digits: int = 3, scale: float = 1.0) -> str:
    """``median [q1 .. q3]`` of ``xs`` times ``scale``."""
    if not xs:
        return "-"
    q1, q2, q3 = quartiles([x * scale for x in xs])
    return f"{q2:.{digits}f} [{q1:.{digits}f} .. {q3:.{digits}f}]"


def _both_fall(se: dict[str, Any]) -> bool:
    return bool(se["lat_change"] < 0 and se["lon_change"] < 0)


def _equals_sins(se: dict[str, Any], sins: dict[str, Any]) -> bool:
    """Whether a sun-elevation member's error is pure SINS's to the last bit (its update never changed the state:
    the mode manager's chi-square gate refused every fix; traced on seed 10 of the envelope sky)."""
    return all(se[k] == sins[k] for k in ("lat_mae_deg", "lon_mae_deg", "along_mae_km", "across_mae_km"))


def zhang_table(per: list[dict[str, Any]]) -> str:
    """The Markdown table: median [inter-quartile range] over the seeds of pure SINS and of the sun-elevation filter
    under each sky the members carry, beside the paper's one run."""
    per = sorted(per, key=lambda r: r["seed"])
    skies = [s for s in ZHANG_SKIES if any(s in r["se"] for r in per)]
    like = [r for r in per if zhang_paper_like(r)]
    pd = zhang_paper_drift()

    def row(label: str, sins: str, f: Callable[[dict[str, Any]], float], digits: int, scale: float, paper: str,
            members: list[dict[str, Any]] | None = None) -> str:
        ms = per if members is None else members
        cells = [_med([f(r["se"][s]) for r in ms if s in r["se"]], digits, scale) for s in skies]
        return f"| {label} | {sins} | " + " | ".join(cells) + f" | {paper} |"

    n_sky = {s: sum(1 for r in per if s in r["se"]) for s in skies}
    sins = lambda k, d=4, sc=1.0, ms=None: _med([r["sins"][k] for r in (per if ms is None else ms)], d, sc)  # noqa: E731
    head = (f"| median [inter-quartile range] over the seeds | pure SINS ({len(per)} seeds) | "
            + " | ".join(f"sun elevation, {s} sky ({n_sky[s]} seeds)" for s in skies) + " | paper (one run) |")
    lines = [head, "|---|---|" + "---|" * len(skies) + "---|",
             row("latitude MAE (deg)", sins("lat_mae_deg"), lambda m: m["lat_mae_deg"], 4, 1.0, "0.058 (SINS 0.143)"),
             row("longitude MAE (deg)", sins("lon_mae_deg"), lambda m: m["lon_mae_deg"], 4, 1.0, "0.009 (SINS 0.47)"),
             row("latitude change against pure SINS (%)", "", lambda m: m["lat_change"], 0, 100.0, "-59.4"),
             row("longitude change against pure SINS (%)", "", lambda m: m["lon_change"], 0, 100.0, "-98.1"),
             row("MAE along the Sun's azimuth (km)", sins("along_mae_km", 1), lambda m: m["along_mae_km"], 1, 1.0,
                 f"(SINS end {abs(pd['sins_along_km']):.0f})"),
             row("MAE across the Sun's azimuth (km)", sins("across_mae_km", 1), lambda m: m["across_mae_km"], 1, 1.0,
                 f"(SINS end {abs(pd['sins_across_km']):.0f})"),
             "| seeds where both MAE fall | | " + " | ".join(
                 f"{sum(1 for r in per if s in r['se'] and _both_fall(r['se'][s]))} of {n_sky[s]}" for s in skies)
             + " | |",
             "| seeds where the error equals pure SINS's (no fix let in) | | " + " | ".join(
                 f"{sum(1 for r in per if s in r['se'] and _equals_sins(r['se'][s], r['sins']))} of {n_sky[s]}"
                 for s in skies) + " | |",
             f"| pure SINS at 20 min, angle off the Sun's azimuth line (deg) | {sins('end_off_azimuth_deg', 0)} | "
             + " | " * (len(skies) - 1) + f" | {pd['sins_off_azimuth_deg']:.0f} |"]
    if like:
        tag = f"seeds like the paper's draw ({len(like)}: pure SINS within {ZHANG_PAPER_LIKE_DEG:.0f} deg of its line)"
        lines += [row(f"{tag}: latitude change (%)", "", lambda m: m["lat_change"], 0, 100.0, "-59.4", like),
                  row(f"{tag}: longitude change (%)", "", lambda m: m["lon_change"], 0, 100.0, "-98.1", like)]
    return "\n".join(lines)


#: Ge et al. under the ``field`` presets: the library scenario's motion, alignment and filter; the world's sensors
#: and sky are the field suite's (the paper's figure overrides dropped) and the firmware's spec sheet is ``field``
GE_FIELD: dict[str, Any] = {
    "sensors.preset": "field",
    "sensors.imu": {"preset": "field"},
    "sensors.gnss": {"preset": "field", "sentences": [], "ubx": ["NAV-PVT"],
                     "glitches": [{"start_s": 200.0, "duration_s": 5.0, "offset_enu_m": [50.0, -30.0, 10.0]}]},
    # the field scenarios' camera grid: under the realistic sky 5 x 5 points leave fewer than the camera's 10
    # valid ones (every frame invalid, heading from the configuration: 30 deg off, seed 1)
    "sensors.camera": {"preset": "reference", "fidelity": "binned", "grid": [15, 15], "rate_hz": 5},
    "sky": {"model": "realistic"},
    "firmware.spec_sheet": "field",
    # the solar vector's noise floor from the field sheet too (the library scenario pins the paper's 0.01 rad)
    "firmware.psns.sigma_deg": None,
}
GE_CONFIGS = {"fused": ["sins_gnss", "pol_mimu"], "pol_mimu": ["pol_mimu"], "sins_gnss": ["sins_gnss"]}
#: Ge et al.'s own simulation conditions (section 3 (1)-(2): gyro drift 25 deg/h, accelerometer bias 800 ug, GPS 2.5 m
#: and 0.1 m/s, gyro noise 20 deg/h, accelerometer noise 600 ug, polarization noise 0.01, initial misalignment (-0.9,
#: 0.6, 0.7) deg, 400 s static and a 300 s half circle, a Rayleigh sky) are the library scenario as written; their
#: Figs. 5/6 compare the configurations without a GNSS fault, so the scenario's glitch at 200 s is taken out
GE_PAPER: dict[str, Any] = {"sensors.gnss.glitches": []}
GE_FIGURES = {"paper": GE_PAPER, "field": GE_FIELD}


def ge_overrides(subfilters: list[str], overrides: dict[str, Any] | None = None,
                 figures: str = "field") -> dict[str, Any]:
    """The scenario overrides of one Ge member: the ``figures`` (:data:`GE_FIGURES`), its sub-filters, then
    ``overrides`` (dotted keys)."""
    return {**GE_FIGURES[figures], "firmware.variants.federated.subfilters": subfilters, **(overrides or {})}


def ge_member(seed: int, subfilters: list[str], after_s: float = 20.0, figures: str = "field") -> dict[str, float]:
    """One member of ``federated_paper_comparison`` under ``figures``: heading RMS / max after ``after_s``."""
    over = ge_overrides(subfilters, figures=figures)
    _s, nav, _ev = run_nav("federated_paper_comparison", seed, over)
    h = [v for r in nav if float(r["time_s"]) >= after_s and (v := _f(r, "err_heading_deg")) is not None]
    return {"heading_rms_deg": _rms(h), "heading_max_deg": max(abs(x) for x in h), "samples": len(h)}


def ge(seeds: list[int], log: Callable[[str], None] = print, figures: str = "field") -> dict[str, Any]:
    """Ge et al.: the three configurations on each seed's stream; does fused < pol/MIMU < SINS/GNSS hold?"""
    per: list[dict[str, Any]] = []
    for seed in seeds:
        t0 = time.monotonic()
        row: dict[str, Any] = {"seed": seed, "figures": figures}
        for cfg, subs in GE_CONFIGS.items():
            row[cfg] = ge_member(seed, subs, figures=figures)
        f, p, g = (row[c]["heading_rms_deg"] for c in GE_CONFIGS)
        row["ordered"] = f < p < g
        per.append(row)
        _checkpoint(seeds, per)
        log(f"seed {seed}: heading RMS fused {f:.3f}, pol/MIMU {p:.3f}, SINS/GNSS {g:.3f} deg, ordered "
            f"{row['ordered']} ({time.monotonic() - t0:.0f} s)")
    return {"seeds": seeds, "members": per, "markdown": ge_table(per)}


def ge_table(per: list[dict[str, Any]]) -> str:
    """The Markdown table of one set of figures: median [inter-quartile range] over the seeds per configuration, and
    the seeds that keep the paper's ordering (its Figs. 5/6 give the ordering, no figure)."""
    n = len(per)
    figures = "/".join(sorted({r.get("figures", "field") for r in per}))
    lines = [f"| heading error after 20 s, deg ({figures} figures, {n} seeds: median [inter-quartile range]) | "
             "fused (three-way) | pol/MIMU | SINS/GNSS |", "|---|---|---|---|"]
    for stat in ("heading_rms_deg", "heading_max_deg"):
        cells = [_med([r[c][stat] for r in per], 3) for c in GE_CONFIGS]
        lines.append(f"| {stat.split('_')[1].upper()} | " + " | ".join(cells) + " |")
    fp = sum(1 for r in per if r["fused"]["heading_rms_deg"] < r["pol_mimu"]["heading_rms_deg"])
    pg = sum(1 for r in per if r["pol_mimu"]["heading_rms_deg"] < r["sins_gnss"]["heading_rms_deg"])
    lines.append(f"| seeds with fused < pol/MIMU; pol/MIMU < SINS/GNSS; both (RMS) | {fp} of {n} | {pg} of {n} | "
                 f"{sum(1 for r in per if r['ordered'])} of {n} |")
    lines.append("| paper (Figs. 5/6, no figure given) | best | second | worst (heading unobservable at rest) |")
    return "\n".join(lines)


def _rms(xs: list[float]) -> float:
    return math.sqrt(statistics.fmean([x * x for x in xs]))


#: the Yang member's scenario and the override that makes the variant log every fix it solves (``kmeans_fix``)
YANG_SCENARIO = "kmeans_field_tilt_series"
YANG_FIX_EVENTS = {"firmware.variants.kmeans_3d.fix_events": True}


def _wrap_deg(x: float) -> float:
    return (x + 180.0) % 360.0 - 180.0


def fix_errors(fixes: list[dict[str, Any]], scn: Any) -> list[dict[str, float]]:
    """Each ``kmeans_fix`` event against the truth at its exposure time (``t_meas_us``; the scenario's trajectory,
    the clock the nav frames' truth is taken at): pitch, roll and heading error, deg."""
    from emulator.world.build import build_trajectory

    times = [e["t_meas_us"] * 1e-6 for e in fixes]
    states = build_trajectory(scn).states(times)
    return [{"t_s": t, "pitch": _wrap_deg(e["pitch_deg"] - st.pitch / DEG),
             "roll": _wrap_deg(e["roll_deg"] - st.roll / DEG),
             "heading": _wrap_deg(e["heading_deg"] - st.heading / DEG)} for t, e, st in zip(times, fixes, states)]


def yang_member(seed: int, after_s: float = 25.0, sky: str = "realistic") -> dict[str, Any]:
    """One member of ``kmeans_field_tilt_series``: the single K-means fixes against the truth at their exposure
    (the paper's field table is of single fixes) and, apart, the pitch / roll error of the navigation output (the
    IMU/GNSS filter weighing the fixes), after the alignment; the fixes answered / refused (with the refusal reasons);
    ``sky`` rayleigh isolates the magnetometer's iron."""
    over = {**YANG_FIX_EVENTS, **({} if sky == "realistic" else {"sky": {"model": sky}})}
    summary, nav, ev = run_nav(YANG_SCENARIO, seed, over)
    rows = [r for r in nav if float(r["time_s"]) >= after_s and _f(r, "err_pitch_deg") is not None]
    pitch = [float(r["err_pitch_deg"]) for r in rows]
    roll = [float(r["err_roll_deg"]) for r in rows]
    head = [float(r["err_heading_deg"]) for r in rows]
    scn = load_test_scenario(SCENARIOS / f"{YANG_SCENARIO}.yaml", {"seed": seed, "expectations": [], **over})
    fx = fix_errors([e for e in ev if e.get("event") == "kmeans_fix" and e["t_meas_s"] >= after_s], scn)
    # every camera frame's decision is counted (the events are logged on a change only), over the whole run
    counters = summary.get("firmware", {}).get("counters", {})
    solved, refused = int(counters.get("camera_admitted", 0)), int(counters.get("camera_rejected", 0))
    reasons: dict[str, int] = {}
    for e in ev:  # the reasons the refusals changed to after the alignment
        if e.get("event") == "kmeans_refused" and e["t_fpga_s"] >= after_s:
            reasons[e["reason"]] = reasons.get(e["reason"], 0) + 1
    out: dict[str, Any] = {
        "pitch_rms_deg": _rms(pitch), "roll_rms_deg": _rms(roll), "pitch_max_deg": max(map(abs, pitch)),
        "roll_max_deg": max(map(abs, roll)), "heading_rms_deg": _rms(head), "solved": solved,
        "refused": refused, "refusals": reasons, "fixes": len(fx)}
    for k in ("pitch", "roll", "heading"):
        xs = [f[k] for f in fx]
        out[f"fix_{k}_rms_deg"] = _rms(xs) if xs else math.nan
        out[f"fix_{k}_max_deg"] = max(map(abs, xs)) if xs else math.nan
        out[f"fix_{k}_mean_deg"] = statistics.fmean(xs) if xs else math.nan
    return out


def yang(seeds: list[int], log: Callable[[str], None] = print, sky: str = "realistic") -> dict[str, Any]:
    """Yang et al. field-like: the single fixes' and the navigation output's pitch / roll error, per seed."""
    per: list[dict[str, Any]] = []
    for seed in seeds:
        t0 = time.monotonic()
        row = {"seed": seed, "sky": sky, **yang_member(seed, sky=sky)}
        per.append(row)
        _checkpoint(seeds, per)
        log(f"seed {seed}: fixes {row['fixes']}: pitch/roll/heading RMS {row['fix_pitch_rms_deg']:.3f}/"
            f"{row['fix_roll_rms_deg']:.3f}/{row['fix_heading_rms_deg']:.3f} deg; nav pitch/roll RMS "
            f"{row['pitch_rms_deg']:.3f}/{row['roll_rms_deg']:.3f} deg, refusals {row['refusals']} "
            f"({time.monotonic() - t0:.0f} s)")
    return {"seeds": seeds, "members": per, "markdown": yang_table(per)}


def yang_table(per: list[dict[str, Any]]) -> str:
    """The Markdown table: median [inter-quartile range] over the seeds, one column per sky, the single fixes
    against the paper's field table and the navigation output below them (not the paper's quantity)."""
    skies = [s for s in ("realistic", "rayleigh") if any(r.get("sky", "realistic") == s for r in per)]
    by = {s: [r for r in per if r.get("sky", "realistic") == s] for s in skies}
    rows = [("single fix: pitch RMS (deg)", "fix_pitch_rms_deg", 3, "0.23"),
            ("single fix: roll RMS (deg)", "fix_roll_rms_deg", 3, "0.43"),
            ("single fix: heading RMS (deg)", "fix_heading_rms_deg", 3, ""),
            ("single fix: pitch / roll mean (deg)", ("fix_pitch_mean_deg", "fix_roll_mean_deg"), 3, ""),
            ("single fix: pitch / roll max (deg)", ("fix_pitch_max_deg", "fix_roll_max_deg"), 3, ""),
            ("fixes after the alignment", "fixes", 0, ""),
            ("frames answered / refused (whole run)", ("solved", "refused"), 0, ""),
            ("navigation output (the filter weighing the fixes): pitch / roll RMS (deg)",
             ("pitch_rms_deg", "roll_rms_deg"), 3, "")]
    lines = ["| median [inter-quartile range] over the seeds | "
             + " | ".join(f"{s} sky ({len(by[s])} seeds)" for s in skies) + " | paper, field table |",
             "|---|" + "---|" * len(skies) + "---|"]
    for label, key, d, paper in rows:
        keys = key if isinstance(key, tuple) else (key,)
        cells = [" / ".join(_med([r[k] for r in by[s]], d) for k in keys) for s in skies]
        lines.append(f"| {label} | " + " | ".join(cells) + f" | {paper} |")
    return "\n".join(lines)


def rerun_member(stored: dict[str, Any]) -> dict[str, Any]:
    """A stored member (one seed of a ``--json`` file) run again with its seed and set-up: a Zhang member with the
    skies it holds, a Yang member with its sky, a Ge member with its figures (tests compare it with the stored one)."""
    quiet = lambda _s: None  # noqa: E731
    seed = int(stored["seed"])
    if "sins" in stored:
        out: dict[str, Any] = zhang([seed], log=quiet, skies=list(stored["se"]))["members"][0]
    elif "fix_pitch_rms_deg" in stored:
        out = yang([seed], log=quiet, sky=stored.get("sky", "realistic"))["members"][0]
    else:
        out = ge([seed], log=quiet, figures=stored.get("figures", "field"))["members"][0]
    return out


# -------------------------------------------------------------------------------------------------------- main
def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("paper", choices=["zhang", "ge", "yang"])
    ap.add_argument("--seeds", default="1-10", help="A-B or A,B,... (default 1-10)")
    ap.add_argument("--json", default=None, help="also write the members and the table to this file")
    ap.add_argument("--sky", default="realistic", choices=["realistic", "rayleigh"],
                    help="yang: the sky (rayleigh: the clear sky of the simulation, to isolate the iron)")
    ap.add_argument("--skies", default=None, metavar="S1,S2",
                    help="zhang: the skies of the sun-elevation runs (rayleigh, realistic, envelope; default all)")
    ap.add_argument("--figures", default="field", choices=list(GE_FIGURES),
                    help="ge: the sensor figures (paper: Ge et al.'s simulation conditions; field: the field presets)")
    ap.add_argument("--sins-from", nargs="+", default=None, metavar="JSON",
                    help="zhang: take the pure-SINS members of these earlier --json files instead of running them "
                         "(merging checks that they are the same)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=JSON",
                    help="zhang: a dotted scenario override for both members (attribution runs), value as JSON")
    ap.add_argument("--merge", nargs="+", default=None, metavar="JSON",
                    help="print the table of earlier --json outputs of this paper together (no runs)")
    a = ap.parse_args(argv)
    if a.merge:
        per = [m for f in a.merge for m in json.loads(Path(f).read_text())["members"]]
        if a.paper == "zhang":
            per = merge_zhang(per)
        print({"zhang": zhang_table, "ge": ge_table}[a.paper](per) if a.paper != "yang" else yang_table(per))
        return 0
    global CHECKPOINT
    CHECKPOINT = Path(a.json) if a.json else None
    log = lambda s: print(s, file=sys.stderr, flush=True)  # noqa: E731
    seeds = parse_seeds(a.seeds)
    overrides = parse_overrides(a.set)
    if a.paper == "yang":
        res = yang(seeds, log=log, sky=a.sky)
    elif a.paper == "zhang":
        sins = ({m["seed"]: m["sins"] for f in a.sins_from for m in json.loads(Path(f).read_text())["members"]}
                if a.sins_from else None)
        res = zhang(seeds, log=log, overrides=overrides, skies=a.skies.split(",") if a.skies else None, sins=sins)
    else:
        res = ge(seeds, log=log, figures=a.figures)
    print(res["markdown"])
    if a.json:
        Path(a.json).write_text(json.dumps({**res, "numerics": numerics()}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
