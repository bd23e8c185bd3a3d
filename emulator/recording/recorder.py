"""The recorder: byte captures, events, navigation output against truth, and the summary.

It is a listener: it subscribes to links (:class:`~emulator.links.base.LinkListener`) and to
device events (:class:`~emulator.devices.base.EventSink`); nothing reaches into a device.

Files in the run directory (written as the run goes and flushed at least once per wall-clock
second, so an interrupted run keeps everything up to the interruption):

``capture.psnscap``
    Every chunk on every tapped link. Format (little-endian): the 9-byte magic
    ``PSNSCAP1\\n``, one JSON header line ``{"version": 1, "links": [...], ...}\\n``, then
    records ``<d t_s> <H link_index> <B direction (0 out, 1 in)> <B reserved> <I length>``
    followed by ``length`` bytes. ``docs/capture-format.md`` has the details.
``events.jsonl``
    One JSON object per event: ``{"t_s", "source", "event", ...}``.
``nav.csv``
    Every NAV_SOLUTION the host received (the ``nav_port`` tap, direction ``out``), decoded,
    with the error against truth at its time of validity.
``truth.csv``
    Truth at the same times.
``timeline.csv``
    One row per simulated second: cumulative link counters (frames, CRC errors, dropped bytes,
    garbage bytes, framing errors per link), the DSP's CPU load in that second and its deadline
    misses (written by the runner through :meth:`Recorder.table_row`; ``emulator.recording.report`` plots it).
``filter_state.csv``
    One row per simulated second: the firmware's mode and the diagonal of its filter covariance and
    its bias estimates (the change indicator's state history, ``emulator.recording.golden``).
``summary.json``
    Written at the end (also after an interruption, with ``"interrupted": true``).

Cost: frame counting on the other taps only needs the totals, so their bytes are buffered and
decoded in batches (at every flush and whenever the summary is read); CSV rows are formatted
by hand and written in batches. Navigation frames are compared with truth in batches of
:attr:`Recorder.NAV_BATCH` (:attr:`Recorder.NAV_BATCH_REALTIME` in realtime mode; one vectorised
trajectory evaluation, bit-for-bit the per-frame values);
``errors``, ``error_series``, ``mode_series`` and :meth:`Recorder.flush` complete the pending batch
first, so readers always see every frame received so far.
"""

from __future__ import annotations

import asyncio
import json
import math
import struct
import time as _time
from array import array
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any, Callable, Iterator, Sequence

import numpy as np

from firmware_model import earth
from protocols.host import NavMode, NavSolution
from protocols.imu_frame import FpgaFrameFormat, ImuFrameFormat
from protocols.psns import PsnsFormat
from protocols.stim import Stim210Format
from protocols.stream import FrameFormat, StreamDecoder

from ..links.base import Link
from ..world.trajectory import Trajectory

__all__ = ["CAPTURE_MAGIC", "Recorder", "ErrorStats", "CaptureRecord", "read_capture", "iter_capture"]

CAPTURE_MAGIC = b"PSNSCAP1\n"
_REC = struct.Struct("<dHBBI")
_PITCH = struct.Struct("<d")
#: record flag: an f64 byte pitch (s, start-to-start spacing of the chunk's bytes) follows the header
FLAG_PITCH = 0x01
CAPTURE_VERSION = 2
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
    #: spacing of the bytes on the wire when it differs from the link's byte time (None otherwise)
    pitch_s: float | None = None


def _read_header(f: IO[bytes], path: str | Path) -> dict[str, Any]:
    from ..errors import RecordingError

    magic = f.read(len(CAPTURE_MAGIC))
    if magic != CAPTURE_MAGIC:
        raise RecordingError(f"{path}: not a psns-hil capture (bad magic)")
    line = f.readline()
    if not line.endswith(b"\n"):
        raise RecordingError(f"{path}: capture header line is incomplete")
    try:
        header = json.loads(line)
    except json.JSONDecodeError as exc:
        raise RecordingError(f"{path}: line 2, column {exc.colno}: bad capture header: {exc.msg}") from None
    if not isinstance(header, dict):
        raise RecordingError(f"{path}: line 2: the capture header must be a JSON object")
    return header


