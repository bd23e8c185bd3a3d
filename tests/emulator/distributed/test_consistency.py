"""NEES / NIS of a campaign (emulator.distributed.campaign.consistency) on synthetic nav.csv / truth.csv files whose
errors are drawn from the reported sigmas: the average NEES comes out at the group's dimension, inside the bounds; an
error twice the sigma comes out at four times it and fails."""

from __future__ import annotations

import math

import numpy as np
import pytest

from emulator.distributed.campaign.consistency import campaign_consistency, member_consistency
from emulator.recording.nav_error import NAV_COLUMNS, TRUTH_COLUMNS


def _write_run(path, rng, scale: float, n: int = 300):
    """A static run at 1 Hz: attitude (small rotation about E, N, U), velocity and position errors of ``scale``
    times the written sigmas."""
    path.mkdir()
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
