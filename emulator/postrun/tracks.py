"""KML and GPX tracks of a run: truth and the estimate, with the faults, for Google Earth, QGIS and GPS tools.

Read from the run directory (truth.csv, nav.csv, events.jsonl, summary.json's epoch), so any run, old or new,
exports (``psns-hil export RUN --kml / --gpx``):

* the **truth** track, and the **estimate** split into segments where the firmware navigates (frames whose error
  against truth is defined, nav.csv's ``err_*`` cells) and where it does not (alignment, a reset, an outage of
  the output);
* each **fault** (``fault_start`` / ``fault_end`` events, :mod:`emulator.faults`) as a placemark at the truth
  position where it began (KML: with its time span and the truth segment it covers; GPX: a waypoint at its start
  and at its end).

Points are thinned to at most one per :data:`TRACK_STEP_S` (s) of scenario time (the first and last point of each
segment are kept); times are UTC, the scenario's epoch plus the scenario clock. KML 2.2 (OGC 07-147r2,
``ogckml22.xsd``) and GPX 1.1 (Topografix) are written with the standard library's ElementTree.
"""

from __future__ import annotations

import csv
import datetime as _dt
import json
import math
import xml.etree.ElementTree as ET
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import RecordingError
from ..recording.rundir import open_no_follow

__all__ = ["TRACK_STEP_S", "FaultSpan", "Tracks", "load_tracks", "write_gpx", "write_kml"]

#: thinning of the tracks, s of scenario time between points (10 Hz: a 1 h run stays under 40 000 points)
TRACK_STEP_S = 0.1
KML_NS = "http://www.opengis.net/kml/2.2"
GPX_NS = "http://www.topografix.com/GPX/1/1"

#: one track point: scenario time (s), latitude (deg), longitude (deg), height (m)
Point = tuple[float, float, float, float]


@dataclass
class FaultSpan:
    """A fault from its ``fault_start`` to its ``fault_end`` (scenario s; end None: it lasted to the run's end)."""

    kind: str
    target: str
    start_s: float
    end_s: float | None


@dataclass
class Tracks:
    """A run's tracks: truth, the estimate in segments (navigating or not), the faults, and the UTC epoch."""

    name: str
    epoch: _dt.datetime
    truth: list[Point] = field(default_factory=list)
    #: (navigating, points) per contiguous stretch of frames
    estimate: list[tuple[bool, list[Point]]] = field(default_factory=list)
    faults: list[FaultSpan] = field(default_factory=list)

    def utc(self, t_s: float) -> str:
        """``t_s`` (scenario s) as an ISO 8601 UTC time with milliseconds (xsd:dateTime)."""
        return (self.epoch + _dt.timedelta(seconds=t_s)).strftime("%Y-%m-%dT%H:%M:%S.%f")[:-3] + "Z"

    def truth_at(self, t_s: float) -> Point | None:
        """The first truth point at or after ``t_s`` (the last one past the end), None without truth."""
        for p in self.truth:
            if p[0] >= t_s:
                return p
        return self.truth[-1] if self.truth else None


_POINT_COLUMNS = ("time_s", "lat_deg", "lon_deg", "height_m")
#: scenario times past this (s, about 31 years) are not a run's: left out (a UTC time could not hold them)
_MAX_T_S = 1e9


def _rows(path: Path) -> Iterator[dict[str, str]]:
    """The rows of a CSV file of the run directory (none when it is absent); a file without the point columns
    raises :class:`~emulator.errors.RecordingError`."""
    if not path.exists():
        return
    with open(path, encoding="utf-8", errors="replace", newline="") as f:
        rd = csv.DictReader(f)
        missing = [c for c in _POINT_COLUMNS if c not in (rd.fieldnames or [])]
        if missing:
            raise RecordingError(f"{path}: not a psns-hil track source (no column {', '.join(missing)})")
        yield from rd


def _point(r: dict[str, str]) -> Point | None:
    """A row's (t, lat, lon, h), None when a cell is not a finite number (the row is left out)."""
    try:
        p = (float(r["time_s"]), float(r["lat_deg"]), float(r["lon_deg"]), float(r["height_m"]))
    except (TypeError, ValueError):
        return None
    ok = all(math.isfinite(v) for v in p) and abs(p[0]) < _MAX_T_S and abs(p[1]) <= 90.0 and abs(p[2]) <= 180.0
    return p if ok else None


