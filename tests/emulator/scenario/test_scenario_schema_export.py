"""docs/scenario.schema.json is the generated schema, never stale."""

import json

from emulator.scenario.export import render
from tests.conftest import ROOT


def test_committed_json_schema_is_current():
    committed = (ROOT / "docs" / "scenario.schema.json").read_text()
    regenerate = ".venv/bin/python -m emulator.scenario.export docs/scenario.schema.json"
    assert committed == render(), f"regenerate with: {regenerate}"


def test_schema_forbids_unknown_keys():
    s = json.loads(render())
    assert s["additionalProperties"] is False
    assert "origin" in s["required"] and "epoch" in s["required"]
