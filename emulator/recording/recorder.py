"""The recorder: byte captures, events, navigation output against truth, and the summary.

It is a listener: it subscribes to links (:class:`~emulator.links.base.LinkListener`) and to
device events (:class:`~emulator.devices.base.EventSink`); nothing reaches into a device.

Files in the run directory (written as the run goes and flushed at least once per wall-clock
second, so an interrupted run keeps everything up to the interruption):

``capture.psnscap``
    Every chunk on every tapped link (:mod:`emulator.recording.capture`; ``docs/capture-format.md``).
``events.jsonl``
    One JSON object per event: ``{"t_s", "source", "event", ...}``.
``nav.csv``
    Every NAV_SOLUTION the host received (the ``nav_port`` tap, direction ``out``), decoded,
    with the error against truth at its time of validity (:mod:`emulator.recording.nav_error`).
``truth.csv``
    Truth at the same times.
``psns.csv``
    Every solar vector the firmware solved, against the world's sun in the body frame at its exposure time
    (:mod:`emulator.recording.psns_error`); only in a run with a polarization sensor.
``timeline.csv``
    One row per simulated second: cumulative link counters (frames, CRC errors, dropped bytes,
    garbage bytes, framing errors per link), the DSP's CPU load in that second and its deadline
    misses (written by the runner through :meth:`Recorder.table_row`; ``emulator.postrun.report`` plots it).
``filter_state.csv``
    One row per simulated second: the firmware's mode and the diagonal of its filter covariance and
    its bias estimates (the change indicator's state history, ``emulator.postrun.golden``).
``summary.json``
    Written at the end (also after an interruption, with ``"interrupted": true``, and after the disk filled up or
    a file reached the size limit, with ``"storage_error"``: the space for it is held from the start by a
    reserve file, :data:`SUMMARY_RESERVE_NAME`, released just before the summary is written).

A SIGKILL leaves the files as last written: ``nav.csv`` and ``truth.csv`` are written (to the OS) at every
comparison batch, so they trail the capture by at most one batch (:attr:`Recorder.NAV_BATCH` frames, 2 s at
100 Hz; :attr:`Recorder.NAV_BATCH_REALTIME` in realtime mode), not by the wall-clock flush interval (issue 41:
15-27 s of emulated time in fast mode before).

Cost: frame counting on the other taps only needs the totals, so their bytes are buffered and
decoded in batches (at every flush and whenever the summary is read) by counting decoders
(:mod:`emulator.recording.counting`); CSV rows are formatted by hand
(:func:`~emulator.recording.formatting.csv_row_fast`) and written in batches. Navigation frames are compared
with truth in batches of :attr:`Recorder.NAV_BATCH` (:attr:`Recorder.NAV_BATCH_REALTIME` in realtime mode; one
vectorised trajectory evaluation, bit-for-bit the per-frame values);
``errors``, ``error_series``, ``mode_series`` and :meth:`Recorder.flush` complete the pending batch
first, so readers always see every frame received so far.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import json
import os
import time as _time
from array import array
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import IO, Any

from firmware_model.registry import SolarSolve
from protocols.host import NavSolution
from protocols.stream import FrameFormat, StreamDecoder

from ..links.base import Link
from ..world.sun import SunModel
from ..world.trajectory import Trajectory
from .capture import CaptureWriter
from .counting import counting_decoder
from .formatting import csv_row_fast, json_default, strict_json
from .nav_error import ErrorStats, NavVsTruth
from .psns_error import SolarVsTruth
from .rundir import SUMMARY_RESERVE_NAME, open_no_follow

__all__ = ["Recorder"]


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


class Recorder:
    """Writes the run directory (see module docstring).

    Parameters
    ----------
    run_dir : output directory (created).
    trajectory : truth for the error evaluation.
    sun : the world's sun (the truth of the firmware's solar vectors; None: they are not compared).
    """

    def __init__(self, run_dir: Path, trajectory: Trajectory, flush_interval_s: float = 1.0,
                 nav_port: str = "host", sun: SunModel | None = None) -> None:
        self.run_dir = Path(run_dir)
        self.run_dir.mkdir(parents=True, exist_ok=True)
        self._reserve_summary_space()
        self.traj = trajectory
        self.nav_port = nav_port
        self._taps: dict[str, _Tap] = {}
        self._link_index: dict[str, int] = {}
        self._cap: CaptureWriter | None = None
        self._events: IO[str] = open_no_follow(self.run_dir / "events.jsonl")
        self._nav_f: IO[str] = open_no_follow(self.run_dir / "nav.csv", newline="")
        self._truth_f: IO[str] = open_no_follow(self.run_dir / "truth.csv", newline="")
        self._compare = NavVsTruth(trajectory)
        #: the firmware's solar vectors against truth (psns.csv), None without a sun model
        self.solar = SolarVsTruth(trajectory, sun) if sun is not None else None
        self._psns_f: IO[str] | None = None
        #: navigation frames (arrival time, frame) whose truth comparison is still to be done
        self._nav_pending: list[tuple[float, NavSolution]] = []
        self._drain_soon = False
        self._nav_batch = self.NAV_BATCH
        self._tables: dict[str, tuple[IO[str], list[str], list[str]]] = {}
        self.nav_count = 0
        self.event_counts: dict[str, int] = {}
        #: the latest :data:`EVENTS_TAIL` events (all of them are in events.jsonl: :meth:`iter_events`), so a
        #: flood of events (commands, rejections) cannot grow the memory without bound (docs/hostile-input.md)
        self.events: deque[dict[str, Any]] = deque(maxlen=self.EVENTS_TAIL)
        #: events emitted after close() (callbacks already due when the run stopped), not recorded
        self.events_after_close = 0
        self.events_total = 0
        self.nav_listeners: list[Callable[[float, NavSolution], None]] = []
        self._flush_interval = flush_interval_s
        self._last_flush = _time.monotonic()
        self._chunks = 0
        self.last_nav: NavSolution | None = None
        #: navigation frames with non-finite values already reported by a ``nav_nonfinite`` event
        self._nonfinite_reported = 0

    # -- wiring ---------------------------------------------------------------------------
    def tap(self, name: str, link: Link, formats: dict[str, Sequence[FrameFormat]]) -> None:
        """Capture ``link`` under ``name`` and decode its directions with ``formats``.

        The ``nav_port`` tap's ``out`` direction is decoded at once (navigation frames against
        truth); every other decoder only counts frames, in batches.
        """
        if self._cap is not None:
            raise RuntimeError("tap() after start()")
        nav = name == self.nav_port
        t = _Tap(link, {d: StreamDecoder(list(f)) if nav and d == "out" else counting_decoder(f)
                        for d, f in formats.items() if f}, nav=nav)
        t.pending = {d: bytearray() for d in t.decoders if not (t.nav and d == "out")}
        self._taps[name] = t
        self._link_index[name] = len(self._link_index)
        link.listeners.append(_TapListener(self, name, len(self._link_index) - 1, t))

    def start(self, header: dict[str, Any]) -> None:
        self._cap = CaptureWriter(self.run_dir / "capture.psnscap", header, list(self._link_index))

    # -- listener callbacks -------------------------------------------------------------------
    def on_bytes(self, name: str, direction: str, t: float, data: bytes) -> None:
        tap = self._taps[name]
        self._record(self._link_index[name], tap, tap.link, direction, t, data)

    def _record(self, index: int, tap: _Tap, link: Link, direction: str, t: float, data: bytes) -> None:
        """One chunk on tapped ``link`` (``tap``, capture index ``index``): captured, counted or decoded."""
        cap = self._cap
        if cap is not None:
            if direction == "out":
                cap.write(index, False, t, data)
            else:
                pitch = link.last_rx_pitch
                cap.write(index, True, t, data, pitch if pitch != link.line.byte_time else None)
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

    #: events kept in memory besides events.jsonl
    EVENTS_TAIL = 4096

    def emit(self, t: float, source: str, kind: str, /, **data: Any) -> None:
        if self._events.closed:  # a callback that was already due when the run stopped (realtime): the run is over
            self.events_after_close += 1
            return
        rec = {"t_s": round(t, 9), "source": source, "event": kind}
        rec.update(data)
        self._events.write(json.dumps(rec, default=json_default) + "\n")
        self.event_counts[kind] = self.event_counts.get(kind, 0) + 1
        self.events.append(rec)
        self.events_total += 1

    def iter_events(self) -> Iterator[dict[str, Any]]:
        """Every event of the run, in order, streamed from events.jsonl (the memory holds only a tail)."""
        if self.events_total <= len(self.events):  # nothing dropped from the tail: no need to read the file
            yield from list(self.events)
            return
        if not self._events.closed:
            self._events.flush()
        with open(self.run_dir / "events.jsonl", encoding="utf-8") as f:
            for line in f:
                if line.strip():
                    yield json.loads(line)

    def on_solar_solves(self, solves: list[SolarSolve]) -> None:
        """The firmware solved solar vectors (``VirtualDsp.solar_listeners``); compared with truth in batches."""
        if self.solar is not None:
            self.solar.add(solves)

    def psns_summary(self) -> dict[str, Any] | None:
        """The summary's ``psns`` section (solar-vector error against truth), None when nothing was solved."""
        return self.solar.summary() if self.solar is not None else None

    def solar_error_window(self, after_s: float, until_s: float | None) -> list[float]:
        """The solar-vector errors (deg) of the solves exposed in [``after_s``, ``until_s``]."""
        return self.solar.window(after_s, until_s) if self.solar is not None else []

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
        return self._compare.errors

    @property
    def errors_by_phase(self) -> dict[str, dict[str, ErrorStats]]:
        """:attr:`errors` split into fine alignment and navigating proper (``NAV_PHASES``)."""
        self._drain_nav()
        return self._compare.errors_by_phase

    @property
    def error_series(self) -> array[float]:
        """Flat rows of (t, attitude, heading, position, velocity) errors, 40 bytes per nav frame."""
        self._drain_nav()
        return self._compare.error_series

    @property
    def mode_series(self) -> array[float]:
        """Flat rows of (time of validity, mode bits) of every nav frame, 16 bytes per frame."""
        self._drain_nav()
        return self._compare.mode_series

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
        self._compare.add(pend)
        self._write_nav_rows()  # nav.csv trails the capture by at most one batch after a SIGKILL
        nf = self._compare.nonfinite_frames
        if nf != self._nonfinite_reported:  # counted and shown (events, summary event_counts), never raised
            self.emit(pend[-1][0], "recorder", "nav_nonfinite", frames=nf - self._nonfinite_reported, total=nf)
            self._nonfinite_reported = nf

    @property
    def nav_nonfinite_frames(self) -> int:
        """Navigation frames with a non-finite time, position, velocity or attitude (left out of the errors)."""
        self._drain_nav()
        return self._compare.nonfinite_frames

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
                "no_peer": st.no_peer_out,
                "garbage_bytes": sum(d.stats.garbage_bytes for d in tap.decoders.values()),
                "framing_errors": st.framing_errors,
            }
        return out

    def error_window(self, metric: str, after_s: float, until_s: float | None) -> ErrorStats:
        """RMS / max of ``metric`` over the navigating frames valid in [``after_s``, ``until_s``]."""
        self._drain_nav()
        return self._compare.error_window(metric, after_s, until_s)

    def table_row(self, name: str, row: dict[str, Any]) -> None:
        """Append ``row`` to ``<name>.csv`` in the run directory (the first row's keys are the header)."""
        tab = self._tables.get(name)
        if tab is None:
            f: IO[str] = open_no_follow(self.run_dir / f"{name}.csv", newline="")
            cols = list(row)
            tab = self._tables[name] = (f, cols, [",".join(cols) + "\r\n"])
        _f, cols, rows = tab
        rows.append(csv_row_fast([row.get(c, "") for c in cols]))

    def flush(self) -> None:
        """Write the batched rows and flush every file (captures included) to the OS."""
        self._drain_nav()
        for tap in self._taps.values():
            tap.feed_pending()
        for f, _cols, rows in self._tables.values():
            if rows and not f.closed:
                f.write("".join(rows))
                rows.clear()
        sol = self.solar
        if sol is not None:
            sol.drain()
            if sol.rows and not self._events.closed:
                if self._psns_f is None:
                    self._psns_f = open_no_follow(self.run_dir / "psns.csv", newline="")
                self._psns_f.write("".join(sol.rows))
                sol.rows.clear()
        if self._cap is not None:
            self._cap.flush()
        for f in self._text_files():
            if not f.closed:
                f.flush()

    def _write_nav_rows(self) -> None:
        """The compared navigation and truth rows to nav.csv / truth.csv, handed to the OS now."""
        cmp = self._compare
        if cmp.nav_rows and not self._nav_f.closed:
            self._nav_f.write("".join(cmp.nav_rows))
            cmp.nav_rows.clear()
            self._nav_f.flush()
        if cmp.truth_rows and not self._truth_f.closed:
            self._truth_f.write("".join(cmp.truth_rows))
            cmp.truth_rows.clear()
            self._truth_f.flush()

    #: bytes held for summary.json from the start of the run (a summary is 10-100 KB)
    SUMMARY_RESERVE_BYTES = 1 << 18

    def _reserve_summary_space(self) -> None:
        """Allocate :data:`SUMMARY_RESERVE_NAME` (:attr:`SUMMARY_RESERVE_BYTES`): released before the summary is
        written, so a run whose disk filled up still writes its summary. No space for it: no reserve."""
        path = self.run_dir / SUMMARY_RESERVE_NAME
        try:
            fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | getattr(os, "O_NOFOLLOW", 0), 0o644)
        except OSError:
            return
        try:
            os.posix_fallocate(fd, 0, self.SUMMARY_RESERVE_BYTES)
        except OSError:
            os.close(fd)
            path.unlink(missing_ok=True)
            return
        os.close(fd)

    def write_summary(self, summary: dict[str, Any]) -> Path:
        (self.run_dir / SUMMARY_RESERVE_NAME).unlink(missing_ok=True)  # its space is the summary's
        path = self.run_dir / "summary.json"
        tmp = path.with_suffix(".json.tmp")
        try:
            tmp.write_text(strict_json(summary) + "\n", encoding="utf-8")
        except OSError:
            tmp.unlink(missing_ok=True)
            raise
        tmp.replace(path)
        return path

    def close(self) -> None:
        self.flush()
        if self._cap is not None:
            self._cap.close()
        for f in self._text_files():
            if not f.closed:
                f.close()
        (self.run_dir / SUMMARY_RESERVE_NAME).unlink(missing_ok=True)

    def abandon(self) -> None:
        """Close every file after a storage error (disk full, file-size limit): what the OS already has is kept,
        what is still buffered is dropped (its write would fail again). The summary reserve stays for
        :meth:`write_summary`."""
        files: list[Any] = [*self._text_files(), *([self._cap.file] if self._cap is not None else [])]
        for f in files:
            if f.closed:
                continue
            with contextlib.suppress(OSError, ValueError):
                f.close()  # a failed flush still closes the file (io's close() closes the raw file regardless)

    def _text_files(self) -> list[IO[str]]:
        files = [self._events, self._nav_f, self._truth_f, *(t[0] for t in self._tables.values())]
        return files if self._psns_f is None else [*files, self._psns_f]


class _TapListener:
    """The recorder's :class:`~emulator.links.base.LinkListener` on one tapped link: ``on_link_bytes(link,
    direction, t, data)`` is :meth:`Recorder._record` with the tap's index and state bound (a ``functools.partial``,
    so a chunk costs no Python frame of its own here)."""

    __slots__ = ("index", "name", "on_link_bytes", "rec", "tap")

    def __init__(self, rec: Recorder, name: str, index: int, tap: _Tap) -> None:
        self.rec = rec
        self.name = name
        self.index = index
        self.tap = tap
        self.on_link_bytes: Callable[[Link, str, float, bytes], None] = functools.partial(rec._record, index, tap)