def _thin(points: list[Point], step: float) -> list[Point]:
    if len(points) <= 2:
        return points
    out = [points[0]]
    for p in points[1:-1]:
        if p[0] - out[-1][0] >= step - 1e-9:
            out.append(p)
    out.append(points[-1])
    return out


def load_tracks(run_dir: Path, step_s: float = TRACK_STEP_S) -> Tracks:
    """The tracks of the run directory ``run_dir`` (see module docstring)."""
    run_dir = Path(run_dir)
    try:
        summary = json.loads((run_dir / "summary.json").read_text(encoding="utf-8"))
        epoch = _dt.datetime.fromisoformat(summary["epoch"]).astimezone(_dt.UTC)
        name = str(summary.get("scenario", run_dir.name))
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise RecordingError(f"{run_dir}: no readable summary.json with the run's epoch ({exc})") from None
    tr = Tracks(name, epoch)
    tr.truth = _thin([p for p in map(_point, _rows(run_dir / "truth.csv")) if p is not None], step_s)
    segs: list[tuple[bool, list[Point]]] = []
    for r in _rows(run_dir / "nav.csv"):
        nav = r.get("err_pos_m", "") != ""
        p = _point(r)
        if p is None:
            continue
        if not segs or segs[-1][0] != nav:
            segs.append((nav, []))
        segs[-1][1].append(p)
    tr.estimate = [(nav, _thin(pts, step_s)) for nav, pts in segs]
    open_faults: dict[tuple[str, int], FaultSpan] = {}
    ev_path = run_dir / "events.jsonl"
    if ev_path.exists():
        with open(ev_path, encoding="utf-8", errors="replace") as f:
            for line in f:
                try:
                    ev = json.loads(line)
                except json.JSONDecodeError:
                    continue  # an interrupted writer's last line
                if not isinstance(ev, dict) or ev.get("source") != "fault":
                    continue
                try:
                    key = (str(ev.get("fault")), int(ev.get("index", -1)))
                    t = float(ev["t_s"])
                except (KeyError, TypeError, ValueError):
                    continue  # not an event this writer wrote
                if not abs(t) < _MAX_T_S:
                    continue
                if ev.get("event") == "fault_start":
                    span = FaultSpan(key[0], str(ev.get("target", "")), t, None)
                    open_faults[key] = span
                    tr.faults.append(span)
                elif ev.get("event") == "fault_end" and key in open_faults:
                    open_faults.pop(key).end_s = t
    return tr


def _coords(points: list[Point]) -> str:
    return " ".join(f"{lon!r},{lat!r},{h!r}" for _t, lat, lon, h in points)


def _sub(parent: ET.Element, tag: str, text: str | None = None, **attrib: str) -> ET.Element:
    e = ET.SubElement(parent, tag, attrib)
    if text is not None:
        e.text = text
    return e


def _kml_line(folder: ET.Element, tr: Tracks, name: str, style: str, points: list[Point]) -> None:
    pm = _sub(folder, "Placemark")
    _sub(pm, "name", name)
    span = _sub(pm, "TimeSpan")
    _sub(span, "begin", tr.utc(points[0][0]))
    _sub(span, "end", tr.utc(points[-1][0]))
    _sub(pm, "styleUrl", f"#{style}")
    ls = _sub(pm, "LineString")
    _sub(ls, "tessellate", "1")
    _sub(ls, "altitudeMode", "absolute")
    _sub(ls, "coordinates", _coords(points))


def _fault_text(f: FaultSpan) -> str:
    end = f"{f.end_s:.3f} s" if f.end_s is not None else "the end of the run"
    return f"fault {f.kind} on {f.target or 'the run'} from {f.start_s:.3f} s to {end} (scenario time)"


