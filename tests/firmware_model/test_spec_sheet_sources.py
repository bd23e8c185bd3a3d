"""Every figure of every bundled spec sheet carries its published source, none is the emulator's own output, and the
sheets are frozen (issue 36: the firmware's sheet from published figures only, frozen before certification)."""

from __future__ import annotations

import hashlib
import json
import re
from pathlib import Path

import pytest
import yaml

from firmware_model.spec_sheet import SensorSpecSheet, SpecSheetError

SHEETS = Path(__file__).resolve().parents[2] / "firmware_model" / "spec_sheets"
SECTIONS = ("gyro", "accel", "gnss", "psns", "compass")
KINDS = ("datasheet:", "paper:", "standard:", "textbook:", "assumed:")
#: what a source may not point at: the emulator's benchmarks, its decision records, or the team's own (simulated)
#: logs and tests, which are the emulator's world under another name
FORBIDDEN = re.compile(r"benchmarks?[/ .]|\bD-\d|\bD\d\b|decisions?[/ ]|decision record|drive (log|test)|sky test|"
                       r"static log|\bbench\b|solar_vector_error|filter-consistency|NIS of", re.IGNORECASE)
#: sha256 of each sheet's figures (sections only, canonical JSON): a change of any figure after certification must be
#: a deliberate edit of this table, with its source, in the same commit
FROZEN = {
    "default": "0fe30c01c4ff176bde2b16bff3ceb109d49c52330de690f379639891cb5c1f2a",
    "field": "218c8e69bed162dffdae917600b6d308c399e05e184ed885acb6fbe95b875c9d",  # + unverified_multipath_m
}


def _load(name: str) -> dict:
    return yaml.safe_load((SHEETS / f"{name}.yaml").read_text(encoding="utf-8"))


def _figures_hash(data: dict) -> str:
    figs = {s: data.get(s, {}) for s in SECTIONS}
    return hashlib.sha256(json.dumps(figs, sort_keys=True).encode()).hexdigest()


def _bundled() -> list[str]:
    return sorted(p.stem for p in SHEETS.glob("*.yaml"))


@pytest.mark.parametrize("name", _bundled())
def test_every_figure_has_a_published_source(name):
    data = _load(name)
    sheet = SensorSpecSheet.from_dict(data, name)
    keys = [f"{s}.{k}" for s in SECTIONS for k in data.get(s, {})]
    assert keys, name
    missing = [k for k in keys if k not in sheet.sources]
    assert not missing, f"{name}: figures without a source: {missing}"
    for k, src in sheet.sources.items():
        assert src.startswith(KINDS), f"{name}: {k}: a source starts with its kind {KINDS}: {src!r}"
        assert not FORBIDDEN.search(src), f"{name}: {k} cites the emulator's own output: {src!r}"


@pytest.mark.parametrize("name", _bundled())
def test_no_comment_of_a_sheet_points_at_the_emulators_output(name):
    text = (SHEETS / f"{name}.yaml").read_text(encoding="utf-8")
    for i, line in enumerate(text.splitlines(), 1):
        comment = line.split("#", 1)[1] if "#" in line else ""
        assert not FORBIDDEN.search(comment), f"{name}.yaml:{i}: {line.strip()}"


@pytest.mark.parametrize("name", _bundled())
def test_the_sheets_are_frozen(name):
    assert name in FROZEN, f"{name}: a bundled sheet without a frozen hash"
    assert _figures_hash(_load(name)) == FROZEN[name], (
        f"{name}.yaml's figures changed after they were frozen for certification: give the new figure its published "
        "source, re-run the certification campaigns (docs/spec-sheet.md) and update FROZEN in the same commit")


def test_the_forbidden_pattern_catches_what_it_must():
    for bad in ("benchmarks/solar_vector_error --series", "D-5.33", "a drive log's 1 s differences", "sky test",
                "docs/decisions/filter-consistency.md", "raised after the NIS of static RMC logs"):
        assert FORBIDDEN.search(bad), bad
    for good in ("datasheet: Sensonor STIM210 (TS1545)", "paper: Liang & Bai, section III"):
        assert not FORBIDDEN.search(good), good


def test_a_source_for_a_figure_the_sheet_does_not_have_is_refused():
    data = _load("field")
    data["sources"] = {**data["sources"], "gyro.made_up": "paper: x"}
    with pytest.raises(SpecSheetError, match=r"gyro\.made_up"):
        SensorSpecSheet.from_dict(data, "field")
    data["sources"] = {"gyro.arw_deg_rt_h": ""}
    with pytest.raises(SpecSheetError, match="non-empty"):
        SensorSpecSheet.from_dict(data, "field")
