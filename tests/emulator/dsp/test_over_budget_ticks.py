"""Deadline misses apart from ticks over the cycle budget (issue 38: a --split run counted the host's scheduling
jitter as DSP deadline misses without saying so)."""

from __future__ import annotations

from emulator.assembly.session import run_scenario
from emulator.scenario.loader import load_scenario
from tests.conftest import SCENARIOS


def test_over_budget_ticks_count_the_ticks_that_overran_by_themselves(tmp_path):
    """110 % extra load for 0.5 s at 200 Hz: each of the 100 loaded ticks is over the budget by itself, and each
    ends late; no tick outside the window is over the budget."""
    scn = load_scenario(SCENARIOS / "overload.yaml", ["duration_s=4", "expectations=[]",
                                                      "faults=[{dsp_extra_load: {load_pct: 110, start_s: 2, "
                                                      "duration_s: 0.5}}]"])
    s = run_scenario(scn, tmp_path)
    d = s["dsp"]
    assert d["over_budget_ticks"] == d["extra_load_ticks"] == 100
    assert d["deadline_misses"] >= d["over_budget_ticks"]


def test_the_console_says_what_a_split_runs_misses_are(tmp_path, capsys):
    from emulator.cli.main import print_summary

    scn = load_scenario(SCENARIOS / "quickstart.yaml", ["duration_s=3", "expectations=[]"])
    s = run_scenario(scn, tmp_path)
    assert s["dsp"]["over_budget_ticks"] == 0
    capsys.readouterr()
    print_summary({**s, "split": {"endpoint": "x"}, "dsp": {**s["dsp"], "deadline_misses": 6}})
    out = " ".join(capsys.readouterr().out.split())
    assert "--split: the DSP process follows the wall clock" in out
    assert "0 of the 6 were ticks over the cycle budget by themselves" in out
    print_summary(s)
    assert "--split" not in capsys.readouterr().out