def write_kml(tr: Tracks, path: Path) -> Path:
    """Write ``tr`` as KML 2.2 to ``path``: a Document with the truth, estimate and fault folders."""
    ET.register_namespace("", KML_NS)
    q = f"{{{KML_NS}}}"
    root = ET.Element(f"{q}kml")
    doc = _sub(root, "Document")
    _sub(doc, "name", f"psns-hil {tr.name}")
    for sid, color, width in (("truth", "ff00ff00", "3"), ("navigating", "ff0000ff", "2"),
                              ("not_navigating", "ff00a5ff", "2"), ("fault", "ff00ffff", "5")):
        st = _sub(doc, "Style", id=sid)
        ls = _sub(st, "LineStyle")
        _sub(ls, "color", color)
        _sub(ls, "width", width)
    if tr.truth:
        folder = _sub(doc, "Folder")
        _sub(folder, "name", "truth")
        _kml_line(folder, tr, "truth", "truth", tr.truth)
    folder = _sub(doc, "Folder")
    _sub(folder, "name", "estimate")
    for i, (nav, pts) in enumerate(tr.estimate):
        if pts:
            _kml_line(folder, tr, f"estimate {i + 1} ({'navigating' if nav else 'not navigating'})",
                      "navigating" if nav else "not_navigating", pts)
    if tr.faults:
        folder = _sub(doc, "Folder")
        _sub(folder, "name", "faults")
        for f in tr.faults:
            p = tr.truth_at(f.start_s)
            if p is None:
                continue
            pm = _sub(folder, "Placemark")
            _sub(pm, "name", f.kind)
            _sub(pm, "description", _fault_text(f))
            span = _sub(pm, "TimeSpan")
            _sub(span, "begin", tr.utc(f.start_s))
            if f.end_s is not None:
                _sub(span, "end", tr.utc(f.end_s))
            _sub(pm, "styleUrl", "#fault")
            end = f.end_s if f.end_s is not None else float("inf")
            during = [q_ for q_ in tr.truth if f.start_s <= q_[0] <= end]
            if len(during) >= 2:  # the stretch of the truth track the fault covers
                mg = _sub(pm, "MultiGeometry")
                _sub(_sub(mg, "Point"), "coordinates", _coords([p]))
                _sub(_sub(mg, "LineString"), "coordinates", _coords(during))
            else:
                _sub(_sub(pm, "Point"), "coordinates", _coords([p]))
    for e in root.iter():  # every element in the KML namespace
        if not e.tag.startswith("{"):
            e.tag = q + e.tag
    return _write(root, path)


def write_gpx(tr: Tracks, path: Path) -> Path:
    """Write ``tr`` as GPX 1.1 to ``path``: fault waypoints, then the truth track and the estimate track (one
    ``trkseg`` per segment; GPX ``ele`` carries the height above the ellipsoid, as the run does)."""
    ET.register_namespace("", GPX_NS)
    q = f"{{{GPX_NS}}}"
    root = ET.Element(f"{q}gpx", {"version": "1.1", "creator": "psns-hil"})
    meta = _sub(root, "metadata")
    _sub(meta, "name", f"psns-hil {tr.name}")
    _sub(meta, "time", tr.utc(0.0))

    def pt(parent: ET.Element, tag: str, p: Point) -> ET.Element:
        e = _sub(parent, tag, lat=repr(p[1]), lon=repr(p[2]))
        _sub(e, "ele", repr(p[3]))
        _sub(e, "time", tr.utc(p[0]))
        return e

    for f in tr.faults:
        for which, t in (("start", f.start_s), ("end", f.end_s)):
            p = tr.truth_at(t) if t is not None else None
            if p is None or t is None:
                continue
            w = pt(root, "wpt", (t, p[1], p[2], p[3]))  # at the fault's time, where truth was then
            _sub(w, "name", f"{f.kind} {which}")
            _sub(w, "desc", _fault_text(f))
            _sub(w, "type", "fault")
    for name, segs in (("truth", [(True, tr.truth)] if tr.truth else []), ("estimate", tr.estimate)):
        if not segs:
            continue
        trk = _sub(root, "trk")
        _sub(trk, "name", name)
        for nav, pts in segs:
            seg = _sub(trk, "trkseg")
            for p in pts:
                e = pt(seg, "trkpt", p)
                if name == "estimate" and not nav:
                    _sub(e, "type", "not navigating")
    for e in root.iter():
        if not e.tag.startswith("{"):
            e.tag = q + e.tag
    return _write(root, path)


def _write(root: ET.Element, path: Path) -> Path:
    ET.indent(root, space=" ")
    with open_no_follow(Path(path), "wb") as f:
        ET.ElementTree(root).write(f, encoding="UTF-8", xml_declaration=True)
    return Path(path)
