"""``run.mcap``: a run directory as an MCAP file that Foxglove (and any MCAP reader) opens.

Written with the ``mcap`` library (D-7.15, docs/decisions/emulator-runtime.md) from what the recorder's taps wrote
into the run directory: the capture (every chunk on every tapped link), nav.csv / truth.csv / psns.csv, timeline.csv,
filter_state.csv, events.jsonl and summary.json. Nothing here reaches into a device: the recorder is a listener on
the links and devices, and this module reads only its files, so a finished run and an old run directory
(``psns-hil export RUN --mcap``) convert the same way. The conversion, :class:`RunFeeds`, takes the files
incrementally and is shared with the live view (:mod:`emulator.postrun.live`, D-7.28), so both carry the channel
set declared once in :data:`TOPICS`.

Messages are JSON (``message_encoding`` ``json``) with a JSON Schema each (``schema encoding`` ``jsonschema``):
the Foxglove well-known schemas where one fits (``foxglove.LocationFix``, ``foxglove.PoseInFrame``,
``foxglove.FrameTransform``, ``foxglove.Log``; field names and types of Foxglove's published definitions), a
``psns_hil.*`` schema of the table's columns where none does. Log time is the scenario clock (ns since the run's
start; the run's UTC epoch is in the ``psns-hil`` metadata record); a navigation frame is logged at its time of
validity and published at its arrival on the host port.

Topics (:data:`TOPICS`; README, "Run directory"):

* ``/nav/solution`` every nav.csv row; ``/nav/location`` (LocationFix, ENU position covariance from the filter's
  sigmas, diagonal known); ``/nav/pose`` (PoseInFrame, attitude as ``C_b^n``, ENU offset from the first truth
  position); ``/nav/error`` the error against truth per component beside the filter's sigma of that component;
* ``/truth/state``, ``/truth/location``, ``/truth/pose``; ``/tf`` (FrameTransform ``enu`` -> ``body`` and
  ``enu`` -> ``body_truth``);
* ``/imu``, ``/gnss/epoch``, ``/gnss/fix`` (LocationFix), ``/psns/frames``: the decoded sensor streams
  (:mod:`emulator.postrun.sensor_tables`); ``/psns/aop_image`` (foxglove.RawImage, 1 Hz): the angle of
  polarization the camera reported at its observation points, on the sensor (:func:`aop_image`);
  ``/psns/solar_vector``: the solved solar vector against the true one;
* ``/links/counters`` (timeline.csv: link counters and DSP load), ``/dsp/filter_state`` (mode, covariance
  diagonal, biases), ``/events`` (foxglove.Log: modes, faults, rejections), ``/expectations``;
* ``/raw/<link>/<in|out>``: every capture chunk, base64 in JSON, so the MCAP alone can be decoded again.
"""

from __future__ import annotations

import base64
import csv
import json
import math
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from itertools import pairwise
from pathlib import Path
from typing import IO, Any, Protocol, TypeGuard

from mcap.writer import Writer

from protocols import __version__ as VERSION
from protocols.constants import DEG
from protocols.host import NavMode, describe_nav_mode
from protocols.psns import PolarizationObs, PolarizationObsPacked

from ..devices.camera.geometry import IMX250MZR_NX, IMX250MZR_NY
from ..errors import RecordingError
from ..recording.capture import CaptureRecord, iter_capture
from ..recording.nav_error import _c_bn
from ..recording.rundir import open_no_follow
from ..world.geodesy import radii
from .sensor_tables import SensorDecoder, gyro_is_rate

__all__ = ["CAMPAIGN_MCAP_NAME", "CAMPAIGN_TOPICS", "CSV_SOURCES", "MCAP_NAME", "RAW_SCHEMA", "SENSOR_SOURCES",
           "TOPICS", "McapStats", "MessageSink", "RunFeeds", "attitude_quaternion", "channel_schema", "encode_message",
           "read_summary", "write_campaign_mcap", "write_run_mcap"]

MCAP_NAME = "run.mcap"
#: the campaign's summary series, beside its members' run directories (:func:`write_campaign_mcap`)
CAMPAIGN_MCAP_NAME = "campaign.mcap"

_TIME = {"type": "object", "title": "time", "properties": {"sec": {"type": "integer", "minimum": 0},
                                                           "nsec": {"type": "integer", "minimum": 0,
                                                                    "maximum": 999999999}}}
_VEC3 = {"type": "object", "title": "foxglove.Vector3",
         "properties": {k: {"type": "number"} for k in "xyz"}, "required": list("xyz")}
_QUAT = {"type": "object", "title": "foxglove.Quaternion",
         "properties": {k: {"type": "number"} for k in "xyzw"}, "required": list("xyzw")}
