"""Event-level checks of the variant scenarios (run through the whole emulator). Until scenario event expectations
land (scenario expectations), the scenario files carry nav_error/link/dsp expectations and these tests check the events:
``psns_mode``/``psns_quality``/``measurement_rejected`` (dual-vector), ``kmeans_refused`` (K-means),
``gnss_isolated``/``gnss_readmitted``/``federated_mode`` (federated)."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import pytest

from emulator.assembly.session import run_scenario
from emulator.testing import load_test_scenario
from protocols.constants import DEG
from tests.conftest import SCENARIOS


def _run(name: str, tmp_path: Path, **overrides) -> tuple[dict, list[dict], list[dict]]:
    scn = load_test_scenario(SCENARIOS / f"{name}.yaml", overrides)
    summary = run_scenario(scn, tmp_path / name, mode="fast")
    events = [json.loads(line) for line in (tmp_path / name / "events.jsonl").read_text().splitlines()]
    with open(tmp_path / name / "nav.csv", newline="") as f:
        nav = list(csv.DictReader(f))
    return summary, [e for e in events if e["source"] == "firmware"], nav


def test_dual_vector_scenario_switches_modes_with_its_sensor_blocks(tmp_path):
    summary, ev, nav = _run("dual_vector_sensor_failure", tmp_path, duration_s=70.0,
                            motion=[{"static": {"duration_s": 70.0}}], expectations=[])
    assert summary["passed"]
    modes = [e for e in ev if e["event"] == "psns_mode"]
    assert [m["mode"] for m in modes] == ["sun_error_vector", "polarization_error_vector"]
    sw = modes[1]
    assert 60.0 <= sw["t_meas_s"] < 60.0 + 0.2 + 0.05 and sw["q"] == [1, 0, 0]  # within one 5 Hz update
    assert {(e["channel"], e["reason"]) for e in ev if e["event"] == "measurement_rejected"} >= {
        ("compass_unit1", "low_dop"), ("compass_unit2", "low_dop")}
    att = [float(r["err_att_deg"]) for r in nav if r["err_att_deg"] and 55.0 <= float(r["time_s"]) <= 70.0]
    assert att and max(att) < 0.5


def test_kmeans_scenario_refuses_when_the_sun_leaves_the_field(tmp_path):
    # with the truth as calibration (seed 7) the fixes themselves are within 0.01-0.06 deg of the truth, but the
    # filter weighs them by its spec sheet, which states the fisheye's calibration check (mount and lens residual,
    # 0.07 deg per axis together, D-5.24): the level it keeps is the sheet's, not the algorithm's best (pitch/roll
    # max 0.242 deg at 45-50 s, at most 2.0 of the filter's sigma; it was 0.158 deg before D-5.31 routed the sun's
    # error into the fix's heading through the magnetometer's tilt compensation, and 0.036 deg when the filter took
    # the fix as exact). With the calibrated unit (the scenario as written) the level improves: D-5.31.
    _summary, ev, nav = _run("kmeans_tilt_series", tmp_path, duration_s=105.0,
                             **{"firmware.calibration.source": "perfect"})
    refused = [e for e in ev if e["event"] == "kmeans_refused"]
    assert refused and refused[0]["reason"] == "sun_outside_fov" and refused[0]["t_fpga_s"] > 90.0
    assert next(e for e in ev if e["event"] == "kmeans_solved")["t_fpga_s"] < 5.0
    # pitch and roll of the navigation output against truth while the Sun is in the field: under 0.2 deg, and at
    # every frame inside 3 times the filter's own level sigma (the larger of its east and north tilt sigmas)
    rows = [r for r in nav if r["err_pitch_deg"] and 5.0 <= float(r["time_s"]) <= 90.0]
    err = [max(abs(float(r["err_pitch_deg"])), abs(float(r["err_roll_deg"]))) for r in rows]
    sig = [max(float(r["sig_att_e_deg"]), float(r["sig_att_n_deg"])) for r in rows]
    assert max(err) < 0.3
    assert all(e < 3.0 * s for e, s in zip(err, sig, strict=True))


def test_federated_scenario_isolates_the_glitch_within_two_epochs(tmp_path):
    # What the detector's design guarantees (docs/variants.md 4 "Chi-square isolation", D-5.35): the glitch (60 s to
    # 65 s, 1 Hz fixes, 6 rows each) is isolated at its first or second epoch, GNSS is readmitted only after it ends
    # and the position stays bounded through it. Before it, a calibrated test at alpha = 0.001 false-alarms on a
    # clean epoch with probability 0.001: over the 59 clean epochs at most one (P(>= 2) = 0.0017), readmitted at the
    # next epoch (readmit_after = 1) and leaving the position undisturbed. The FIRST isolation is not guaranteed to be
    # the glitch's: this run (seed 11) has one false alarm at 45 s (lambda 23.24 against 22.458, D-5.34).
    from scipy.stats import chi2

    from studies.scripts.federated_chi2_epochs import epochs

    recs, ev = epochs(0.0, 75.0, duration_s=75.0, run_dir=tmp_path / "run")
    with open(tmp_path / "run" / "nav.csv", newline="") as f:
        nav = [(float(r["time_s"]), float(r["err_pos_m"])) for r in csv.DictReader(f) if r["err_pos_m"]]
    iso = [e["t_meas_s"] for e in ev if e["event"] == "gnss_isolated"]
    back = [e["t_meas_s"] for e in ev if e["event"] == "gnss_readmitted"]
    glitch_iso, glitch_back = [t for t in iso if t >= 60.0], [t for t in back if t >= 60.0]
    assert glitch_iso and 60.0 <= glitch_iso[0] <= 61.0  # the glitch starts at 60 s: isolated at epoch 1 or 2
    assert glitch_back and glitch_back[0] >= 65.0  # readmitted only once the fixes are clean again
    assert max(e for t, e in nav if 58.0 <= t <= 70.0) < 15.0
    false_alarms = [t for t in iso if t < 60.0]
    assert len(false_alarms) <= 1  # binomial(59, 0.001): P(>= 2) = 0.0017
    for t_fa in false_alarms:
        assert [t for t in back if t_fa < t < 60.0] == [t_fa + 1.0]  # readmitted at the next epoch
        # one epoch without GNSS does not move the position: its error within the 10 s before, plus 0.5 m
        before = max(e for t, e in nav if t_fa - 10.0 <= t < t_fa)
        assert max(e for t, e in nav if t_fa <= t <= t_fa + 3.0) < before + 0.5
    # the test's calibration: over the clean epochs, lambda (m = 6 rows) has mean m; the mean over n epochs lies
    # within chi2(n m) / n's two-sided 99 % bounds (n = 59: 4.90 .. 7.23; this run 6.22, D-5.35)
    clean = [r for r in recs if r["t_s"] < 60.0]
    n, m = len(clean), len(clean[0]["norm_eps"])
    mean_lam = sum(r["lambda"] for r in clean) / n
    assert n == 59 and m == 6
    assert chi2.ppf(0.005, n * m) / n < mean_lam < chi2.ppf(0.995, n * m) / n, mean_lam


_SE_RUNS: dict[str, dict] = {}


def _along_azimuth(label: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, **over) -> dict:
    """``sun_elevation_gnss_free`` (its seed, the firmware knowing its compass units exactly): the largest error along
    the Sun's azimuth (km), the filter's own along-azimuth sigma at the end (km, from P before each elevation update)
    and the largest ratio of the two; cached per configuration for this module's tests."""
    if label in _SE_RUNS:
        return _SE_RUNS[label]
    import datetime as dt

    import numpy as np

    from emulator.world.sun import SunModel
    from firmware_model.kf import D_LAT, D_LON
    from firmware_model.variants import sun_elevation as se

    sig: dict[int, float] = {}  # exposure second -> along-azimuth position sigma (m) before the update
    orig = se.SunElevationFilter.update_compass

    def recorded(self, nav, frame, t_exp):
        p_before = self.P.copy()
        rep = orig(self, nav, frame, t_exp)
        if self.last.get("t") == t_exp:
            h = np.zeros(p_before.shape[0])
            h[D_LAT], h[D_LON] = self.last["alpha"], self.last["beta"]  # dh/dL = cos Az, dh/dlambda = cos L sin Az
            sig[round(t_exp)] = 6.371e6 * math.sqrt(float(h @ p_before @ h))
        return rep

    with monkeypatch.context() as m:
        m.setattr(se.SunElevationFilter, "update_compass", recorded)
        _summary, _ev, nav = _run("sun_elevation_gnss_free", tmp_path / label,
                                  **{"expectations": [], "firmware.calibration.source": "perfect", **over})
    sun = SunModel(dt.datetime(2019, 9, 18, 8, 12, tzinfo=dt.UTC), 69.0)
    along, norm = [], []
    for r in nav[::100]:
        if not r["err_pos_n_m"] or float(r["time_s"]) < 60.0:
            continue
        t = float(r["time_s"])
        az, _ = sun.az_el(t, 39.979 * DEG, 116.339 * DEG, 50.0)
        a = abs(float(r["err_pos_e_m"]) * math.sin(az) + float(r["err_pos_n_m"]) * math.cos(az))
        along.append(a)
        if sig.get(round(t), 0.0) > 0.0:
            norm.append(a / sig[round(t)])
    _SE_RUNS[label] = {"max_along_km": max(along) / 1e3, "final_sigma_along_km": sig[max(sig)] / 1e3 if sig else 0.0,
                       "max_along_over_sigma": max(norm) if norm else 0.0}
    return _SE_RUNS[label]


