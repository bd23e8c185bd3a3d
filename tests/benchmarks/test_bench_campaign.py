"""The campaign-throughput rows (issue 43 item 5): the command is the certification's, cut to K seeds, and the
certification's prediction and its labelled extrapolation follow from the measured rates."""

from __future__ import annotations

from pathlib import Path

import pytest

from benchmarks import bench_campaign as bc
from emulator.cli.main import build_parser


def test_the_command_is_the_certification_command_cut_to_k_seeds(tmp_path: Path) -> None:
    cmd = bc.command("quickstart", 4, 2, tmp_path / "out")
    assert cmd[1:4] == ["-m", "emulator", "campaign"]
    args = build_parser().parse_args(cmd[3:])  # psns-hil's own parser accepts it
    assert Path(args.scenario).name == "quickstart.yaml" and Path(args.scenario).exists()
    assert (args.seeds, args.envelope, args.consistency, args.workers) == ("1-4", "published", True, 2)
    assert args.no_plots and args.quiet and args.out == str(tmp_path / "out")
    assert all((bc.ROOT / "scenarios" / f"{s}.yaml").exists() for s in bc.SCENARIOS)


def _measured(rate_1: float, rate_2: float, fixed: float) -> dict[int, dict[str, float]]:
    return {1: {"runs_per_min": rate_1, "fixed_s": fixed}, 2: {"runs_per_min": rate_2, "fixed_s": fixed}}


def test_certification_wall_is_fixed_cost_plus_members_over_machines_times_rate() -> None:
    per = {"a": _measured(6.0, 12.0, 10.0), "b": _measured(3.0, 6.0, 20.0)}
    # a: 10 s + 31 members at 12/min; b: 20 s + 31 members at 6/min
    assert bc.certification_wall(per, 2) == pytest.approx(10 + 31 * 5 + 20 + 31 * 10)
    assert bc.certification_wall(per, 1) == pytest.approx(10 + 31 * 10 + 20 + 31 * 20)
    # four machines divide the members' time, never the fixed cost
    assert bc.certification_wall(per, 2, 4) == pytest.approx(30 + 31 * 15 / 4)