#: the Foxglove well-known schemas used here (their published JSON Schema definitions' fields)
FOXGLOVE_SCHEMAS: dict[str, dict[str, Any]] = {
    "foxglove.LocationFix": {
        "title": "foxglove.LocationFix", "type": "object",
        "properties": {"timestamp": _TIME, "frame_id": {"type": "string"}, "latitude": {"type": "number"},
                       "longitude": {"type": "number"}, "altitude": {"type": "number"},
                       "position_covariance": {"type": "array", "items": {"type": "number"}, "minItems": 9,
                                               "maxItems": 9},
                       "position_covariance_type": {"title": "foxglove.PositionCovarianceType",
                                                    "oneOf": [{"title": t, "const": i} for i, t in enumerate(
                                                        ("UNKNOWN", "APPROXIMATED", "DIAGONAL_KNOWN", "KNOWN"))]},
                       "heading": {"type": "number"}, "velocity": _VEC3},
        "required": ["timestamp", "frame_id", "latitude", "longitude", "altitude", "position_covariance",
                     "position_covariance_type"]},
    "foxglove.PoseInFrame": {
        "title": "foxglove.PoseInFrame", "type": "object",
        "properties": {"timestamp": _TIME, "frame_id": {"type": "string"},
                       "pose": {"type": "object", "title": "foxglove.Pose",
                                "properties": {"position": _VEC3, "orientation": _QUAT},
                                "required": ["position", "orientation"]}},
        "required": ["timestamp", "frame_id", "pose"]},
    "foxglove.FrameTransform": {
        "title": "foxglove.FrameTransform", "type": "object",
        "properties": {"timestamp": _TIME, "parent_frame_id": {"type": "string"},
                       "child_frame_id": {"type": "string"}, "translation": _VEC3, "rotation": _QUAT},
        "required": ["timestamp", "parent_frame_id", "child_frame_id", "translation", "rotation"]},
    "foxglove.RawImage": {
        "title": "foxglove.RawImage", "type": "object",
        "properties": {"timestamp": _TIME, "frame_id": {"type": "string"}, "width": {"type": "integer", "minimum": 0},
                       "height": {"type": "integer", "minimum": 0}, "encoding": {"type": "string"},
                       "step": {"type": "integer", "minimum": 0},
                       "data": {"type": "string", "contentEncoding": "base64"}},
        "required": ["timestamp", "frame_id", "width", "height", "encoding", "step", "data"]},
    "foxglove.Log": {
        "title": "foxglove.Log", "type": "object",
        "properties": {"timestamp": _TIME,
                       "level": {"title": "foxglove.LogLevel",
                                 "oneOf": [{"title": t, "const": i} for i, t in enumerate(
                                     ("UNKNOWN", "DEBUG", "INFO", "WARNING", "ERROR", "FATAL"))]},
                       "message": {"type": "string"}, "name": {"type": "string"}, "file": {"type": "string"},
                       "line": {"type": "integer", "minimum": 0}},
        "required": ["timestamp", "level", "message", "name", "file", "line"]},
}

#: topic -> schema name (``foxglove.*`` above, or a ``psns_hil.*`` schema made from the source's columns)
TOPICS: dict[str, str] = {
    "/nav/solution": "psns_hil.NavSolution", "/nav/location": "foxglove.LocationFix",
    "/nav/pose": "foxglove.PoseInFrame", "/nav/error": "psns_hil.NavError", "/nav/mode": "foxglove.Log",
    "/truth/state": "psns_hil.Truth", "/truth/location": "foxglove.LocationFix",
    "/truth/pose": "foxglove.PoseInFrame", "/tf": "foxglove.FrameTransform",
    "/imu": "psns_hil.ImuFrame", "/gnss/epoch": "psns_hil.GnssEpoch", "/gnss/fix": "foxglove.LocationFix",
    "/psns/frames": "psns_hil.PsnsFrame", "/psns/aop_image": "foxglove.RawImage",
    "/psns/solar_vector": "psns_hil.SolarVector",
    "/links/counters": "psns_hil.Timeline", "/dsp/filter_state": "psns_hil.FilterState",
    "/events": "foxglove.Log", "/expectations": "psns_hil.Expectation",
}
#: the campaign's channels (``campaign.mcap``, :func:`write_campaign_mcap`)
CAMPAIGN_TOPICS: dict[str, str] = {"/campaign/members": "psns_hil.CampaignMember",
                                   "/campaign/consistency": "psns_hil.CampaignConsistency"}
#: the schema of the raw-bytes channels ``/raw/<link>/<direction>``
RAW_SCHEMA = "psns_hil.RawBytes"
_RAW_SCHEMA_DEF = {"title": RAW_SCHEMA, "type": "object",
                   "description": "One chunk of bytes on a link, as the capture holds it (docs/capture-format.md)",
                   "properties": {"link": {"type": "string"}, "direction": {"type": "string", "enum": ["in", "out"]},
                                  "pitch_s": {"type": ["number", "null"],
                                              "description": "byte spacing on the wire, s (null: the line's)"},
                                  "data": {"type": "string", "contentEncoding": "base64"}},
                   "required": ["link", "direction", "data"]}