def _check_observed_direction(r: dict, sins: dict) -> None:
    """The elevation measured in the INS's own level frame observes the psi-angle along the Sun's azimuth
    (tilt and position together): over 20 static minutes the filter resolves the position along the azimuth to about
    1.0-1.2 km only (its own sigma), and on this draw pure SINS drifted 0.58 km along it, so the former "below 0.6 x
    pure SINS" asked more than the measurement carries (the firmware-level tests of test_sun_elevation.py, whose gyro
    drives the drift along the azimuth, check that the update holds it). What holds and can fail: the error along the
    observed direction stays within 3 of the filter's own sigmas and is not worse than pure SINS's by more than that
    sigma (docs/decisions/filter-consistency.md D-5.21)."""
    assert r["max_along_over_sigma"] < 3.0
    assert r["max_along_km"] < sins["max_along_km"] + r["final_sigma_along_km"]


@pytest.mark.slow
@pytest.mark.timeout(1200)  # two 21-minute runs (about 70 s each, several minutes on a loaded machine)
def test_sun_elevation_tilt_columns_hold_the_observed_direction(tmp_path, capsys, monkeypatch):
    """The tilt columns in H (attitude_coupling) against pure SINS: :func:`_check_observed_direction`."""
    c = _along_azimuth("coupled", tmp_path, monkeypatch, **{"firmware.variants.sun_elevation.attitude_coupling": True})
    s = _along_azimuth("sins", tmp_path, monkeypatch, **{"firmware.filter": "base"})
    with capsys.disabled():
        print(f"\nsun_elevation_gnss_free, tilt columns: {c}\npure SINS: {s}")
    _check_observed_direction(c, s)  # 2026-12-02: 0.70 km at most 0.9 sigma (1.19 km), pure SINS 0.58 km


@pytest.mark.slow
@pytest.mark.timeout(1200)
@pytest.mark.xfail(strict=True, raises=AssertionError,
                   reason="known (issue 15, D-5.21): the paper's H (the default, attitude_coupling off) takes the "
                   "INS tilt (0.1-0.18 deg after 20 static minutes) for position along the Sun's azimuth: "
                   "2.80 km against pure SINS's 0.58 km + its own sigma 1.03 km (2026-12-02); the tilt columns pass "
                   "(test above) but double the like-for-like MAE, so they are not the default")
def test_sun_elevation_scenario_against_pure_sins(tmp_path, capsys, monkeypatch):
    """The default filter (the paper's H) against pure SINS: :func:`_check_observed_direction`."""
    p = _along_azimuth("paper_h", tmp_path, monkeypatch)
    s = _along_azimuth("sins", tmp_path, monkeypatch, **{"firmware.filter": "base"})
    with capsys.disabled():
        print(f"\nsun_elevation_gnss_free, the paper's H: {p}\npure SINS: {s}")
    _check_observed_direction(p, s)
