"""The envelope (emulator/world/envelope.py): draws per seed from published ranges, the minimum ranges issue 36
asks for, reproducibility, groups, and what the drawn scenario carries into a run and a campaign's runs.csv."""

from __future__ import annotations

import csv
import math

import numpy as np
import pytest

from emulator.scenario.loader import load_scenario
from emulator.world.envelope import ENVELOPE_STREAM, draw_envelope, envelope_draws, envelope_scenario, flat_draws
from tests.conftest import ROOT

QUICKSTART = ROOT / "scenarios" / "quickstart.yaml"
SEEDS = range(1, 201)


@pytest.fixture(scope="module")
def many() -> list[dict]:
    return [draw_envelope("published", s) for s in SEEDS]


def test_every_draw_has_a_group_and_a_source_and_a_known_distribution():
    draws = envelope_draws("published")
    assert len(draws) >= 25
    rng = np.random.default_rng([1, ENVELOPE_STREAM])
    for d in draws:
        assert d.group in ("imu", "gnss", "sky", "camera", "mounting", "calibration")
        assert len(d.source) > 3
        d.sample(rng)  # raises on an unknown distribution
    assert {d.group for d in draws} == {"imu", "gnss", "sky", "camera", "mounting", "calibration"}


def test_same_seed_same_draws_other_seed_other_draws(many):
    assert draw_envelope("published", 7) == draw_envelope("published", 7)
    a, b = draw_envelope("published", 7), draw_envelope("published", 8)
    numeric = [k for k, v in a.items() if isinstance(v, float)]
    assert len(numeric) > 10 and all(a[k] != b[k] for k in numeric)
    # no two of 200 seeds draw the same sky
    seps = [d["sky.neutral_point_sep_deg"] for d in many]
    assert len(set(seps)) == len(seps)


def test_groups_select_without_changing_the_other_groups_values():
    full = draw_envelope("published", 11)
    sky = draw_envelope("published", 11, ["sky"])
    assert sky and all(k.startswith("sky.") for k in sky)
    assert all(sky[k] == full[k] for k in sky)
    imu = draw_envelope("published", 11, ["imu", "gnss"])
    assert all(imu[k] == full[k] for k in imu) and "sensors.gnss.environment" in imu


def test_minimum_ranges_of_issue_36(many):
    # neutral points up to 30 deg from the sun and the antisun: separation up to 60 deg
    seps = np.array([d["sky.neutral_point_sep_deg"] for d in many])
    assert seps.min() >= 20.0 and seps.max() <= 60.0 and seps.max() > 58.0
    # and the published placement of Pan et al. (2023) in some skies
    assert 20 < sum(d["sky.neutral_points"] == "pan2023" for d in many) < 80
    # accelerometer turn-on bias up to 7 mg
    acc = np.array([d["sensors.imu.accel.turn_on_bias_mg"] for d in many])
    assert np.abs(acc).max() <= 7.0 and np.abs(acc).max() > 6.9
    assert np.mean(np.abs(acc) > 3.6) > 0.4  # beyond the MS1030's typical repeatability, often
    # radial diattenuation 0.5-1 % at the field edge
    dia = np.array([d["sensors.camera.optics.radial_diattenuation_edge"] for d in many])
    assert dia.min() >= 0.005 and dia.max() <= 0.01 and dia.min() < 0.0053 and dia.max() > 0.0097
    # every GNSS environment, the urban canyon among them
    env = [d["sensors.gnss.environment"] for d in many]
    assert {e: env.count(e) > 40 for e in ("open_sky", "suburban", "urban_canyon")} == {
        "open_sky": True, "suburban": True, "urban_canyon": True}
    # thin cloud in some skies; every lens outside the firmware's family; every unit lab-calibrated
    assert 30 < sum(bool(d["sky.clouds"]) for d in many) < 90
    assert all(d["sensors.camera.optics.distortion_k3"] != 0.0 for d in many)
    assert all(d["firmware.calibration.source"] == "lab" for d in many)


