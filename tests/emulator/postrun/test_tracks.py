"""KML and GPX tracks of a run with a fault: KML valid against the OGC KML 2.2 schema vendored in tests/vectors/kml
(with the Atom and xAL schemas it imports), GPX valid against the Topografix GPX 1.1 schema vendored in
tests/vectors/gpx (no network); KML read back by fastkml and GPX by gpxpy (independent parsers) with the points of
truth.csv / nav.csv and the fault's placemarks and waypoints."""

from __future__ import annotations

import csv
import datetime as _dt
import xml.etree.ElementTree as ET

import gpxpy
import pytest
import xmlschema

from emulator.assembly.session import run_scenario
from emulator.postrun.tracks import KML_NS, TRACK_STEP_S, load_tracks, write_gpx, write_kml
from emulator.scenario import load_scenario
from tests.conftest import ROOT, SCENARIOS

KML_XSD = ROOT / "tests" / "vectors" / "kml" / "ogckml22.xsd"
GPX_XSD = ROOT / "tests" / "vectors" / "gpx" / "gpx.xsd"
#: the quickstart, 10 s: still for the alignment, then driving off; a 2 s GNSS outage from 5 s
SCENARIO_EDITS = {
    "duration_s: 120\n": "duration_s: 10\n",
    "  - static: {duration_s: 120}\n": "  - static: {duration_s: 4}\n  - accelerate: {duration_s: 3, to_speed_mps: 6}\n"
                                        "  - cruise: {duration_s: 3}\nfaults:\n"
                                        "  - gnss_outage: {start_s: 5, duration_s: 2}\n",
}


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    text = (SCENARIOS / "quickstart.yaml").read_text(encoding="utf-8")
    for old, new in SCENARIO_EDITS.items():
        assert old in text
        text = text.replace(old, new)
    text = text.split("expectations:")[0]
    d = tmp_path_factory.mktemp("tracks")
    path = d / "drive.yaml"
    path.write_text(text, encoding="utf-8")
    run_scenario(load_scenario(path), d / "run")
    return d / "run"


