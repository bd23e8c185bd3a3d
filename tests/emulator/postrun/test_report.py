"""The HTML report is self-contained and shows what the run measured."""

import base64
import re

import pytest

from emulator.assembly.session import run_scenario
from emulator.postrun.report import write_report
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


def test_report_decodes_what_the_sensors_sent_from_the_capture(run_dir):
    """The GNSS and PSNS panels read the capture with the ports' own decoders: the quickstart's receiver sends one
    GGA a second with the GnssConfig defaults (12 satellites, HDOP 0.8) and the camera 5 frames a second."""
    from emulator.devices.gnss import GnssConfig
    from emulator.postrun.report import sensor_series

    s = sensor_series(run_dir)
    assert len(s["gnss_t"]) in (5, 6, 7) and set(s["gnss_sats"]) == {GnssConfig.num_sats}
    assert s["gnss_dop"] == pytest.approx([GnssConfig.hdop] * len(s["gnss_t"]), abs=0.05)  # GGA carries 0.1
    gaps = [b - a for a, b in zip(s["gnss_t"], s["gnss_t"][1:])]
    assert gaps == pytest.approx([1.0] * len(gaps), abs=0.01)
    assert len(s["psns_t"]) == pytest.approx(30, abs=1) and min(s["psns_points"]) > 10
    assert all(0.0 < d < 1.0 for d in s["psns_dop"])


def test_sensor_series_of_a_run_without_capture_is_empty(tmp_path):
    from emulator.postrun.report import sensor_series

    assert all(v == [] for v in sensor_series(tmp_path).values())


def test_report_shows_the_solved_solar_vector_against_truth(run_dir):
    """The quickstart carries a camera: the report's table holds the summary's psns statistics, its figure the
    rows of psns.csv, and the reader keeps the text columns."""
    import json

    from emulator.postrun.report import load_psns_csv

    summary = json.loads((run_dir / "summary.json").read_text())
    psns = summary["psns"]
    assert psns["solves"] > 0
    rows = load_psns_csv(run_dir / "psns.csv")
    assert len(rows["time_s"]) == psns["solves"]
    assert set(rows["use"]) <= set(psns["uses"]) and set(rows["source"]) == {"camera"}  # solved from images
    assert max(rows["err_deg"]) == pytest.approx(psns["solar_vector_error_deg"]["max"], rel=1e-6)
    from emulator.postrun.report import _solar_error_figure

    assert len(_solar_error_figure(rows)) == 1 and _solar_error_figure({}) == []
    doc = write_report(run_dir).read_text()
    assert "Solved solar vector against truth" in doc and "Solar vector against truth" in doc
    from emulator.postrun.report import _fmt

    assert _fmt(psns["solar_vector_error_deg"]["median"]) in doc


def test_psns_csv_reader_without_the_file_is_empty(tmp_path):
    from emulator.postrun.report import load_psns_csv

    assert load_psns_csv(tmp_path / "psns.csv") == {}
