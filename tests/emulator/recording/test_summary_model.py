"""The typed run summary: docs/summary.schema.json is current, real summaries validate, foreign files do not."""

import json

import pytest

from emulator.errors import RecordingError
from emulator.recording.summary_model import RunSummary, load_summary, summary_json_schema
from emulator.scenario.loader import load_scenario
from tests.conftest import ROOT


def test_committed_summary_schema_is_current():
    committed = (ROOT / "docs" / "summary.schema.json").read_text()
    assert committed == summary_json_schema(), "regenerate: python -c 'from emulator.recording.summary_model " \
        "import summary_json_schema as s; open(\"docs/summary.schema.json\", \"w\").write(s())'"


def test_a_real_run_summary_validates_and_reads_typed(tmp_path):
    from emulator.assembly.session import run_scenario

    scn = load_scenario(ROOT / "scenarios" / "quickstart.yaml", ["duration_s=3", "motion.0.static.duration_s=3"])
    run_scenario(scn, tmp_path / "run")
    s = load_summary(tmp_path / "run")
    assert isinstance(s, RunSummary) and s.scenario == "quickstart" and s.sim_duration_s == 3.0
    assert s.links["uart1"].frames > 0 and s.dsp is not None and s.dsp.clock_hz == 300e6
    # every expectation applies to a single run but the campaign-level consistency check (psns-hil campaign)
    assert [e.kind for e in s.expectations if not e.applicable] == ["consistency"]


def test_a_foreign_file_is_a_clear_error(tmp_path):
    (tmp_path / "summary.json").write_text(json.dumps({"hello": 1}))
    with pytest.raises(RecordingError, match="not a psns-hil run summary"):
        load_summary(tmp_path)
    with pytest.raises(RecordingError, match=r"no summary\.json"):
        load_summary(tmp_path / "nothing")
