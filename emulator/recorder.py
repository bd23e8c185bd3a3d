"""The recorder: byte captures, events, navigation output against truth, and the summary.

It is a listener: it subscribes to links (:class:`~emulator.links.base.LinkListener`) and to
device events (:class:`~emulator.devices.base.EventSink`); nothing reaches into a device.

Files in the run directory (written as the run goes, flushed at least once per wall second,
so an interrupted run keeps everything up to the interruption):

``capture.psnscap``
    Every chunk on every tapped link. Format (little-endian): the 9-byte magic
    ``PSNSCAP1\\n``, one JSON header line ``{"version": 1, "links": [...], ...}\\n``, then
    records ``<d t_s> <H link_index> <B direction (0 out, 1 in)> <B reserved> <I length>``
    followed by ``length`` bytes. ``docs/capture-format.md`` has the details.
``events.jsonl``
    One JSON object per event: ``{"t_s", "source", "event", ...}``.
``nav.csv``
    Every decoded NAV_SOLUTION with the error against truth at its time of validity.
``truth.csv``
    Truth at the same times.
``summary.json``
    Written at the end (also after an interruption, with ``"interrupted": true``).
"""

from __future__ import annotations

import csv
import json
import math
import struct
import time as _time
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any, Callable, Sequence

import numpy as np

from firmware_model import earth
from protocols.host import NavMode, NavSolution
from protocols.stream import FrameFormat, StreamDecoder

from .links.base import Link
from .world.trajectory import Trajectory

__all__ = ["CAPTURE_MAGIC", "Recorder", "ErrorStats", "CaptureRecord", "read_capture"]

CAPTURE_MAGIC = b"PSNSCAP1\n"
_REC = struct.Struct("<dHBBI")
DEG = math.pi / 180.0

NAV_COLUMNS = [
    "time_s", "lat_deg", "lon_deg", "height_m", "vel_e_mps", "vel_n_mps", "vel_u_mps",
    "roll_deg", "pitch_deg", "heading_deg",
    "sig_att_e_deg", "sig_att_n_deg", "sig_att_u_deg", "sig_vel_e_mps", "sig_vel_n_mps", "sig_vel_u_mps",
    "sig_pos_n_m", "sig_pos_e_m", "sig_pos_u_m",
    "mode", "gnss_status", "psns_status", "cpu_load_pct", "deadline_misses", "arrival_s",
    "err_att_deg", "err_roll_deg", "err_pitch_deg", "err_heading_deg",
    "err_pos_e_m", "err_pos_n_m", "err_pos_u_m", "err_pos_m",
    "err_vel_e_mps", "err_vel_n_mps", "err_vel_u_mps", "err_vel_mps",
]
TRUTH_COLUMNS = [
    "time_s", "lat_deg", "lon_deg", "height_m", "vel_e_mps", "vel_n_mps", "vel_u_mps",
    "roll_deg", "pitch_deg", "heading_deg",
]


@dataclass
class CaptureRecord:
    t_s: float
    link: str
    direction: str
    data: bytes


def read_capture(path: str | Path) -> tuple[dict[str, Any], list[CaptureRecord]]:
    """Read a ``.psnscap`` file; a truncated last record (interrupted run) is ignored."""
    from .errors import RecordingError

    raw = Path(path).read_bytes()
    if not raw.startswith(CAPTURE_MAGIC):
        raise RecordingError(f"{path}: not a psns-hil capture (bad magic)")
    nl = raw.find(b"\n", len(CAPTURE_MAGIC))
    if nl < 0:
        raise RecordingError(f"{path}: capture header line is incomplete")
    try:
        header = json.loads(raw[len(CAPTURE_MAGIC):nl])
    except json.JSONDecodeError as exc:
        raise RecordingError(f"{path}: line 2, column {exc.colno}: bad capture header: {exc.msg}") from None
    links = header.get("links", [])
    out: list[CaptureRecord] = []
    pos = nl + 1
    while pos + _REC.size <= len(raw):
        t, idx, d, _r, n = _REC.unpack_from(raw, pos)
        pos += _REC.size
        if pos + n > len(raw):
            break
        name = links[idx] if idx < len(links) else f"link{idx}"
        out.append(CaptureRecord(t, name, "out" if d == 0 else "in", raw[pos:pos + n]))
        pos += n
    return header, out


