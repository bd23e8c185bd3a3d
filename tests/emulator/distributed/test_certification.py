"""Certification across the envelope (issue 36 item 3; D-5.42 in docs/decisions/sky-and-sheet-consistency.md).

The three library scenarios that carry a 31-run consistency expectation (quickstart, static_psns_camera_field,
vehicle_loop_gnss_outage) are run as the certification campaign does it, ``psns-hil campaign SCENARIO --seeds 301-331
[--envelope published] --consistency``: seeds the project never tuned on, each member's world drawn from the
published envelope, and again on the typical ``field`` world. Two claims, each tested on the same six campaigns:

* no group the scenario asks for (heading added wherever it has a heading source) is overconfident: its mean NEES is
  at most its upper chi-square bound, across the envelope and on ``field`` (the issue's "not overconfident");
* across the envelope the scenario's consistency expectation passes as written (two-sided where it asks for it).

What does not hold yet is marked ``xfail(strict=True)`` with the measured reason (studies/2026-12-07-certification-
across-the-envelope.md): such a test fails the day the gap closes, so the mark is removed with the fix. 31 members of
each of six campaigns: about an hour on a loaded 2-core machine, so ``slow`` (``make test-all``), never ``make test``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from emulator.distributed.campaign import CampaignConfig, run_campaign

pytest.importorskip("distributed")

SCENARIOS = Path(__file__).resolve().parents[3] / "scenarios"
#: the certification seeds: 31 runs, the project's minimum for a 1-dof group, never used to tune anything
SEEDS = list(range(301, 332))
_CACHE: dict[tuple[str, str], dict[str, Any]] = {}

_CANYON = ("across the envelope the urban-canyon receivers are wider than the firmware's DOP law covers: the world's "
           "errors follow the reported HDOP (D-4.13) from the receiver's figures at HDOP 0.8 plus a 5 m range "
           "multipath and the NLOS bias, the sheet's at hdop_ref 1.0 (D-5.42); velocity and position overconfident "
           "in the canyon members (studies/2026-12-07-certification-across-the-envelope.md, 'After D-4.13')")

NOT_OVERCONFIDENT = [
    pytest.param("quickstart", "envelope", marks=pytest.mark.xfail(strict=True, reason=_CANYON + ": 6.01 / 6.59")),
    ("quickstart", "field"),
    pytest.param("static_psns_camera_field", "envelope",
                 marks=pytest.mark.xfail(strict=True, reason=_CANYON + ": 4.12 / 5.22")),
    ("static_psns_camera_field", "field"),
    pytest.param("vehicle_loop_gnss_outage", "envelope",
                 marks=pytest.mark.xfail(strict=True, reason=_CANYON + ": 7.18 / 7.34")),
    ("vehicle_loop_gnss_outage", "field"),
]
#: vehicle_loop_gnss_outage on field fails the expectation two-sided too (velocity 2.07 below 2.20, D-5.41's sheet):
#: the field world is tested for overconfidence only, as the issue asks
TWO_SIDED = [
    pytest.param("quickstart", marks=pytest.mark.xfail(strict=True, reason=_CANYON)),
    pytest.param("static_psns_camera_field", marks=pytest.mark.xfail(strict=True, reason=_CANYON)),
    pytest.param("vehicle_loop_gnss_outage", marks=pytest.mark.xfail(strict=True, reason=_CANYON)),
]


def _consistency(name: str, world: str, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """The consistency result of one certification campaign (run once per module and shared by both tests)."""
    key = (name, world)
    if key not in _CACHE:
        cfg = CampaignConfig(SCENARIOS / f"{name}.yaml", runs=len(SEEDS), seeds=SEEDS, workers=1, plots=False,
                             consistency=True, out_dir=tmp_path_factory.mktemp(f"cert-{name}-{world}"),
                             envelope="published" if world == "envelope" else None)
        c = run_campaign(cfg).consistency
        assert c is not None and c["runs"] == len(SEEDS), "every member must complete"
        assert "heading" in c["asked"]["groups"], f"{name}: heading must be asked (the scenario has a camera)"
        _CACHE[key] = c
    return _CACHE[key]


def _rows(c: dict[str, Any]) -> dict[str, tuple[float, float, float, str]]:
    return {g: (round(d["mean_nees"], 3), round(d["lower"], 3), round(d["upper"], 3), d["status"])
            for g, d in c["groups"].items() if g in c["asked"]["groups"]}


@pytest.mark.slow
@pytest.mark.timeout(7200)
@pytest.mark.parametrize(("name", "world"), NOT_OVERCONFIDENT)
def test_no_asked_group_is_overconfident(name, world, tmp_path_factory):
    c = _consistency(name, world, tmp_path_factory)
    over = {g: r for g, r in _rows(c).items() if not r[0] <= r[2]}
    assert not over, f"{name} on {world}: overconfident (mean NEES above the upper bound): {over}"


@pytest.mark.slow
@pytest.mark.timeout(7200)
@pytest.mark.parametrize("name", TWO_SIDED)
def test_the_scenarios_consistency_expectation_passes_across_the_envelope(name, tmp_path_factory):
    c = _consistency(name, "envelope", tmp_path_factory)
    assert c["passed"], f"{name} across the envelope: {_rows(c)}"
