"""The HTML report is self-contained and shows what the run measured."""

import base64
import re

import pytest

from emulator.assembly.runner import run_scenario
from emulator.recording.report import write_report
from emulator.scenario import load_scenario
from tests.conftest import SCENARIOS


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    scn = load_scenario(SCENARIOS / "quickstart.yaml")
    scn.duration_s = 6.0
    d = tmp_path_factory.mktemp("rep") / "run"
    run_scenario(scn, d)
    return d


def test_report_is_self_contained_with_plots(run_dir):
    p = write_report(run_dir)
    doc = p.read_text()
    assert doc.startswith("<!DOCTYPE html>")
    assert "src='http" not in doc and "href='http" not in doc  # nothing fetched from outside
    imgs = re.findall(r"base64,([A-Za-z0-9+/=]+)'", doc)
    assert len(imgs) >= 4
    for b in imgs:
        assert base64.b64decode(b).startswith(b"\x89PNG")
    for title in ("Attitude error", "Velocity error", "Position error", "Filter consistency (NEES)", "Mode timeline",
                  "DSP load"):
        assert title in doc
    assert "uart1" in doc and "imu_tick" in doc


def test_report_survives_truncated_event_line(run_dir):
    with open(run_dir / "events.jsonl", "a") as f:
        f.write('{"t_s": 1.0, "sour')  # an interrupted writer
    assert write_report(run_dir).exists()