@dataclass
class ErrorStats:
    """Running RMS / max of one error metric."""

    n: int = 0
    sum_sq: float = 0.0
    max: float = 0.0

    def add(self, v: float) -> None:
        self.n += 1
        self.sum_sq += v * v
        self.max = max(self.max, abs(v))

    def as_dict(self) -> dict[str, float | None]:
        if not self.n:
            return {"rms": None, "max": None}
        return {"rms": math.sqrt(self.sum_sq / self.n), "max": self.max}


@dataclass
class _Tap:
    link: Link
    decoders: dict[str, StreamDecoder] = field(default_factory=dict)


def _wrap180(x: float) -> float:
    return (x + 180.0) % 360.0 - 180.0


class Recorder:
    """Writes the run directory (see module docstring).

    Parameters
    ----------
    run_dir : output directory (created).
    trajectory : truth for the error evaluation.
    """

    def __init__(self, run_dir: Path, trajectory: Trajectory, flush_interval_s: float = 1.0) -> None:
        self.run_dir = Path(run_dir)
        self.run_dir.mkdir(parents=True, exist_ok=True)
        self.traj = trajectory
        self._taps: dict[str, _Tap] = {}
        self._link_index: dict[str, int] = {}
        self._cap: IO[bytes] | None = None
        self._events: IO[str] = open(self.run_dir / "events.jsonl", "w", encoding="utf-8")
        self._nav_f: IO[str] = open(self.run_dir / "nav.csv", "w", encoding="utf-8", newline="")
        self._truth_f: IO[str] = open(self.run_dir / "truth.csv", "w", encoding="utf-8", newline="")
        self._nav_w = csv.writer(self._nav_f)
        self._truth_w = csv.writer(self._truth_f)
        self._nav_w.writerow(NAV_COLUMNS)
        self._truth_w.writerow(TRUTH_COLUMNS)
        self.errors = {k: ErrorStats() for k in ("attitude_deg", "heading_deg", "position_m", "velocity_mps")}
        self.error_series: list[tuple[float, float, float, float, float]] = []  # t, att, hdg, pos, vel
        self.nav_count = 0
        self.event_counts: dict[str, int] = {}
        self.events: list[dict[str, Any]] = []
        self.nav_listeners: list[Callable[[float, NavSolution], None]] = []
        self._flush_interval = flush_interval_s
        self._last_flush = _time.monotonic()
        self.last_nav: NavSolution | None = None

    # -- wiring ---------------------------------------------------------------------------
    def tap(self, name: str, link: Link, formats: dict[str, Sequence[FrameFormat]]) -> None:
        """Capture ``link`` under ``name`` and decode its directions with ``formats``."""
        if self._cap is not None:
            raise RuntimeError("tap() after start()")
        t = _Tap(link, {d: StreamDecoder(list(f)) for d, f in formats.items()})
        self._taps[name] = t
        self._link_index[name] = len(self._link_index)
        link.listeners.append(_TapListener(self, name))

    def start(self, header: dict[str, Any]) -> None:
        self._cap = open(self.run_dir / "capture.psnscap", "wb")
        hdr = dict(header)
        hdr["version"] = 1
        hdr["links"] = list(self._link_index)
        self._cap.write(CAPTURE_MAGIC + json.dumps(hdr, sort_keys=True).encode() + b"\n")

    # -- listener callbacks -------------------------------------------------------------------
    def on_bytes(self, name: str, direction: str, t: float, data: bytes) -> None:
        if self._cap is not None:
            self._cap.write(_REC.pack(t, self._link_index[name], 0 if direction == "out" else 1, 0, len(data)) + data)
        dec = self._taps[name].decoders.get(direction)
        if dec is not None:
            for fr in dec.feed(data):
                if isinstance(fr, NavSolution):
                    self._on_nav(t, fr)
        self._maybe_flush()

    def emit(self, t: float, source: str, kind: str, **data: Any) -> None:
        rec = {"t_s": round(t, 9), "source": source, "event": kind}
        rec.update(data)
        self._events.write(json.dumps(rec, default=_json_default) + "\n")
        self.event_counts[kind] = self.event_counts.get(kind, 0) + 1
        self.events.append(rec)

    def _on_nav(self, t_arrival: float, n: NavSolution) -> None:
        self.nav_count += 1
        self.last_nav = n
        for cb in self.nav_listeners:
            cb(t_arrival, n)
        st = self.traj.state(n.time_s)
        lat, lon, h = st.pos
        tru = [
            n.time_s, lat / DEG, lon / DEG, h, *st.v_enu.tolist(),
            st.roll / DEG, st.pitch / DEG, st.heading / DEG,
        ]
        self._truth_w.writerow([_fmt(x) for x in tru])
        navigating = bool(n.mode & NavMode.NAVIGATING)
        if navigating:
            from firmware_model.attitude import a2mat, yaw_from_heading

            c_nav = a2mat(n.pitch_deg * DEG, n.roll_deg * DEG, yaw_from_heading(n.heading_deg * DEG))
            c_err = c_nav @ st.c_bn.T
            att = math.degrees(math.acos(max(-1.0, min(1.0, (np.trace(c_err) - 1.0) / 2.0))))
            e_roll = _wrap180(n.roll_deg - st.roll / DEG)
            e_pitch = n.pitch_deg - st.pitch / DEG
            e_hdg = _wrap180(n.heading_deg - st.heading / DEG)
            rm, rn = earth.radii(lat)
            e_n = (n.lat_deg * DEG - lat) * (rm + h)
            e_e = (n.lon_deg * DEG - lon) * (rn + h) * math.cos(lat)
            e_u = n.height_m - h
            e_pos = math.sqrt(e_e * e_e + e_n * e_n + e_u * e_u)
            ev = [n.vel_enu_mps[i] - float(st.v_enu[i]) for i in range(3)]
            e_vel = math.sqrt(sum(x * x for x in ev))
            self.errors["attitude_deg"].add(att)
            self.errors["heading_deg"].add(e_hdg)
            self.errors["position_m"].add(e_pos)
            self.errors["velocity_mps"].add(e_vel)
            self.error_series.append((n.time_s, att, e_hdg, e_pos, e_vel))
            errs = [att, e_roll, e_pitch, e_hdg, e_e, e_n, e_u, e_pos, *ev, e_vel]
        else:
            errs = [""] * 12
        row = [
            n.time_s, n.lat_deg, n.lon_deg, n.height_m, *n.vel_enu_mps, n.roll_deg, n.pitch_deg, n.heading_deg,
            *n.sigma, n.mode, n.gnss_status, n.psns_status, n.cpu_load_pct, n.deadline_misses, t_arrival,
        ]
        self._nav_w.writerow([_fmt(x) for x in row] + [_fmt(x) for x in errs])

    # -- results -----------------------------------------------------------------------------
    def link_summary(self) -> dict[str, dict[str, int]]:
        out: dict[str, dict[str, int]] = {}
        for name, tap in self._taps.items():
            st = tap.link.stats
            frames = sum(d.stats.frames for d in tap.decoders.values())
            crc = sum(d.stats.crc_errors for d in tap.decoders.values())
            out[name] = {
                "bytes": st.bytes_out + st.bytes_in,
                "frames": frames,
                "crc_errors": crc,
                "dropped": st.dropped,
                "garbage_bytes": sum(d.stats.garbage_bytes for d in tap.decoders.values()),
            }
        return out

    def error_window(self, metric: str, after_s: float, until_s: float | None) -> ErrorStats:
        idx = {"attitude_deg": 1, "heading_deg": 2, "position_m": 3, "velocity_mps": 4}[metric]
        es = ErrorStats()
        for row in self.error_series:
            if row[0] >= after_s and (until_s is None or row[0] <= until_s):
                es.add(row[idx])
        return es

    def _maybe_flush(self) -> None:
        now = _time.monotonic()
        if now - self._last_flush >= self._flush_interval:
            self.flush()
            self._last_flush = now

    def flush(self) -> None:
        for f in (self._cap, self._events, self._nav_f, self._truth_f):
            if f is not None and not f.closed:
                f.flush()

    def write_summary(self, summary: dict[str, Any]) -> Path:
        path = self.run_dir / "summary.json"
        tmp = path.with_suffix(".json.tmp")
        tmp.write_text(json.dumps(summary, indent=2, default=_json_default) + "\n", encoding="utf-8")
        tmp.replace(path)
        return path

    def close(self) -> None:
        self.flush()
        for f in (self._cap, self._events, self._nav_f, self._truth_f):
            if f is not None and not f.closed:
                f.close()


class _TapListener:
    __slots__ = ("rec", "name")

    def __init__(self, rec: Recorder, name: str) -> None:
        self.rec = rec
        self.name = name

    def on_link_bytes(self, link: Link, direction: str, t: float, data: bytes) -> None:
        self.rec.on_bytes(self.name, direction, t, data)


def _fmt(x: Any) -> str:
    if isinstance(x, float):
        return repr(float(x)) if math.isfinite(x) else ""
    return str(x)


def _json_default(o: Any) -> Any:
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    return str(o)