def iter_capture(path: str | Path) -> tuple[dict[str, Any], Iterator[CaptureRecord]]:
    """Header and a lazy iterator over the records (constant memory for any file size).

    A truncated last record (interrupted run) ends the iteration silently.
    """
    f = open(path, "rb")
    try:
        header = _read_header(f, path)
    except BaseException:
        f.close()
        raise
    links = header.get("links", [])

    def gen() -> Iterator[CaptureRecord]:
        with f:
            size = _REC.size
            while True:
                head = f.read(size)
                if len(head) < size:
                    return
                t, idx, d, flags, n = _REC.unpack(head)
                pitch = None
                if flags & FLAG_PITCH:
                    raw = f.read(_PITCH.size)
                    if len(raw) < _PITCH.size:
                        return
                    pitch = _PITCH.unpack(raw)[0]
                data = f.read(n)
                if len(data) < n:
                    return
                name = links[idx] if idx < len(links) else f"link{idx}"
                yield CaptureRecord(t, name, "out" if d == 0 else "in", data, pitch)

    return header, gen()


def read_capture(path: str | Path) -> tuple[dict[str, Any], list[CaptureRecord]]:
    """Read a ``.psnscap`` file; a truncated last record (interrupted run) is ignored."""
    header, it = iter_capture(path)
    return header, list(it)


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


class _Counted:
    """A frame format that delimits and checks like ``fmt`` but does not build the frame object.

    For the recorder's counting decoders (only the totals are kept). Used only for the formats of
    :data:`COUNT_ONLY_FORMATS`, whose ``parse`` is a fixed-layout unpack of a frame whose length
    ``frame_length`` has already validated and so cannot fail: the decoder's counters (frames, CRC
    errors, garbage, resyncs) are exactly those of the full format
    (``tests/emulator/recording/test_recorder_counting.py``)."""

    __slots__ = ("name", "sync", "frame_length", "check")

    def __init__(self, fmt: FrameFormat) -> None:
        self.name = fmt.name
        self.sync = fmt.sync
        self.frame_length = fmt.frame_length
        self.check = fmt.check

    @staticmethod
    def parse(frame: bytes) -> None:
        return None


#: formats counted without parsing (see :class:`_Counted`)
COUNT_ONLY_FORMATS: tuple[type, ...] = (Stim210Format, ImuFrameFormat, FpgaFrameFormat, PsnsFormat)


def counting_format(fmt: FrameFormat) -> FrameFormat:
    """``fmt`` itself, or its non-parsing twin when counting its frames cannot differ (:class:`_Counted`)."""
    return _Counted(fmt) if type(fmt) in COUNT_ONLY_FORMATS else fmt  # type: ignore[return-value]


@dataclass
class _Tap:
    link: Link
    decoders: dict[str, StreamDecoder] = field(default_factory=dict)
    pending: dict[str, bytearray] = field(default_factory=dict)
    nav: bool = False

    def feed_pending(self) -> None:
        for d, buf in self.pending.items():
            if buf:
                self.decoders[d].feed(buf)
                buf.clear()


def _wrap180(x: float) -> float:
    return (x + 180.0) % 360.0 - 180.0


