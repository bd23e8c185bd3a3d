"""``psns-hil sweep`` (emulator.cli.sweep): one campaign per value, the boundary where the average NEES of an asked
group first rises above its chi-square upper bound, and its table and plot. The campaigns are replaced by synthetic
results whose heading error grows with the parameter against a fixed sigma, so the boundary has a closed form."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from types import SimpleNamespace

import pytest

from emulator.cli import sweep
from emulator.scenario.consistency_schema import chi2_bounds

SCENARIO = Path(__file__).resolve().parents[3] / "scenarios" / "static_psns_camera_field.yaml"


def _result(nees_heading: float, runs: int = 10) -> SimpleNamespace:
    lo, hi = chi2_bounds(runs, 1)
    lo3, hi3 = chi2_bounds(runs, 3)
    groups = {"heading": {"mean_nees": nees_heading, "lower": lo, "upper": hi, "asked": True},
              "attitude": {"mean_nees": 3.0, "lower": lo3, "upper": hi3, "asked": True},
              "horizontal_position": {"mean_nees": 50.0, "lower": 1.0, "upper": 3.4, "asked": False}}
    return SimpleNamespace(stats={"completed": runs, "failed": 0,
                                  "metrics": {"heading_deg_rms": {"mean": 0.1 * nees_heading ** 0.5}}},
                           consistency={"groups": groups, "heading_error": {"mean_deg": 0.2, "sigma_mean_deg": 0.1}})


def test_the_boundary_is_the_first_value_above_the_upper_bound_of_an_asked_group():
    hi = chi2_bounds(10, 1)[1]  # 2.05
    rows = sweep.sweep_rows("sky.neutral_point_sep_deg",
                            [(v, _result(n)) for v, n in ((20, 1.0), (40, 0.99 * hi), (50, 1.01 * hi), (60, 8.1))])
    b = sweep.boundary(rows)
    assert b["asked"] == 50 and b["groups"]["heading"] == 50 and b["groups"]["attitude"] is None
    # an informative group above its bound does not move the boundary of the asked ones
    assert b["groups"]["horizontal_position"] == 20
    assert [r["over_heading"] for r in rows] == [False, False, True, True]
    held = sweep.boundary(rows[:2])
    assert held["asked"] is None


def test_values_are_read_as_yaml():
    assert sweep.parse_values("20, 30.5,urban") == [20, 30.5, "urban"]
    assert sweep.parse_values("[3.6,3.6,3.6];[7.2,7.2,7.2]") == [[3.6] * 3, [7.2] * 3]
    from emulator.distributed.campaign import CampaignError

    with pytest.raises(CampaignError):
        sweep.parse_values(" , ")


def test_sweep_cli_writes_table_plot_and_exit_code(tmp_path, monkeypatch, capsys):
    from emulator.cli.main import build_parser

    seen = []

    def fake_run(cfg, progress=None, client=None):
        assert cfg.consistency and cfg.seeds == [301, 302, 303]
        v = float(cfg.overrides[-1].split("=")[1])
        seen.append(cfg.overrides)
        return _result(8.1 if v >= 60 else 1.0, runs=3)

    import emulator.distributed.campaign as camp
    import emulator.distributed.campaign.execute as ex

    monkeypatch.setattr(camp, "run_campaign", fake_run)
    monkeypatch.setattr(ex, "local_cluster", lambda workers, dashboard=False: (None, None))
    args = build_parser().parse_args(["sweep", str(SCENARIO), "--param", "sky.neutral_point_sep_deg",
                                      "--values", "20,40,60", "--seeds", "301-303", "--set", "duration_s=15",
                                      "--out", str(tmp_path)])
    assert sweep.run(args) == 1
    assert seen[0] == ["duration_s=15", "sky.neutral_point_sep_deg=20"]
    doc = json.loads((tmp_path / "sweep.json").read_text())
    assert doc["boundary"]["asked"] == 60
    with open(tmp_path / "sweep.csv", encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    assert [r["value"] for r in rows] == ["20", "40", "60"] and rows[2]["over_heading"] == "True"
    assert (tmp_path / "sweep.png").stat().st_size > 10_000
    assert "stops holding at sky.neutral_point_sep_deg=60" in capsys.readouterr().out
    # the same sweep stopped before the boundary holds: exit 0
    args.values, args.no_plots = "20,40", True
    assert sweep.run(args) == 0