def test_the_scenario_carries_the_draws_and_no_envelope_leaves_it_alone():
    scn = load_scenario(QUICKSTART)
    same, draws = envelope_scenario(scn, 5)
    assert same is scn and draws == {}
    env = load_scenario(QUICKSTART, overrides=["envelope.preset=published"])
    drawn, draws = envelope_scenario(env, 5)
    assert draws == draw_envelope("published", 5)
    assert drawn.sky.neutral_point_sep_deg == draws["sky.neutral_point_sep_deg"]
    assert drawn.sensors.gnss.environment == draws["sensors.gnss.environment"]
    assert list(drawn.sensors.imu.accel.turn_on_bias_mg) == draws["sensors.imu.accel.turn_on_bias_mg"]
    assert drawn.sensors.camera.optics.radial_diattenuation_edge == draws[
        "sensors.camera.optics.radial_diattenuation_edge"]
    assert drawn.firmware.calibration.source == "lab"
    assert drawn.firmware.spec_sheet == scn.firmware.spec_sheet  # the firmware's sheet is never drawn
    assert drawn.source_file == env.source_file
    assert drawn.envelope.preset is None and envelope_scenario(drawn, 6) == (drawn, {})  # drawing twice: a no-op
    with pytest.raises(Exception, match="unknown envelope preset"):
        load_scenario(QUICKSTART, overrides=["envelope.preset=nowhere"])


def test_flat_draws_are_scalar_columns():
    flat = flat_draws(draw_envelope("published", 3))
    assert "sensors.imu.accel.turn_on_bias_mg[2]" in flat and "sky.thin_clouds" in flat
    assert all(isinstance(v, (float, str)) for v in flat.values())


def test_a_campaign_member_records_its_draws_in_the_summary_and_runs_csv(tmp_path):
    """A short member through the campaign's own path (run_member, write_outputs): the summary's envelope section
    (validated by the typed summary) and runs.csv's envelope: columns hold this seed's draws."""
    from emulator.distributed.campaign.execute import run_member
    from emulator.distributed.campaign.outputs import CampaignResult, write_outputs
    from emulator.distributed.campaign.plan import MemberTask
    from emulator.recording.summary_model import load_summary
    from emulator.scenario.loader import load_yaml_with_marks

    data, _ = load_yaml_with_marks(QUICKSTART.read_text(), str(QUICKSTART))
    data = {**data, "duration_s": 4.0, "motion": [{"static": {"duration_s": 4.0}}], "expectations": [],
            "envelope": {"preset": "published", "groups": ["imu", "gnss", "sky"]}}
    rows = []
    for i, seed in enumerate((21, 22)):
        task = MemberTask(i, seed, {}, data, str(QUICKSTART), str(QUICKSTART.parent), str(tmp_path / f"m{i}"))
        row = run_member(task)
        assert row["ok"], row["traceback"]
        rows.append(row)
    s = load_summary(tmp_path / "m0" / "summary.json")
    assert s.envelope is not None and s.envelope.preset == "published"
    assert s.envelope.draws == draw_envelope("published", 21, ["imu", "gnss", "sky"])
    write_outputs(CampaignResult(tmp_path, rows, {"metrics": {}}, 1.0, 1.0, {}), plots=False)
    with open(tmp_path / "runs.csv", newline="") as f:
        table = list(csv.DictReader(f))
    col = "envelope:sky.neutral_point_sep_deg"
    assert float(table[0][col]) == pytest.approx(draw_envelope("published", 21)["sky.neutral_point_sep_deg"])
    assert float(table[1][col]) != float(table[0][col])
    assert not any(k.startswith("envelope:sensors.camera") for k in table[0])
    assert math.isfinite(float(table[1]["envelope:sensors.imu.accel.turn_on_bias_mg[0]"]))


def test_a_key_the_scenario_sets_is_pinned():
    env = load_scenario(QUICKSTART, overrides=["envelope.preset=published", "sky.neutral_point_sep_deg=55",
                                               "sensors.gnss.environment=urban_canyon"])
    drawn, draws = envelope_scenario(env, 5)
    assert drawn.sky.neutral_point_sep_deg == 55.0 and drawn.sensors.gnss.environment == "urban_canyon"
    assert "sky.neutral_point_sep_deg" not in draws and "sensors.gnss.environment" not in draws
    assert draws["sky.turbidity"] == draw_envelope("published", 5)["sky.turbidity"]  # the others as drawn
    from emulator.world.envelope import pinned_keys

    assert set(pinned_keys(env)) == {"sky.neutral_point_sep_deg", "sensors.gnss.environment"}


def test_the_envelope_never_adds_a_sensor():
    scn = load_scenario(ROOT / "scenarios" / "sun_elevation_gnss_free.yaml", overrides=["envelope.preset=published"])
    assert scn.sensors.camera is None
    drawn, draws = envelope_scenario(scn, 2)
    assert drawn.sensors.camera is None and not any(k.startswith("sensors.camera") for k in draws)
    assert "sky.neutral_point_sep_deg" in draws