#: /nav/error: (error column, sigma column) per component (nav.csv); attitude errors are Euler-angle differences,
#: the attitude sigmas the filter's misalignment sigmas about E, N, U
NAV_ERROR_PAIRS = (("err_pos_e_m", "sig_pos_e_m"), ("err_pos_n_m", "sig_pos_n_m"), ("err_pos_u_m", "sig_pos_u_m"),
                   ("err_vel_e_mps", "sig_vel_e_mps"), ("err_vel_n_mps", "sig_vel_n_mps"),
                   ("err_vel_u_mps", "sig_vel_u_mps"), ("err_pitch_deg", "sig_att_e_deg"),
                   ("err_roll_deg", "sig_att_n_deg"), ("err_heading_deg", "sig_att_u_deg"))
RAW_PREFIX = "/raw/"
_DEGRADED = int(NavMode.DEGRADED)
_LOG_LEVEL = {"fault": 3, "error": 4, "reject": 3, "watchdog": 4, "deadline": 3, "timeout": 3}


def channel_schema(topic: str, topics: dict[str, str] = TOPICS) -> str:
    """The schema name of ``topic``: :data:`TOPICS` (the channel set, declared once for ``run.mcap`` and the live
    view), :data:`RAW_SCHEMA` for ``/raw/<link>/<direction>``; a topic declared nowhere raises ``KeyError``."""
    if topics is TOPICS and topic.startswith(RAW_PREFIX):
        return RAW_SCHEMA
    return topics[topic]


@dataclass
class McapStats:
    """What :func:`write_run_mcap` wrote: messages per topic, the file and the wall time it took (s)."""

    path: Path
    messages: dict[str, int] = field(default_factory=dict)
    wall_s: float = 0.0


def attitude_quaternion(roll_deg: float, pitch_deg: float, heading_deg: float) -> tuple[float, float, float, float]:
    """``(x, y, z, w)`` of ``C_b^n`` (body x right, y forward, z up -> ENU; heading clockwise from North; the
    recorder's convention, ``nav_error._c_bn`` with yaw = -heading), by Shepperd's method (w >= 0)."""
    m = _c_bn(pitch_deg * DEG, roll_deg * DEG, -heading_deg * DEG)
    r00, r01, r02, r10, r11, r12, r20, r21, r22 = m
    tr = r00 + r11 + r22
    if tr > 0.0:
        s = 2.0 * math.sqrt(1.0 + tr)
        w, x, y, z = 0.25 * s, (r21 - r12) / s, (r02 - r20) / s, (r10 - r01) / s
    elif r00 > r11 and r00 > r22:
        s = 2.0 * math.sqrt(1.0 + r00 - r11 - r22)
        w, x, y, z = (r21 - r12) / s, 0.25 * s, (r01 + r10) / s, (r02 + r20) / s
    elif r11 > r22:
        s = 2.0 * math.sqrt(1.0 + r11 - r00 - r22)
        w, x, y, z = (r02 - r20) / s, (r01 + r10) / s, 0.25 * s, (r12 + r21) / s
    else:
        s = 2.0 * math.sqrt(1.0 + r22 - r00 - r11)
        w, x, y, z = (r10 - r01) / s, (r02 + r20) / s, (r12 + r21) / s, 0.25 * s
    if w < 0.0:
        w, x, y, z = -w, -x, -y, -z
    return x, y, z, w


def _ns(t_s: float) -> int:
    return max(0, round(t_s * 1e9))


