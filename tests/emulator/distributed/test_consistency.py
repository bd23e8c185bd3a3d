"""NEES / NIS of a campaign (emulator.distributed.campaign.consistency) on synthetic nav.csv / truth.csv files whose
errors are drawn from the reported sigmas: the average NEES comes out at the group's dimension, inside the bounds; an
error twice the sigma comes out at four times it and fails."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from emulator.distributed.campaign.consistency import campaign_consistency, member_consistency
from emulator.recording.nav_error import NAV_COLUMNS, TRUTH_COLUMNS


def _write_run(path, rng, scale: float, n: int = 300):
    """A static run at 1 Hz: attitude (small rotation about E, N, U), velocity and position errors of ``scale``
    times the written sigmas."""
    path.mkdir(parents=True)
    sig = {"att": np.array([0.05, 0.05, 0.2]), "vel": np.array([0.02, 0.03, 0.1]), "pos": np.array([3.0, 2.0, 6.0])}
    nav_rows, truth_rows = [",".join(NAV_COLUMNS)], [",".join(TRUTH_COLUMNS)]
    for k in range(n):
        t = 0.005 + k
        # roll/pitch/heading errors from a tilt about E (pitch), N (roll), U (-heading) at heading 0
        ea, ev, ep = (scale * sig[g] * rng.standard_normal(3) for g in ("att", "vel", "pos"))
        nav = {c: "0" for c in NAV_COLUMNS}
        nav.update(time_s=f"{t}", pitch_deg=f"{ea[0]}", roll_deg=f"{ea[1]}", heading_deg=f"{-ea[2]}",
                   sig_att_e_deg=f"{sig['att'][0]}", sig_att_n_deg=f"{sig['att'][1]}", sig_att_u_deg=f"{sig['att'][2]}",
                   sig_vel_e_mps=f"{sig['vel'][0]}", sig_vel_n_mps=f"{sig['vel'][1]}", sig_vel_u_mps=f"{sig['vel'][2]}",
                   sig_pos_e_m=f"{sig['pos'][0]}", sig_pos_n_m=f"{sig['pos'][1]}", sig_pos_u_m=f"{sig['pos'][2]}",
                   err_att_deg="1", err_vel_e_mps=f"{ev[0]}", err_vel_n_mps=f"{ev[1]}", err_vel_u_mps=f"{ev[2]}",
                   err_pos_e_m=f"{ep[0]}", err_pos_n_m=f"{ep[1]}", err_pos_u_m=f"{ep[2]}")
        nav_rows.append(",".join(nav[c] for c in NAV_COLUMNS))
        tr = {c: "0" for c in TRUTH_COLUMNS}
        tr["time_s"] = f"{t}"
        truth_rows.append(",".join(tr[c] for c in TRUTH_COLUMNS))
    (path / "nav.csv").write_text("\n".join(nav_rows) + "\n")
    (path / "truth.csv").write_text("\n".join(truth_rows) + "\n")


def _members(tmp_path, scale, runs=12):
    rng = np.random.default_rng(7)
    out = []
    for i in range(runs):
        d = tmp_path / f"r{scale}-{i}"
        _write_run(d, rng, scale)
        summary = {"firmware": {"innovation": {"gnss_position": {"rows": 100, "nis_sum": 100.0 * scale**2}}}}
        out.append(member_consistency(d, summary))
    return out


def test_errors_drawn_from_the_sigmas_are_consistent(tmp_path):
    c = campaign_consistency(_members(tmp_path, 1.0))
    assert c["runs"] == 12 and len(c["t"]) == 300
    for g, dof in (("attitude", 3), ("heading", 1), ("velocity", 3), ("position", 3), ("horizontal_position", 2)):
        d = c["groups"][g]
        # 3600 samples of chi2(dof): the mean is dof within a few percent (small-angle attitude: within 1 %)
        assert d["mean_nees"] == pytest.approx(dof, rel=0.08), g
        assert d["passed"] and d["lower"] < dof < d["upper"]
        assert d["share_inside"] > 0.85
    assert c["heading_in_3sigma"]["mean"] == pytest.approx(0.9973, abs=0.01)  # P(|z| <= 3)
    m = c["measurements"]["gnss_position"]
    assert m["rows"] == 1200 and m["mean_nis"] == pytest.approx(1.0) and m["passed"]
    assert c["measurements"]["compass"]["passed"] is None and c["passed"]


def test_errors_twice_the_sigmas_fail(tmp_path):
    c = campaign_consistency(_members(tmp_path, 2.0))
    d = c["groups"]["position"]
    assert d["mean_nees"] == pytest.approx(12.0, rel=0.1) and not d["passed"]
    assert c["heading_in_3sigma"]["mean"] == pytest.approx(2 * 0.5 * (1 + math.erf(1.5 / math.sqrt(2))) - 1,
                                                           abs=0.02)
    assert not c["measurements"]["gnss_position"]["passed"] and not c["passed"]


def test_explicit_seeds_for_the_members(tmp_path):
    from emulator.cli.campaign import parse_seeds
    from emulator.distributed.campaign import CampaignError, plan_members

    assert parse_seeds("1-3,7") == [1, 2, 3, 7]
    for bad in ("3-1", "x", "-2"):
        with pytest.raises(CampaignError):
            parse_seeds(bad)
    tasks = plan_members({"seed": 5}, 3, 5, [], tmp_path, seeds=[1, 2, 3], consistency=True, consistency_after_s=10)
    assert [t.seed for t in tasks] == [1, 2, 3] and [t.data["seed"] for t in tasks] == [1, 2, 3]
    assert all(t.consistency and t.consistency_after_s == 10 for t in tasks)


# -- issue 38 item 4: the asked groups decide; the rest is informative; not applied is never a pass ----------------
def _with_nis(members, mean_nis: float):
    for m in members:
        m["innovation"] = {"gnss_position": {"rows": 100, "nis_sum": 100.0 * mean_nis},
                           "solar_vector": {"rows": 100, "nis_sum": 100.0 * mean_nis}}
    return members


def test_conservative_nis_rows_nobody_asked_for_are_informative(tmp_path):
    c = campaign_consistency(_with_nis(_members(tmp_path, 1.0), 0.43), groups=["attitude", "velocity", "position"])
    nis = c["measurements"]["gnss_position"]
    assert nis["passed"] is False and nis["status"] == "FAIL" and nis["asked"] is False
    assert c["groups"]["heading"]["asked"] is False and c["groups"]["attitude"]["asked"] is True
    assert c["passed"] is True and c["not_applied"] == []
    # the same rows asked for decide
    c = campaign_consistency(_with_nis(_members(tmp_path / "b", 1.0), 0.43), measurements=["gnss_position"])
    assert c["measurements"]["gnss_position"]["asked"] and c["passed"] is False


def test_an_asked_check_that_was_not_applied_is_not_a_pass(tmp_path):
    c = campaign_consistency(_members(tmp_path, 1.0), measurements=["compass"])
    assert c["measurements"]["compass"]["status"] == "not applied" and c["measurements"]["compass"]["passed"] is None
    assert c["not_applied"] == ["compass"] and c["passed"] is False
    empty = campaign_consistency([], groups=["heading"])
    assert empty["groups"]["heading"]["status"] == "not applied" and empty["passed"] is False


def test_the_heading_group_is_the_heading_error_over_the_heading_sigma(tmp_path):
    # a heading bias of one sign: 2 sigma on every sample -> NEES 4 + 1 = 5 on average, positive in every run
    rng = np.random.default_rng(3)
    members = []
    for i in range(12):
        d = tmp_path / f"h{i}"
        _write_run(d, rng, 1.0, n=50)
        rows = (d / "nav.csv").read_text().splitlines()
        hdr = rows[0].split(",")
        k, s = hdr.index("heading_deg"), hdr.index("sig_att_u_deg")
        out = [rows[0]]
        for r in rows[1:]:
            f = r.split(",")
            f[k] = f"{(float(f[k]) - 2 * float(f[s])) % 360.0}"  # heading estimate 2 sigma low, wrapped to [0, 360)
            out.append(",".join(f))
        (d / "nav.csv").write_text("\n".join(out) + "\n")
        members.append(member_consistency(d, {}))
    c = campaign_consistency(members, groups=["heading"])
    assert c["groups"]["heading"]["mean_nees"] == pytest.approx(5.0, rel=0.15) and not c["passed"]
    assert c["heading_error"]["positive_runs"] == 0 and c["heading_error"]["mean_deg"] == pytest.approx(-0.4, abs=0.03)


def _fake_result(tmp_path, members, groups, measurements):
    from emulator.distributed.campaign import CampaignResult
    from emulator.distributed.campaign.stats import campaign_statistics

    rows = [{"index": i, "seed": 301 + i, "params": {}, "ok": True, "passed": True, "error": None,
             "expectations": [{"index": 0, "description": "consistency of attitude at 95% over 11 runs",
                               "value": None, "passed": True, "applicable": False}]} for i in range(len(members))]
    res = CampaignResult(tmp_path, rows, campaign_statistics(rows), 1.0, 60.0,
                         {"scenario": "x", "workers": 1, "scheduler": "test"})
    res.consistency = campaign_consistency(members, 0.95, groups, measurements)
    return res


@pytest.mark.parametrize(("nis", "cli", "code"), [
    (0.43, [], 0),                                        # conservative NIS, nobody asked: exit 0
    (0.43, ["--measurements", "gnss_position"], 1),       # asked on the command line: it decides
    (1.0, ["--groups", "heading"], 0),
])
def test_campaign_exit_code_follows_the_asked_groups(tmp_path, monkeypatch, capsys, nis, cli, code):
    import emulator.cli.campaign as cc
    from emulator.cli.main import build_parser

    members = _with_nis(_members(tmp_path, 1.0), nis)

    def fake_run(cfg, progress=None):
        assert cfg.consistency
        return _fake_result(tmp_path, members, cfg.consistency_groups, cfg.consistency_measurements)

    monkeypatch.setattr(cc, "run_campaign", fake_run)
    args = build_parser().parse_args(["campaign", "x.yaml", "--runs", "12", "--consistency", "--quiet", *cli])
    assert cc.run(args) == code
    out = capsys.readouterr().out
    assert "informative" in out and "not applied in the members" in out
    assert "NIS compass" in out and "not applied" in out.split("NIS compass")[1].splitlines()[0]


def test_a_campaign_level_expectation_is_not_applied_in_the_members(tmp_path):
    from emulator.distributed.campaign.outputs import write_outputs

    res = _fake_result(tmp_path, _members(tmp_path, 1.0, runs=3), None, None)
    d = res.stats["expectations"][0]
    assert d["runs"] == 0 and d["not_applied"] == 3 and d["status"] == "not applied" and d["pass_rate"] is None
    write_outputs(res, plots=False)
    import csv

    with open(tmp_path / "runs.csv", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    assert {r["exp0_passed"] for r in rows} == {"not applied"}


def test_heading_is_asked_by_default_wherever_the_scenario_has_a_heading_source():
    from emulator.distributed.campaign.execute import consistency_spec
    from emulator.scenario import load_scenario

    root = Path(__file__).resolve().parents[3] / "scenarios"
    spec = consistency_spec(load_scenario(root / "quickstart.yaml"))
    assert spec["groups"] == ["attitude", "velocity", "position", "heading"] and spec["measurements"] == []
    assert consistency_spec(load_scenario(root / "quickstart.yaml"), groups=["position"])["groups"] == \
        ["position", "heading"]
    no_cam = load_scenario(root / "quickstart.yaml", ["sensors.camera=null", "links.psns=null"])
    assert "heading" not in consistency_spec(no_cam)["groups"]
    off = load_scenario(root / "quickstart.yaml", ["expectations.3.consistency.include_heading=false"])
    assert consistency_spec(off)["groups"] == ["attitude", "velocity", "position"]


def test_an_upper_only_group_passes_conservative_and_fails_overconfident(tmp_path):
    # errors at half the sigmas: NEES 1/4 of the dof, under the lower bound
    half = _members(tmp_path, 0.5)
    two = campaign_consistency(half, groups=["heading"])
    assert not two["passed"] and two["groups"]["heading"]["conservative"]
    one = campaign_consistency(half, groups=["heading"], upper_only=["heading"])
    d = one["groups"]["heading"]
    assert one["passed"] and d["passed"] and d["conservative"] and d["upper_only"]
    # twice the sigmas: overconfident, fails either way
    over = campaign_consistency(_members(tmp_path / "o", 2.0), groups=["heading"], upper_only=["heading"])
    assert not over["passed"] and not over["groups"]["heading"]["conservative"]


def test_upper_only_names_known_groups(tmp_path):
    from emulator.errors import ScenarioError
    from emulator.scenario import load_scenario

    root = Path(__file__).resolve().parents[3] / "scenarios"
    with pytest.raises(ScenarioError, match="upper_only"):
        load_scenario(root / "quickstart.yaml", ["expectations.3.consistency.upper_only=[bias]"])