def _csv(path):
    with open(path, newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


def test_tracks_hold_truth_estimate_and_the_fault(run_dir):
    tr = load_tracks(run_dir)
    truth = _csv(run_dir / "truth.csv")
    assert tr.truth[0][0] == float(truth[0]["time_s"]) and tr.truth[-1][0] == float(truth[-1]["time_s"])
    assert len(tr.truth) == pytest.approx(10.0 / TRACK_STEP_S, abs=2)
    gaps = [b[0] - a[0] for a, b in zip(tr.truth, tr.truth[1:-1])]
    assert min(gaps) >= TRACK_STEP_S - 1e-9
    assert [nav for nav, _ in tr.estimate][:2] == [False, True]  # aligning, then navigating
    assert [(f.kind, f.start_s, f.end_s) for f in tr.faults] == [("gnss_outage", 5.0, 7.0)]


def test_kml_is_valid_against_the_ogc_schema(run_dir, tmp_path):
    schema = xmlschema.XMLSchema(str(KML_XSD))  # imports atom-author-link.xsd and xAL.xsd beside it
    path = write_kml(load_tracks(run_dir), tmp_path / "t.kml")
    schema.validate(str(path))
    root = ET.parse(path).getroot()
    q = f"{{{KML_NS}}}"
    names = [e.text for e in root.iter(f"{q}name")]
    assert "truth" in names and "gnss_outage" in names
    fault = next(pm for pm in root.iter(f"{q}Placemark") if pm.findtext(f"{q}name") == "gnss_outage")
    assert fault.findtext(f"{q}TimeSpan/{q}begin") == "2019-09-18T08:14:05.000Z"
    assert fault.findtext(f"{q}TimeSpan/{q}end") == "2019-09-18T08:14:07.000Z"
    # a broken document is caught (the schema check can fail)
    bad = path.read_text().replace("<LineString>", "<LineString><bogus/>", 1)
    (tmp_path / "bad.kml").write_text(bad)
    assert not schema.is_valid(str(tmp_path / "bad.kml"))


@pytest.mark.filterwarnings("ignore:Package `lxml` missing")
def test_kml_reads_back_with_fastkml(run_dir, tmp_path):
    from fastkml import kml

    tr = load_tracks(run_dir)
    doc = kml.KML.parse(str(write_kml(tr, tmp_path / "t.kml")))

    def placemarks(node):
        for f in getattr(node, "features", None) or []:
            yield from ([f] if type(f).__name__ == "Placemark" else placemarks(f))

    pms = {p.name: p for p in placemarks(doc)}
    truth = [(lo, la, h) for _t, la, lo, h in tr.truth]
    # pygeoif's LineString keeps one of each run of equal points (the box stands still for 4 s)
    assert list(pms["truth"].geometry.coords) == [c for i, c in enumerate(truth) if i == 0 or c != truth[i - 1]]
    est = [p for name, p in pms.items() if name.startswith("estimate")]
    assert len(est) == len(tr.estimate) >= 2
    assert list(est[-1].geometry.coords)[-1] == (tr.estimate[-1][1][-1][2], tr.estimate[-1][1][-1][1],
                                                 tr.estimate[-1][1][-1][3])
    fault = pms["gnss_outage"]
    epoch = _dt.datetime(2019, 9, 18, 8, 14, tzinfo=_dt.UTC)
    assert fault.times.begin.dt == epoch + _dt.timedelta(seconds=5)
    assert fault.times.end.dt == epoch + _dt.timedelta(seconds=7)


def test_gpx_is_valid_against_the_topografix_schema(run_dir, tmp_path):
    schema = xmlschema.XMLSchema(str(GPX_XSD))
    assert schema.target_namespace == "http://www.topografix.com/GPX/1/1"
    path = write_gpx(load_tracks(run_dir), tmp_path / "t.gpx")
    schema.validate(str(path))
    doc = schema.to_dict(str(path))
    assert [t["name"] for t in doc["trk"]] == ["truth", "estimate"]
    assert [w["type"] for w in doc["wpt"]] == ["fault", "fault"]
    # a broken document is caught: an element out of the schema's order, a latitude out of range
    text = path.read_text()
    for old, new in (("<ele>", "<bogus/><ele>"), ('lat="', 'lat="9')):
        (tmp_path / "bad.gpx").write_text(text.replace(old, new, 1))
        assert not schema.is_valid(str(tmp_path / "bad.gpx")), old


def test_gpx_reads_back_with_the_runs_points(run_dir, tmp_path):
    tr = load_tracks(run_dir)
    path = write_gpx(tr, tmp_path / "t.gpx")
    with open(path, encoding="utf-8") as f:
        g = gpxpy.parse(f)
    assert g.version == "1.1"
    by_name = {t.name: t for t in g.tracks}
    truth = [p for s in by_name["truth"].segments for p in s.points]
    assert [(p.latitude, p.longitude, p.elevation) for p in truth] == [(la, lo, h) for _t, la, lo, h in tr.truth]
    epoch = _dt.datetime(2019, 9, 18, 8, 14, tzinfo=_dt.UTC)
    assert truth[-1].time == epoch + _dt.timedelta(milliseconds=round(tr.truth[-1][0] * 1000))
    est = by_name["estimate"].segments
    assert len(est) == len(tr.estimate) >= 2
    nav = _csv(run_dir / "nav.csv")
    assert (est[-1].points[-1].latitude, est[-1].points[-1].longitude) == (float(nav[-1]["lat_deg"]),
                                                                           float(nav[-1]["lon_deg"]))
    assert [w.name for w in g.waypoints] == ["gnss_outage start", "gnss_outage end"]
    assert g.waypoints[0].time == epoch + _dt.timedelta(seconds=5)
    # the box drove off: the truth track moved by about 6 m/s * (3 s / 2 + 3 s) = 27 m
    assert truth[0].distance_2d(truth[-1]) == pytest.approx(27.0, abs=1.0)