def _stamp(t_s: float) -> dict[str, int]:
    ns = _ns(t_s)
    return {"sec": ns // 1_000_000_000, "nsec": ns % 1_000_000_000}


def _num(cell: str) -> int | float | str | None:
    """A CSV cell as the number it was written from (exact: Python writes floats by ``repr``), None when empty."""
    if cell == "":
        return None
    if cell.isdigit() or (cell[0] == "-" and cell[1:].isdigit()):  # an int (no exception on the float path)
        return int(cell)
    try:
        return float(cell)
    except ValueError:
        return cell


def _read_csv(path: Path) -> tuple[list[str], Iterator[list[str]]]:
    if not path.exists():
        return [], iter(())
    f = open(path, encoding="utf-8", newline="")  # noqa: SIM115 - closed by the generator
    rd = csv.reader(f)
    cols = next(rd, [])

    def gen() -> Iterator[list[str]]:
        with f:
            yield from rd
    return cols, gen()


def _columns_schema(name: str, columns: list[str], description: str) -> dict[str, Any]:
    return {"title": name, "type": "object", "description": description,
            "properties": {c: {"type": ["number", "string", "null"]} for c in columns}}


class _Enu:
    """ENU offsets (m) from an origin, on the WGS-84 ellipsoid's local radii (good to ~1e-4 of the distance within
    tens of km: the viewer's 3-D scene, not a measurement)."""

    def __init__(self, lat_deg: float, lon_deg: float, h_m: float) -> None:
        rm, rn = radii(lat_deg * DEG)
        self.rm, self.rn = float(rm), float(rn)
        self.lat0, self.lon0, self.h0 = lat_deg, lon_deg, h_m
        self.coslat = math.cos(lat_deg * DEG)

    def __call__(self, lat_deg: float, lon_deg: float, h_m: float) -> dict[str, float]:
        return {"x": (lon_deg - self.lon0) * DEG * (self.rn + self.h0) * self.coslat,
                "y": (lat_deg - self.lat0) * DEG * (self.rm + self.h0), "z": h_m - self.h0}


class MessageSink(Protocol):
    """Where :class:`RunFeeds` puts its messages: ``run.mcap``'s gatherer (:func:`write_run_mcap`) or the live
    server (:class:`emulator.postrun.live.LiveServer`). ``schemas`` holds each schema's JSON Schema by name (filled
    by the feeds as they learn a file's columns); ``add`` takes one message at log time ``log_s`` (scenario s) and
    publish time ``publish_s`` (s; None: the log time) on a topic of the channel set (:func:`channel_schema`)."""

    schemas: dict[str, dict[str, Any]]

    def add(self, topic: str, log_s: float, msg: dict[str, Any], publish_s: float | None = None) -> None: ...


class _Out:
    """Messages gathered per topic, written time-ordered at the end."""

    def __init__(self, topics: dict[str, str] = TOPICS) -> None:
        self.msgs: list[tuple[int, int, str, bytes, int]] = []
        self.schemas: dict[str, dict[str, Any]] = {**FOXGLOVE_SCHEMAS, RAW_SCHEMA: _RAW_SCHEMA_DEF}
        self.topic_schema: dict[str, str] = {}
        self.topics = topics

    def add(self, topic: str, log_s: float, msg: dict[str, Any], publish_s: float | None = None) -> None:
        if topic not in self.topic_schema:
            self.topic_schema[topic] = channel_schema(topic, self.topics)
        log = _ns(log_s)
        self.msgs.append((log, len(self.msgs), topic, encode_message(msg), _ns(publish_s) if publish_s is not None
                          else log))


_ENCODER = json.JSONEncoder(separators=(",", ":"), allow_nan=False)


def encode_message(msg: dict[str, Any]) -> bytes:
    """A message as its channel carries it: compact, strict JSON (UTF-8)."""
    return _ENCODER.encode(msg).encode()


def _finite(v: Any) -> Any:
    return v if not isinstance(v, float) or math.isfinite(v) else None


def _location(t: float, lat: float, lon: float, h: float, sig: tuple[float, float, float] | None,
              frame: str, heading_deg: float | None = None, vel: tuple[Any, Any, Any] | None = None
              ) -> dict[str, Any]:
    cov = [0.0] * 9
    if sig is not None:
        cov[0], cov[4], cov[8] = sig[0] ** 2, sig[1] ** 2, sig[2] ** 2
    msg: dict[str, Any] = {"timestamp": _stamp(t), "frame_id": frame, "latitude": lat, "longitude": lon,
                           "altitude": h, "position_covariance": cov,
                           "position_covariance_type": 2 if sig is not None else 0}
    if isinstance(heading_deg, float | int):
        msg["heading"] = heading_deg * DEG
    if vel is not None and all(isinstance(v, float | int) for v in vel):
        msg["velocity"] = {"x": vel[0], "y": vel[1], "z": vel[2]}
    return msg


def _pose_msgs(out: MessageSink, pose_topic: str, child: str, t: float, r: dict[str, Any], enu: _Enu | None,
               publish: float | None = None) -> None:
    if any(not isinstance(r.get(k), float | int) for k in ("roll_deg", "pitch_deg", "heading_deg", "lat_deg")):
        return
    x, y, z, w = attitude_quaternion(r["roll_deg"], r["pitch_deg"], r["heading_deg"])
    pos = enu(r["lat_deg"], r["lon_deg"], r["height_m"]) if enu is not None else {"x": 0.0, "y": 0.0, "z": 0.0}
    q = {"x": x, "y": y, "z": z, "w": w}
    out.add(pose_topic, t, {"timestamp": _stamp(t), "frame_id": "enu", "pose": {"position": pos, "orientation": q}},
            publish)
    out.add("/tf", t, {"timestamp": _stamp(t), "parent_frame_id": "enu", "child_frame_id": child,
                       "translation": pos, "rotation": q}, publish)


#: the run directory's CSV files, in the order they are read (truth before nav: the ENU origin of the poses), with
#: the topic of their rows and the description of its schema (made from the file's columns)
CSV_SOURCES: dict[str, tuple[str, str]] = {
    "truth.csv": ("/truth/state", "truth.csv: the trajectory at the nav frames' times of validity (deg, m, m/s)"),
    "nav.csv": ("/nav/solution", "nav.csv: one NAV_SOLUTION as the host received it, with its error against truth "
                "(deg, m, m/s; sig_* the filter's 1-sigma; empty errors: not navigating)"),
    "psns.csv": ("/psns/solar_vector", "psns.csv: the solved solar vector (body, unit) against the true one, "
                 "errors (deg)"),
    "timeline.csv": ("/links/counters", "timeline.csv: cumulative link counters, DSP CPU load (%) and deadline "
                     "misses, 1 Hz"),
    "filter_state.csv": ("/dsp/filter_state", "filter_state.csv: firmware mode, covariance diagonal, bias "
                         "estimates, 1 Hz"),
}
#: the decoded sensor streams (:data:`~emulator.postrun.sensor_tables.SENSOR_TABLES`): topic and description
SENSOR_SOURCES: dict[str, tuple[str, str]] = {
    "imu.csv": ("/imu", "One FPGA IMU frame (UART1): STIM210 gyro words scaled (deg/s or deg), accelerometer ADC "
                "codes at the nominal scale (g); t_rx_s scenario s"),
    "gnss.csv": ("/gnss/epoch", "One GNSS epoch (GGA/GNS or UBX-NAV-PVT) as received on the GNSS port (deg, m, m/s)"),
    "psns_frames.csv": ("/psns/frames", "One frame on the PSNS port: header and, for a solar-vector frame, the "
                        "vector and its quality"),
}
#: the columns the conversion needs in a CSV file (the rest are carried as they are); others: ``time_s``
_REQUIRED_COLUMNS = {name: ("time_s", "lat_deg", "lon_deg", "height_m") for name in ("truth.csv", "nav.csv")}


#: log times past this (s, about 31 years; MCAP's u64 ns end near 585 years) are not a run's: left out
_MAX_LOG_S = 1e9


def _time_ok(t: Any) -> TypeGuard[float]:
    """Whether ``t`` is a scenario time a message can be logged at (a finite number, |t| < :data:`_MAX_LOG_S`)."""
    return isinstance(t, float | int) and not isinstance(t, bool) and abs(t) < _MAX_LOG_S


def _has_position(r: dict[str, Any]) -> bool:
    """Whether row ``r`` has a position (finite numbers, latitude and longitude in range) to place on a map."""
    lat, lon, h = r.get("lat_deg"), r.get("lon_deg"), r.get("height_m")
    return isinstance(lat, float | int) and isinstance(lon, float | int) and isinstance(h, float | int) and \
        abs(lat) <= 90.0 and abs(lon) <= 180.0


def _sig3(sigma_column: str) -> str:
    """The /nav/error field of a sigma column's 3-sigma bound: ``sig_pos_e_m`` -> ``sig3_pos_e_m``."""
    return "sig3_" + sigma_column.removeprefix("sig_")


EVENTS_FILE, CAPTURE_FILE, SUMMARY_FILE = "events.jsonl", "capture.psnscap", "summary.json"
_NAV_ERROR_SCHEMA: dict[str, Any] = {
    "title": "psns_hil.NavError", "type": "object",
    "properties": {"timestamp": _TIME, **{c: {"type": ["number", "null"]} for pair in NAV_ERROR_PAIRS for c in pair},
                   **{_sig3(s): {"type": ["number", "null"]} for _e, s in NAV_ERROR_PAIRS}},
    "description": "The error against truth per component beside the filter's 1-sigma of that component and its "
                   "3-sigma bound sig3_* (plot err inside +-sig3); null errors: the frame is not navigating"}
_EXPECTATION_SCHEMA: dict[str, Any] = {
    "title": "psns_hil.Expectation", "type": "object",
    "description": "One of the scenario's expectations as evaluated at the end of the run (summary.json)",
    "properties": {"timestamp": _TIME, "index": {"type": "integer"}, "passed": {"type": "boolean"},
                   "result": {"type": "object"}}}


class RunFeeds:
    """A run directory's files as messages on the channel set (:data:`TOPICS`), fed incrementally: one conversion
    for ``run.mcap`` (:func:`write_run_mcap` hands it each file whole) and the live view (:mod:`.live` hands it the
    lines and records the recorder has flushed so far), so the two carry the same channels and the same values.

    CSV files (:data:`CSV_SOURCES`): :meth:`csv_header` with the first line's cells, then :meth:`csv_row` per line;
    the capture: :meth:`capture_header`, then :meth:`capture_record` per record; events.jsonl: :meth:`event_line`;
    summary.json: :meth:`summary`."""

    def __init__(self, out: MessageSink) -> None:
        self.out = out
        out.schemas.update(FOXGLOVE_SCHEMAS)
        out.schemas[RAW_SCHEMA] = _RAW_SCHEMA_DEF
        out.schemas["psns_hil.NavError"] = _NAV_ERROR_SCHEMA
        out.schemas["psns_hil.Expectation"] = _EXPECTATION_SCHEMA
        #: the ENU origin of the poses: the first truth row
        self.enu: _Enu | None = None
        self.header: dict[str, Any] = {}
        self._cols: dict[str, list[str]] = {}
        self._line: dict[str, int] = {}
        self._last_mode: int | None = None
        self._sensors: SensorDecoder | None = None
        self._next_image = 0.0
        self._event_line = 0

    # -- CSV files ---------------------------------------------------------------------------------
    def csv_header(self, name: str, cols: list[str]) -> None:
        """The header of CSV file ``name`` (a key of :data:`CSV_SOURCES`): its topic's schema. A header without the
        columns the conversion needs raises :class:`~emulator.errors.RecordingError`."""
        missing = [c for c in _REQUIRED_COLUMNS.get(name, ("time_s",)) if c not in cols]
        if missing:
            raise RecordingError(f"{name}: not a psns-hil {name} (no column {', '.join(missing)})")
        topic, description = CSV_SOURCES[name]
        schema = TOPICS[topic]
        self.out.schemas[schema] = _columns_schema(schema, cols, description)
        self._cols[name], self._line[name] = cols, 1

    def csv_row(self, name: str, cells: list[str]) -> None:
        """One data line of CSV file ``name``, after its :meth:`csv_header` (a non-finite cell becomes null; a row
        without a time is skipped, one without a position has no location or pose)."""
        self._line[name] += 1
        r: dict[str, Any] = {c: _finite(_num(v)) for c, v in zip(self._cols[name], cells)}
        t = r.get("time_s")
        if not _time_ok(t):
            return
        if name == "nav.csv":
            self._nav_row(t, r)
        elif name == "truth.csv":
            self._truth_row(t, r)
        else:
            self.out.add(CSV_SOURCES[name][0], t, r)

    def _truth_row(self, t: float, r: dict[str, Any]) -> None:
        out = self.out
        out.add("/truth/state", t, r)
        if not _has_position(r):
            return
        if self.enu is None:
            self.enu = _Enu(r["lat_deg"], r["lon_deg"], r["height_m"])
        out.add("/truth/location", t, _location(t, r["lat_deg"], r["lon_deg"], r["height_m"], None, "body_truth",
                                                r.get("heading_deg"), (r.get("vel_e_mps"), r.get("vel_n_mps"),
                                                                       r.get("vel_u_mps"))))
        _pose_msgs(out, "/truth/pose", "body_truth", t, r, self.enu)

    def _nav_row(self, t: float, r: dict[str, Any]) -> None:
        out = self.out
        arr = r.get("arrival_s")
        pub = arr if isinstance(arr, float | int) else None
        out.add("/nav/solution", t, r, pub)
        mode = r.get("mode")
        if isinstance(mode, int) and mode != self._last_mode:  # each change of the mode bits, as a log line
            out.add("/nav/mode", t, {"timestamp": _stamp(t), "level": 3 if mode & _DEGRADED else 2,
                                     "message": describe_nav_mode(mode), "name": "firmware", "file": "nav.csv",
                                     "line": self._line["nav.csv"]})
            self._last_mode = mode
        sig: tuple[Any, Any, Any] = (r.get("sig_pos_e_m"), r.get("sig_pos_n_m"), r.get("sig_pos_u_m"))
        ok = all(isinstance(v, float | int) for v in sig)
        if _has_position(r):
            out.add("/nav/location", t, _location(t, r["lat_deg"], r["lon_deg"], r["height_m"],
                                                  sig if ok else None, "body", r.get("heading_deg"),
                                                  (r.get("vel_e_mps"), r.get("vel_n_mps"), r.get("vel_u_mps"))), pub)
            _pose_msgs(out, "/nav/pose", "body", t, r, self.enu, pub)
        err: dict[str, Any] = {"timestamp": _stamp(t)}
        for e, s in NAV_ERROR_PAIRS:
            one = r.get(s)
            err[e], err[s] = r.get(e), one
            err[_sig3(s)] = 3.0 * one if isinstance(one, float | int) and math.isfinite(one) else None
        out.add("/nav/error", t, err, pub)

    # -- the capture -------------------------------------------------------------------------------
    def capture_header(self, header: dict[str, Any]) -> None:
        """The capture's header (its scenario tells the IMU's output: rate or incremental angle)."""
        self.header = header
        self._sensors = SensorDecoder(gyro_is_rate(header))

    def capture_record(self, r: CaptureRecord) -> None:
        """One capture record: its raw bytes, and the sensor frames it completes (none at an impossible time)."""
        out = self.out
        if not _time_ok(r.t_s):
            return
        out.add(f"{RAW_PREFIX}{r.link}/{r.direction}", r.t_s, {"link": r.link, "direction": r.direction,
                                                                "pitch_s": r.pitch_s,
                                                                "data": base64.b64encode(r.data).decode("ascii")})
        if self._sensors is None:
            self._sensors = SensorDecoder()
        for fr in self._sensors.feed(r):
            topic, text = SENSOR_SOURCES[fr.table]
            schema = TOPICS[topic]
            if schema not in out.schemas:
                out.schemas[schema] = _columns_schema(schema, list(fr.row), text)
            row = {k: _finite(v) for k, v in fr.row.items()}
            out.add(topic, fr.t_rx_s, row)
            if isinstance(fr.frame, PolarizationObs | PolarizationObsPacked) and fr.t_rx_s >= self._next_image:
                w, h, img = aop_image(fr.frame.points)
                out.add("/psns/aop_image", fr.t_rx_s,
                        {"timestamp": _stamp(fr.t_rx_s), "frame_id": "camera", "width": w, "height": h,
                         "encoding": "mono8", "step": w, "data": base64.b64encode(img).decode("ascii")})
                self._next_image = (fr.t_rx_s // AOP_IMAGE_EVERY_S + 1) * AOP_IMAGE_EVERY_S
            if fr.table == "gnss.csv" and isinstance(row.get("lat_deg"), float) and \
                    isinstance(row.get("lon_deg"), float):
                out.add("/gnss/fix", fr.t_rx_s, _location(fr.t_rx_s, row["lat_deg"], row["lon_deg"],
                                                          row.get("height_msl_m") or 0.0, None, "gnss"))

    # -- events and the summary --------------------------------------------------------------------
    def event_line(self, line: str) -> None:
        """One line of events.jsonl (a line that is not an event object is skipped, and counted in the line
        numbers)."""
        self._event_line += 1
        try:
            ev = json.loads(line)
        except json.JSONDecodeError:
            return
        if not isinstance(ev, dict) or not _time_ok(ev.get("t_s")):
            return
        kind = str(ev.get("event", ""))
        rest = {k: v for k, v in ev.items() if k not in ("t_s", "source", "event")}
        level = next((lv for word, lv in _LOG_LEVEL.items() if word in kind), 2)
        self.out.add("/events", ev["t_s"],
                     {"timestamp": _stamp(ev["t_s"]), "level": level,
                      "message": f"{kind} {json.dumps(rest, sort_keys=True, default=str)}" if rest else kind,
                      "name": str(ev.get("source", "")), "file": EVENTS_FILE, "line": self._event_line})

    def summary(self, summary: dict[str, Any]) -> None:
        """summary.json: the expectations' results, at the end of the run."""
        t_end = summary.get("sim_duration_s") or 0.0
        for i, res in enumerate(summary.get("expectations") or []):
            if isinstance(res, dict):
                self.out.add("/expectations", t_end, {"timestamp": _stamp(t_end), "index": i,
                                                      "passed": bool(res.get("passed")), "result": res})


def read_summary(run_dir: Path) -> dict[str, Any] | None:
    """summary.json of ``run_dir`` as a dict (None: absent or not a JSON object)."""
    try:
        summary = json.loads((Path(run_dir) / SUMMARY_FILE).read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError):
        return None
    return summary if isinstance(summary, dict) else None


#: the AoP image: camera pixels per image pixel, and the camera frames per image (1 Hz at the usual 5 Hz)
AOP_IMAGE_BIN = 16
AOP_IMAGE_EVERY_S = 1.0


def aop_image(points: Any, nx: int = IMX250MZR_NX, ny: int = IMX250MZR_NY, binning: int = AOP_IMAGE_BIN
              ) -> tuple[int, int, bytes]:
    """A ``mono8`` image (width, height, bytes) of a POLARIZATION_OBS frame's points on the sensor (``nx`` x ``ny``
    pixels, binned by ``binning``): each point's cell of the observation grid (half the grid's pitch in x and
    in y) painted with its angle of polarization, -90..90 deg -> 1..255; 0 where nothing was observed."""
    w, h = -(-nx // binning), -(-ny // binning)
    img = bytearray(w * h)
    pts = [(p.x_px, p.y_px, p.aop_cdeg) for p in points]

    def half_pitch(values: set[int]) -> int:
        gaps = [b - a for a, b in pairwise(sorted(values))]
        return max(1, min(gaps) // 2) if gaps else binning

    hx, hy = half_pitch({x for x, _, _ in pts}), half_pitch({y for _, y, _ in pts})
    for x, y, aop in pts:
        v = 1 + round((max(-9000, min(9000, aop)) + 9000) / 18000 * 254)
        x0, x1 = max(0, (x - hx) // binning), min(w, (x + hx) // binning + 1)
        y0, y1 = max(0, (y - hy) // binning), min(h, (y + hy) // binning + 1)
        for row in range(y0, y1):
            img[row * w + x0: row * w + x1] = bytes([v]) * (x1 - x0)
    return w, h, bytes(img)


def write_run_mcap(run_dir: Path, out_path: Path | None = None) -> McapStats:
    """Write ``run.mcap`` (or ``out_path``) from the run directory ``run_dir`` (see module docstring)."""
    wall0 = time.perf_counter()
    run_dir = Path(run_dir)
    path = Path(out_path) if out_path is not None else run_dir / MCAP_NAME
    out = _Out()
    feeds = RunFeeds(out)
    for name in CSV_SOURCES:
        cols, rows = _read_csv(run_dir / name)
        if cols:
            feeds.csv_header(name, cols)
            for cells in rows:
                feeds.csv_row(name, cells)
    if (run_dir / CAPTURE_FILE).exists():
        header, records = iter_capture(run_dir / CAPTURE_FILE)
        feeds.capture_header(header)
        for r in records:
            feeds.capture_record(r)
    if (run_dir / EVENTS_FILE).exists():
        with open(run_dir / EVENTS_FILE, encoding="utf-8", errors="replace") as f:
            for line in f:
                feeds.event_line(line)
    summary = read_summary(run_dir) or {}
    feeds.summary(summary)
    header = feeds.header
    meta = {"scenario": str(summary.get("scenario", header.get("scenario", ""))),
            "seed": str(summary.get("seed", header.get("seed", ""))),
            "epoch_utc": str(summary.get("epoch", header.get("epoch", ""))),
            "log_time": "scenario clock, ns since the run's start",
            "psns_hil_version": VERSION}
    stats = McapStats(path)
    stats.messages = _write(out, path, meta)
    stats.wall_s = time.perf_counter() - wall0
    return stats


def _write(out: _Out, path: Path, meta: dict[str, str]) -> dict[str, int]:
    """Write the gathered messages time-ordered into ``path`` with their schemas, channels and the ``psns-hil``
    metadata record; the number of messages per topic."""
    out.msgs.sort()
    f: IO[bytes] = open_no_follow(path, "wb")
    seq: dict[str, int] = {}
    with f:
        w = Writer(f)
        w.start(profile="", library=f"psns-hil {VERSION}")
        schema_ids = {name: w.register_schema(name=name, encoding="jsonschema",
                                              data=json.dumps(defn, sort_keys=True).encode())
                      for name, defn in sorted(out.schemas.items()) if name in set(out.topic_schema.values())}
        chan = {topic: w.register_channel(topic=topic, message_encoding="json", schema_id=schema_ids[schema])
                for topic, schema in sorted(out.topic_schema.items())}
        for log, _i, topic, data, pub in out.msgs:
            n = seq.get(topic, 0)
            seq[topic] = n + 1
            w.add_message(chan[topic], log_time=log, data=data, publish_time=pub, sequence=n)
        w.add_metadata("psns-hil", meta)
        w.finish()
    return seq


def _json_safe(v: Any) -> Any:
    """``v`` with every non-finite float as None (strict JSON), recursively."""
    if isinstance(v, dict):
        return {str(k): _json_safe(x) for k, x in v.items()}
    if isinstance(v, list | tuple):
        return [_json_safe(x) for x in v]
    if isinstance(v, float) and not math.isfinite(v):
        return None
    if isinstance(v, int | float | str | bool) or v is None:
        return v
    return str(v)


def write_campaign_mcap(out_dir: Path, rows: list[dict[str, Any]], info: dict[str, Any],
                        consistency: dict[str, Any] | None = None, metric_columns: list[str] | None = None
                        ) -> McapStats:
    """Write ``campaign.mcap`` into a campaign's directory: its summary series, to open beside the members'
    ``run.mcap`` files (issue 39 item 5).

    Log time is the member's index in seconds (member *i* at *i* s), so a viewer's plot of a field over time is that
    field over the members. Topics: ``/campaign/members`` (``psns_hil.CampaignMember``: index, seed, completed and
    passed, the varied parameters and the envelope's draws, the error metrics of runs.csv, and the member's mean NEES
    per state group, dimensionless, with its mean signed heading error, deg) and, with a consistency check,
    ``/campaign/consistency`` (``psns_hil.CampaignConsistency``, once, after the last member: consistency.json
    without its per-sample series)."""
    wall0 = time.perf_counter()
    path = Path(out_dir) / CAMPAIGN_MCAP_NAME
    out = _Out(CAMPAIGN_TOPICS)
    out.schemas["psns_hil.CampaignMember"] = {
        "title": "psns_hil.CampaignMember", "type": "object",
        "description": "One campaign member: runs.csv's row with the member's mean NEES per state group",
        "properties": {"index": {"type": "integer"}, "seed": {"type": "integer"}, "ok": {"type": "boolean"},
                       "passed": {"type": ["boolean", "null"]}, "params": {"type": "object"},
                       "envelope": {"type": "object"}, "metrics": {"type": "object"},
                       "nees_mean": {"type": "object"},
                       "heading_err_mean_deg": {"type": ["number", "null"]}}}
    out.schemas["psns_hil.CampaignConsistency"] = {
        "title": "psns_hil.CampaignConsistency", "type": "object",
        "description": "The campaign's consistency check (consistency.json without the per-sample series)",
        "properties": {"consistency": {"type": "object"}}}
    cols = list(metric_columns or [])
    for r in rows:
        c = r.get("consistency") or {}
        nees = {g: (float(sum(v) / len(v)) if v else None) for g, v in (c.get("nees") or {}).items()}
        msg = {"index": int(r["index"]), "seed": int(r["seed"]), "ok": bool(r.get("ok")),
               "passed": None if r.get("passed") is None else bool(r["passed"]),
               "params": r.get("params") or {}, "envelope": r.get("envelope") or {},
               "metrics": {k: r.get(k) for k in cols}, "nees_mean": nees,
               "heading_err_mean_deg": c.get("heading_err_mean_deg")}
        out.add("/campaign/members", float(r["index"]), _json_safe(msg))
    if consistency is not None:
        brief = {k: v for k, v in consistency.items() if k != "t"}
        for g in (brief.get("groups") or {}).values():
            if isinstance(g, dict):
                for key in [k for k, v in g.items() if isinstance(v, list) and len(v) > 32]:
                    del g[key]  # per-sample series stay in consistency.json
        t_end = float(max((int(r["index"]) for r in rows), default=0) + 1)
        out.add("/campaign/consistency", t_end, {"consistency": _json_safe(brief)})
    meta = {"scenario": str(info.get("scenario", "")), "campaign_seed": str(info.get("campaign_seed", "")),
            "runs": str(len(rows)), "log_time": "member index, s (member i at i s)", "psns_hil_version": VERSION}
    stats = McapStats(path)
    stats.messages = _write(out, path, meta)
    stats.wall_s = time.perf_counter() - wall0
    return stats