class Recorder:
    """Writes the run directory (see module docstring).

    Parameters
    ----------
    run_dir : output directory (created).
    trajectory : truth for the error evaluation.
    """

    def __init__(self, run_dir: Path, trajectory: Trajectory, flush_interval_s: float = 1.0,
                 nav_port: str = "host") -> None:
        self.run_dir = Path(run_dir)
        self.run_dir.mkdir(parents=True, exist_ok=True)
        self.traj = trajectory
        self.nav_port = nav_port
        self._taps: dict[str, _Tap] = {}
        self._link_index: dict[str, int] = {}
        self._cap: IO[bytes] | None = None
        self._events: IO[str] = open(self.run_dir / "events.jsonl", "w", encoding="utf-8")
        self._nav_f: IO[str] = open(self.run_dir / "nav.csv", "w", encoding="utf-8", newline="")
        self._truth_f: IO[str] = open(self.run_dir / "truth.csv", "w", encoding="utf-8", newline="")
        self._nav_rows: list[str] = [",".join(NAV_COLUMNS) + "\r\n"]
        self._truth_rows: list[str] = [",".join(TRUTH_COLUMNS) + "\r\n"]
        self._errors = {k: ErrorStats() for k in ("attitude_deg", "heading_deg", "position_m", "velocity_mps")}
        self._error_series = array("d")
        self._mode_series = array("d")
        #: navigation frames (arrival time, frame) whose truth comparison is still to be done
        self._nav_pending: list[tuple[float, NavSolution]] = []
        self._drain_soon = False
        self._nav_batch = self.NAV_BATCH
        self._tables: dict[str, tuple[IO[str], list[str], list[str]]] = {}
        self.nav_count = 0
        self.event_counts: dict[str, int] = {}
        self.events: list[dict[str, Any]] = []
        self.nav_listeners: list[Callable[[float, NavSolution], None]] = []
        self._flush_interval = flush_interval_s
        self._last_flush = _time.monotonic()
        self._chunks = 0
        self.last_nav: NavSolution | None = None

    # -- wiring ---------------------------------------------------------------------------
    def tap(self, name: str, link: Link, formats: dict[str, Sequence[FrameFormat]]) -> None:
        """Capture ``link`` under ``name`` and decode its directions with ``formats``.

        The ``nav_port`` tap's ``out`` direction is decoded at once (navigation frames against
        truth); every other decoder only counts frames, in batches.
        """
        if self._cap is not None:
            raise RuntimeError("tap() after start()")
        nav = name == self.nav_port
        t = _Tap(link, {d: StreamDecoder(list(f) if nav and d == "out" else [counting_format(x) for x in f])
                        for d, f in formats.items() if f}, nav=nav)
        t.pending = {d: bytearray() for d in t.decoders if not (t.nav and d == "out")}
        self._taps[name] = t
        self._link_index[name] = len(self._link_index)
        link.listeners.append(_TapListener(self, name, len(self._link_index) - 1, t))

    def start(self, header: dict[str, Any]) -> None:
        self._cap = open(self.run_dir / "capture.psnscap", "wb")
        hdr = dict(header)
        hdr["version"] = CAPTURE_VERSION
        hdr["links"] = list(self._link_index)
        self._cap.write(CAPTURE_MAGIC + json.dumps(hdr, sort_keys=True, default=_json_default).encode() + b"\n")
        self._cap.flush()

    # -- listener callbacks -------------------------------------------------------------------
    def on_bytes(self, name: str, direction: str, t: float, data: bytes) -> None:
        tap = self._taps[name]
        self._record(self._link_index[name], tap, direction, t, data)

    def _record(self, index: int, tap: _Tap, direction: str, t: float, data: bytes) -> None:
        cap = self._cap
        if cap is not None:
            if direction == "out":
                cap.write(_REC.pack(t, index, 0, 0, len(data)))
            else:
                link = tap.link
                pitch = link.last_rx_pitch
                if pitch != link.line.byte_time:
                    cap.write(_REC.pack(t, index, 1, FLAG_PITCH, len(data)) + _PITCH.pack(pitch))
                else:
                    cap.write(_REC.pack(t, index, 1, 0, len(data)))
            cap.write(data)
        buf = tap.pending.get(direction)
        if buf is not None:
            buf += data
            if len(buf) > self.PENDING_BYTES:
                tap.decoders[direction].feed(buf)
                buf.clear()
        elif tap.nav and direction == "out":
            for fr in tap.decoders["out"].feed(data):
                if isinstance(fr, NavSolution):
                    self._on_nav(t, fr)
        self._chunks += 1
        if not self._chunks & 15:  # the wall clock every 16 chunks (a realtime run has >= 600 per wall s)
            now = _time.monotonic()
            if now - self._last_flush >= self._flush_interval:
                self.flush()
                self._last_flush = now

    def emit(self, t: float, source: str, kind: str, /, **data: Any) -> None:
        rec = {"t_s": round(t, 9), "source": source, "event": kind}
        rec.update(data)
        self._events.write(json.dumps(rec, default=_json_default) + "\n")
        self.event_counts[kind] = self.event_counts.get(kind, 0) + 1
        self.events.append(rec)

    # -- navigation output against truth (batched) ------------------------------------------------
    #: frames compared with truth in one batch (the trajectory is evaluated vectorised, ~1 us per frame
    #: plus ~0.1 ms per batch); in realtime mode small enough that a batch (< 1 ms) never delays the
    #: next IMU tick
    NAV_BATCH = 200
    NAV_BATCH_REALTIME = 25
    #: bytes a counting tap buffers before decoding them (a bounded burst, ~0.3 ms, in realtime mode)
    PENDING_BYTES = 4096

    @property
    def errors(self) -> dict[str, ErrorStats]:
        """Running RMS / max per error metric over every navigating frame so far."""
        self._drain_nav()
        return self._errors

    @property
    def error_series(self) -> array:
        """Flat rows of (t, attitude, heading, position, velocity) errors, 40 bytes per nav frame."""
        self._drain_nav()
        return self._error_series

    @property
    def mode_series(self) -> array:
        """Flat rows of (time of validity, mode bits) of every nav frame, 16 bytes per frame."""
        self._drain_nav()
        return self._mode_series

    def _on_nav(self, t_arrival: float, n: NavSolution) -> None:
        self.nav_count += 1
        self.last_nav = n
        for cb in self.nav_listeners:
            cb(t_arrival, n)
        pend = self._nav_pending
        pend.append((t_arrival, n))
        if len(pend) >= self._nav_batch and not self._drain_soon:
            # after the frame has gone on (this runs inside the link's delivery, before a pty write)
            try:
                loop = asyncio.get_running_loop()
            except RuntimeError:  # no event loop (a replay tool, a test): now
                self._drain_nav()
                return
            loop.call_soon(self._drain_nav)
            self._drain_soon = True
        elif len(pend) == 1 and self.nav_count == 1:  # the first frame: the batch size for this run
            try:
                realtime = getattr(asyncio.get_running_loop(), "mode", "fast") == "realtime"
            except RuntimeError:
                realtime = False
            self._nav_batch = self.NAV_BATCH_REALTIME if realtime else self.NAV_BATCH

    def _drain_nav(self) -> None:
        """Compare the pending frames with truth (one vectorised trajectory evaluation)."""
        self._drain_soon = False
        pend = self._nav_pending
        if not pend:
            return
        self._nav_pending = []
        for (t_arrival, n), st in zip(pend, self.traj.states([n.time_s for _t, n in pend])):
            self._nav_row(t_arrival, n, st)

    def _nav_row(self, t_arrival: float, n: NavSolution, st: Any) -> None:
        lat, lon, h = (float(x) for x in st.pos)
        ve, vn, vu = (float(x) for x in st.v_enu)
        self._truth_rows.append(_row((n.time_s, lat / DEG, lon / DEG, h, ve, vn, vu,
                                      st.roll / DEG, st.pitch / DEG, st.heading / DEG)))
        self._mode_series.extend((n.time_s, n.mode))
        navigating = bool(n.mode & NavMode.NAVIGATING)
        if navigating:
            c_nav = _c_bn(n.pitch_deg * DEG, n.roll_deg * DEG, -n.heading_deg * DEG)
            # trace(C_nav C_true^T) = sum of the element-wise product
            tr = sum(a * b for a, b in zip(c_nav, st.c_bn.ravel().tolist()))
            att = math.degrees(math.acos(max(-1.0, min(1.0, (tr - 1.0) / 2.0))))
            e_roll = _wrap180(n.roll_deg - st.roll / DEG)
            e_pitch = n.pitch_deg - st.pitch / DEG
            e_hdg = _wrap180(n.heading_deg - st.heading / DEG)
            rm, rn = earth.radii(lat)
            e_n = (n.lat_deg * DEG - lat) * (rm + h)
            e_e = (n.lon_deg * DEG - lon) * (rn + h) * math.cos(lat)
            e_u = n.height_m - h
            e_pos = math.sqrt(e_e * e_e + e_n * e_n + e_u * e_u)
            v = n.vel_enu_mps
            ev = (v[0] - ve, v[1] - vn, v[2] - vu)
            e_vel = math.sqrt(ev[0] * ev[0] + ev[1] * ev[1] + ev[2] * ev[2])
            err = self._errors
            err["attitude_deg"].add(att)
            err["heading_deg"].add(e_hdg)
            err["position_m"].add(e_pos)
            err["velocity_mps"].add(e_vel)
            self._error_series.extend((n.time_s, att, e_hdg, e_pos, e_vel))
            errs = _row((att, e_roll, e_pitch, e_hdg, e_e, e_n, e_u, e_pos, *ev, e_vel))
        else:
            errs = _NO_ERRORS
        row = (
            n.time_s, n.lat_deg, n.lon_deg, n.height_m, *n.vel_enu_mps, n.roll_deg, n.pitch_deg, n.heading_deg,
            *n.sigma, n.mode, n.gnss_status, n.psns_status, n.cpu_load_pct, n.deadline_misses, t_arrival,
        )
        self._nav_rows.append(_row(row)[:-2] + "," + errs)

    # -- results -----------------------------------------------------------------------------
    def link_summary(self) -> dict[str, dict[str, int]]:
        out: dict[str, dict[str, int]] = {}
        for name, tap in self._taps.items():
            tap.feed_pending()
            st = tap.link.stats
            frames = sum(d.stats.frames for d in tap.decoders.values())
            crc = sum(d.stats.crc_errors for d in tap.decoders.values())
            out[name] = {
                "bytes": st.bytes_out + st.bytes_in,
                "frames": frames,
                "crc_errors": crc,
                "dropped": st.dropped,
                "garbage_bytes": sum(d.stats.garbage_bytes for d in tap.decoders.values()),
                "framing_errors": st.framing_errors,
            }
        return out

    def error_window(self, metric: str, after_s: float, until_s: float | None) -> ErrorStats:
        idx = {"attitude_deg": 1, "heading_deg": 2, "position_m": 3, "velocity_mps": 4}[metric]
        es = ErrorStats()
        ser = self.error_series
        for k in range(0, len(ser), 5):
            t = ser[k]
            if t >= after_s and (until_s is None or t <= until_s):
                es.add(ser[k + idx])
        return es

    def table_row(self, name: str, row: dict[str, Any]) -> None:
        """Append ``row`` to ``<name>.csv`` in the run directory (the first row's keys are the header)."""
        tab = self._tables.get(name)
        if tab is None:
            f = open(self.run_dir / f"{name}.csv", "w", encoding="utf-8", newline="")
            cols = list(row)
            tab = self._tables[name] = (f, cols, [",".join(cols) + "\r\n"])
        f, cols, rows = tab
        rows.append(_row([row.get(c, "") for c in cols]))

    def flush(self) -> None:
        """Write the batched rows and flush every file (captures included) to the OS."""
        self._drain_nav()
        for tap in self._taps.values():
            tap.feed_pending()
        if self._nav_rows and not self._nav_f.closed:
            self._nav_f.write("".join(self._nav_rows))
            self._nav_rows.clear()
        if self._truth_rows and not self._truth_f.closed:
            self._truth_f.write("".join(self._truth_rows))
            self._truth_rows.clear()
        for f, _cols, rows in self._tables.values():
            if rows and not f.closed:
                f.write("".join(rows))
                rows.clear()
        for f in (self._cap, self._events, self._nav_f, self._truth_f, *(t[0] for t in self._tables.values())):
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
        for f in (self._cap, self._events, self._nav_f, self._truth_f, *(t[0] for t in self._tables.values())):
            if f is not None and not f.closed:
                f.close()


