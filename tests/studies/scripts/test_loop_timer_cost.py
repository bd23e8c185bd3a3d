"""``studies.scripts.loop_timer_cost``: the reference's timer pattern on two trees' loops, CPU per tick and the
order the callbacks ran in."""

from __future__ import annotations

import re

import pytest

from studies.scripts.loop_timer_cost import ROOT, _spawn, main


def test_the_workload_runs_its_ticks_in_one_order_every_time() -> None:
    a, b = _spawn(ROOT, 2000), _spawn(ROOT, 2000)
    assert a["order"] == b["order"]  # the same callbacks at the same instants, in the same order
    assert _spawn(ROOT, 2001)["order"] != a["order"]  # the digest sees one more tick
    assert float(a["cpu_s"]) > 0 and float(a["us_per_tick"]) == pytest.approx(float(a["cpu_s"]) / 2000 * 1e6)


def test_compares_two_trees_pair_by_pair(capsys: pytest.CaptureFixture[str]) -> None:
    assert main([str(ROOT), "1000", "2"]) == 0
    out = capsys.readouterr().out.splitlines()
    pairs = [re.fullmatch(r"pair \d: other [\d.]+ us/tick \((\w+)\), this [\d.]+ us/tick \((\w+)\), ratio [\d.]+", line)
             for line in out[:2]]
    assert all(m and m.group(1) == m.group(2) for m in pairs), out
    assert out[2].startswith("median ratio (other CPU / this CPU) over 2 pairs: ")
    with pytest.raises(SystemExit, match="usage"):
        main([])
