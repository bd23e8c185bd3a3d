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

from emulator.assembly.runner import run_scenario
from emulator.testing import load_test_scenario
from tests.conftest import SCENARIOS

DEG = math.pi / 180.0


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
    # the algorithm's accuracy, with the truth as calibration (seed 7: max 0.036 deg); the residuals of a calibrated
    # unit (polarizer angles, magnetometer iron) make it 0.18 deg, within the scenario's own expectations
    _summary, ev, nav = _run("kmeans_tilt_series", tmp_path, duration_s=105.0,
                             **{"firmware.calibration.source": "perfect"})
    refused = [e for e in ev if e["event"] == "kmeans_refused"]
    assert refused and refused[0]["reason"] == "sun_outside_fov" and refused[0]["t_fpga_s"] > 90.0
    assert next(e for e in ev if e["event"] == "kmeans_solved")["t_fpga_s"] < 5.0
    # pitch and roll of the navigation output against truth while the Sun is in the field
    rows = [r for r in nav if r["err_pitch_deg"] and 5.0 <= float(r["time_s"]) <= 90.0]
    assert max(max(abs(float(r["err_pitch_deg"])), abs(float(r["err_roll_deg"]))) for r in rows) < 0.1


def test_federated_scenario_isolates_the_glitch_within_two_epochs(tmp_path):
    _summary, ev, nav = _run("federated_gnss_glitch", tmp_path, duration_s=75.0,
                            motion=[{"static": {"duration_s": 75.0}}], expectations=[])
    iso = [e for e in ev if e["event"] == "gnss_isolated"]
    back = [e for e in ev if e["event"] == "gnss_readmitted"]
    assert iso and 60.0 <= iso[0]["t_meas_s"] <= 61.0  # the glitch starts at 60 s: isolated at epoch 1 (<= 2)
    assert back and back[0]["t_meas_s"] >= 65.0
    pos = [float(r["err_pos_m"]) for r in nav if r["err_pos_m"] and 58.0 <= float(r["time_s"]) <= 70.0]
    assert max(pos) < 15.0


@pytest.mark.slow
@pytest.mark.xfail(strict=True, reason="known (issue 15, docs/variants.md 6.4): in this scenario the sun-elevation "
                   "filter no longer beats the same filter without its update: max along-sun error 2.81 km against "
                   "pure SINS's 0.58 km, horizontal MAE 1.887 km for both (2026-12-02); the 12 km drift of pure "
                   "SINS is not what the base filter shows on this stream")
def test_sun_elevation_scenario_against_pure_sins(tmp_path, capsys):
    """The 20-minute GNSS-free scenario and the same stream navigated by the base filter (pure SINS), the firmware
    knowing its compass units exactly (the algorithm's check: max along-sun error 2.2 km against pure SINS's 11.9
    km). With a calibrated unit's residuals it is 7.7 km (0.1 deg per unit axis) to 12.2 km (0.18 deg):
    docs/calibration.md."""
    import datetime as dt

    from emulator.world.sun import SunModel

    res = {}
    for flt in ("sun_elevation", "base"):
        _summary, _ev, nav = _run("sun_elevation_gnss_free", tmp_path / flt,
                                  **{"firmware.filter": flt, "expectations": [],
                                     "firmware.calibration.source": "perfect"})
        sun = SunModel(dt.datetime(2019, 9, 18, 8, 12, tzinfo=dt.UTC), 69.0)
        along, hor = [], []
        for r in nav[::100]:
            if not r["err_pos_n_m"] or float(r["time_s"]) < 60.0:
                continue
            az, _ = sun.az_el(float(r["time_s"]), 39.979 * DEG, 116.339 * DEG, 50.0)
            n, e = float(r["err_pos_n_m"]), float(r["err_pos_e_m"])
            along.append(abs(e * math.sin(az) + n * math.cos(az)))
            hor.append(math.hypot(n, e))
        res[flt] = {"max_along_km": max(along) / 1e3, "mae_hor_km": sum(hor) / len(hor) / 1e3}
    with capsys.disabled():
        print(f"\nscenario sun_elevation_gnss_free: {res}")
    assert res["sun_elevation"]["max_along_km"] < 0.6 * res["base"]["max_along_km"]
    assert res["sun_elevation"]["mae_hor_km"] < res["base"]["mae_hor_km"]