class _TapListener:
    __slots__ = ("rec", "name", "index", "tap")

    def __init__(self, rec: Recorder, name: str, index: int, tap: _Tap) -> None:
        self.rec = rec
        self.name = name
        self.index = index
        self.tap = tap

    def on_link_bytes(self, link: Link, direction: str, t: float, data: bytes) -> None:
        self.rec._record(self.index, self.tap, direction, t, data)  # noqa: SLF001


_NO_ERRORS = "," * 11 + "\r\n"


def _fmt(x: Any) -> str:
    if isinstance(x, float):  # numpy floats too
        return repr(float(x)) if x - x == 0.0 else ""  # NaN and infinities: empty cells
    return str(x)


def _row(values: Sequence[Any]) -> str:
    """One CSV line (``\\r\\n`` as the csv module writes): floats by repr, non-finite ones empty."""
    line = ",".join(map(repr, values))
    # repr is already right for finite Python floats, ints and bools; anything else (NaN, inf, numpy
    # scalars, strings) takes the careful path
    if "n" in line or "i" in line or "'" in line or "(" in line or "<" in line or " " in line:
        return ",".join([repr(x) if x.__class__ is float and x - x == 0.0 else _fmt(x) for x in values]) + "\r\n"
    return line + "\r\n"


def _c_bn(pitch: float, roll: float, yaw: float) -> list[float]:
    """``C_b^n`` from Euler angles (rad; yaw counter-clockwise from North), row-major 9 floats.

    The same matrix as :func:`firmware_model.attitude.a2mat` (algorithms.md section 0), in plain
    floats for the per-frame error evaluation.
    """
    sp, cp = math.sin(pitch), math.cos(pitch)
    sr, cr = math.sin(roll), math.cos(roll)
    sy, cy = math.sin(yaw), math.cos(yaw)
    return [cr * cy - sp * sr * sy, -cp * sy, sr * cy + sp * cr * sy,
            cr * sy + sp * sr * cy, cp * cy, sr * sy - sp * cr * cy,
            -cp * sr, sp, cp * cr]


def _json_default(o: Any) -> Any:
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    return str(o)
