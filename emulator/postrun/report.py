"""A self-contained HTML report of one run directory.

``write_report(run_dir)`` reads the files the recorder wrote (``summary.json``, ``nav.csv``,
``events.jsonl`` and, when present, ``timeline.csv`` with per-second link and DSP counters) and
writes ``report.html``. The plots are embedded as base64 PNG, so the report is one file.

* whether the run is valid (every scheduled fault took effect) and passed, the faults with their
  evidence, the expectations with their measured values (numbers readable: ``22 710``, ``300 MHz``);
* a trajectory map (truth vs estimate, periods without GNSS aiding and fault windows marked), attitude and
  heading against truth with the filter's 3 sigma band, an error CDF, a GNSS panel (updates, innovations,
  aided periods), a PSNS/sky panel (solar vector used / rejected, aided periods, the firmware's counters) and,
  from ``psns.csv``, the solved solar vector against truth over time with its azimuth and elevation parts;
  a panel with nothing to show is left out rather than drawn empty;
* attitude (roll, pitch, heading), velocity and position errors against truth, each with the
  filter's own +-3 sigma envelope, with the fault windows shaded;
* the mode timeline (aligning / navigating / GNSS- and PSNS-aided / degraded) with the fault
  windows as bars and other events marked (one line collection per event kind); a kind with more than
  :data:`MARKS_PER_KIND` events is drawn as a rate histogram in an "Event rate" figure instead;
* link error counters over time (from ``timeline.csv``) and the link table;
* DSP load: cycles per task (bars, % of the tick budget), the CPU load and deadline misses over time.

``psns-hil run`` writes it at the end of every run; ``psns-hil report RUN_DIR`` writes it again.

**Cost bounded by design** (issue 41, docs/hostile-input.md section 8): ``events.jsonl`` is streamed once
(:func:`digest_events`, never loaded whole) into per-kind aggregates: the fault events, the GNSS updates (three
numbers each) and, for every other kind, an array of times (8 bytes per event). A line the recorder wrote is
recognised by its fixed prefix (time, source, kind) without a JSON parse unless its kind is needed in detail. A
flood of 300 000 host-command events costs at most 1.5 times the report's time and peak memory of the same run
without them (``tests/emulator/postrun/test_report_cost.py``); before, one ``axvline`` per event took 4 min and
4.76 GB for 348 156 events. ``report.html`` is written to a temporary file and renamed, so an interrupted report
never leaves a partial page.
"""

from __future__ import annotations

import base64
import csv
import html
import io
import json
import math
import os
import re
from array import array
from collections.abc import Iterable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..recording.formatting import readable_number

__all__ = ["MARKS_PER_KIND", "EventDigest", "digest_events", "fault_spans", "load_nav_csv", "load_psns_csv",
           "write_report"]

#: events of one kind drawn as individual marks on the mode timeline; beyond it, a rate histogram
MARKS_PER_KIND = 300
#: bins of an event-rate histogram (the cost of drawing it does not grow with the events)
RATE_BINS = 400
#: a line of events.jsonl longer than this is skipped and counted (the recorder's lines are < 1 KB)
EVENT_LINE_MAX_CHARS = 1 << 20
#: the prefix :meth:`emulator.recording.recorder.Recorder.emit` writes (``json.dumps`` of t_s, source, event first)
_PREFIX = re.compile(r'\{"t_s": (-?[0-9][0-9.eE+-]*), "source": "([^"\\]*)", "event": "([^"\\]*)"')


@dataclass
class EventDigest:
    """What the report needs of ``events.jsonl``, aggregated in one streaming pass (:func:`digest_events`):
    memory grows by 8 bytes per event (its time, s) plus the detail of the few kinds drawn individually."""

    faults: list[dict[str, Any]] = field(default_factory=list)  #: ``source == "fault"`` events
    gnss_t: array[float] = field(default_factory=lambda: array("d"))  #: GNSS update times (s)
    gnss_n: array[float] = field(default_factory=lambda: array("d"))  #: measurements per update
    gnss_innov: array[float] = field(default_factory=lambda: array("d"))  #: largest normalised innovation (sigma)
    marks: dict[str, array[float]] = field(default_factory=dict)  #: other kinds: their times (s)
    total: int = 0  #: events read
    skipped: int = 0  #: lines that were not an event (truncated, not JSON, too long)


_DETAIL_KINDS = ("gnss_update",)
_UNMARKED_KINDS = ("gnss_update", "psns_update")


def _num(x: Any) -> float:
    try:
        return float(x)
    except (TypeError, ValueError):
        return math.nan


def digest_events(path: Path) -> EventDigest:
    """Stream ``path`` (an ``events.jsonl``) into an :class:`EventDigest`; a missing file gives an empty one. A
    line that is not a JSON object (a truncated last line of an interrupted run, non-UTF-8 bytes, a line longer
    than :data:`EVENT_LINE_MAX_CHARS`) is skipped and counted."""
    d = EventDigest()
    if not path.is_file():
        return d
    marks = d.marks
    with open(path, encoding="utf-8", errors="replace") as f:
        for line in f:
            if len(line) > EVENT_LINE_MAX_CHARS:
                d.skipped += 1
                continue
            m = _PREFIX.match(line)
            if m is not None and m.group(2) != "fault" and m.group(3) not in _DETAIL_KINDS:
                t = _num(m.group(1))
                kind = m.group(3)
                if kind not in _UNMARKED_KINDS and t == t:
                    marks.setdefault(kind, array("d")).append(t)
                d.total += 1
                continue
            if not line.strip():
                continue
            try:
                ev = json.loads(line)
            except ValueError:
                d.skipped += 1
                continue
            if not isinstance(ev, dict):
                d.skipped += 1
                continue
            d.total += 1
            kind = str(ev.get("event", ""))
            t = _num(ev.get("t_s"))
            if ev.get("source") == "fault":
                d.faults.append(ev)
            elif kind == "gnss_update":
                if t == t:
                    d.gnss_t.append(t)
                    d.gnss_n.append(_num(ev.get("n_meas")))
                    d.gnss_innov.append(_num(ev.get("max_norm_innov")))
            elif kind not in _UNMARKED_KINDS and t == t:
                marks.setdefault(kind, array("d")).append(t)
    return d


_MODE_BITS = [(0x0001, "aligning"), (0x0002, "navigating"), (0x0004, "GNSS-aided"), (0x0008, "PSNS-aided"),
              (0x0010, "degraded")]


def load_nav_csv(path: Path, text_columns: tuple[str, ...] = ()) -> dict[str, list[Any]]:
    """Columns of ``nav.csv`` (or another of the run's CSV files) as float lists (empty cells become NaN); the
    ``text_columns`` stay strings."""
    cols: dict[str, list[Any]] = {}
    with open(path, newline="", encoding="utf-8") as f:
        r = csv.reader(f)
        header = next(r, None)
        if header is None:
            return {}
        for h in header:
            cols[h] = []
        for row in r:
            for h, v in zip(header, row):
                if h in text_columns:
                    cols[h].append(v)
                    continue
                try:
                    cols[h].append(float(v) if v != "" else math.nan)
                except ValueError:
                    cols[h].append(math.nan)
    return cols


def _png(fig: Any) -> str:
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=90, bbox_inches="tight")
    import matplotlib.pyplot as plt

    plt.close(fig)
    return base64.b64encode(buf.getvalue()).decode("ascii")


def fault_spans(events: Iterable[dict[str, Any]]) -> list[tuple[float, float, str]]:
    """``(start, end, label)`` of every fault in ``events`` (``fault_start`` / ``fault_end`` pairs by index)."""
    starts: dict[Any, tuple[float, str, float | None]] = {}
    spans = []
    for ev in events:
        if ev.get("source") != "fault":
            continue
        idx = ev.get("index")
        if ev.get("event") == "fault_start":
            starts[idx] = (float(ev.get("t_s", 0.0)), f"#{idx} {ev.get('fault', '')}", ev.get("end_s"))
        elif ev.get("event") == "fault_end" and idx in starts:
            t0, label, _ = starts.pop(idx)
            spans.append((t0, float(ev.get("t_s", t0)), label))
    for t0, label, end in starts.values():  # an interrupted run: the fault's scheduled end
        spans.append((t0, float(end) if end is not None else t0, label))
    return sorted(spans)


def _shade(ax: Any, spans: list[tuple[float, float, str]]) -> None:
    for t0, t1, _ in spans:
        ax.axvspan(t0, max(t1, t0 + 1e-3), color="orange", alpha=0.15, lw=0)


def _err_panel(ax: Any, t: list[float], err: list[float], sig: list[float] | None, label: str, unit: str) -> None:
    ax.plot(t, err, lw=0.8, label=f"{label} error")
    if sig is not None:
        s3 = [3 * s for s in sig]
        ax.plot(t, s3, "r--", lw=0.6, label="+-3 sigma (filter)")
        ax.plot(t, [-v for v in s3], "r--", lw=0.6)
    ax.set_ylabel(unit)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper right", fontsize=7)


def _nav_figures(nav: dict[str, list[float]], digest: EventDigest) -> list[tuple[str, str]]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out: list[tuple[str, str]] = []
    t = nav.get("time_s", [])
    if not t:
        return out
    spans = fault_spans(digest.faults)
    # The filter's tilt sigmas are about East/North; roll is about the body's forward axis and pitch
    # about its right axis, so rotate them by the heading h: forward = (sin h, cos h), right = (cos h, -sin h).
    sig_roll, sig_pitch = [], []
    for h, se, sn in zip(nav.get("heading_deg", []), nav.get("sig_att_e_deg", []), nav.get("sig_att_n_deg", [])):
        sh, ch = math.sin(math.radians(h)), math.cos(math.radians(h))
        sig_roll.append(math.sqrt((sh * se) ** 2 + (ch * sn) ** 2))
        sig_pitch.append(math.sqrt((ch * se) ** 2 + (sh * sn) ** 2))
    def error_figure(title: str, panels: list[tuple[str, Any, str, str]]) -> str:
        """Three stacked error panels (column, sigma column, label, unit) with the outage/fault spans shaded."""
        fig, axes = plt.subplots(3, 1, figsize=(10, 7), sharex=True)
        for ax, (col, sig, name, unit) in zip(axes, panels):
            _err_panel(ax, t, nav.get(col, []), sig, name, unit)
            _shade(ax, spans)
        axes[-1].set_xlabel("time (s)")
        fig.suptitle(f"{title} against truth")
        return _png(fig)

    out.append(("Attitude error", error_figure("attitude error", [
        ("err_roll_deg", sig_roll, "roll", "deg"), ("err_pitch_deg", sig_pitch, "pitch", "deg"),
        ("err_heading_deg", nav.get("sig_att_u_deg"), "heading", "deg")])))
    out.append(("Velocity error", error_figure("velocity error", [
        (f"err_vel_{a}_mps", nav.get(f"sig_vel_{a}_mps"), f"v_{a.upper()}", "m/s") for a in "enu"])))
    out.append(("Position error", error_figure("position error", [
        (f"err_pos_{a}_m", nav.get(f"sig_pos_{a}_m"), f"p_{a.upper()}", "m") for a in "enu"])))
    nees = _nees_figure(plt, nav, spans)
    if nees is not None:
        out.append(("Filter consistency (NEES)", nees))

    # mode timeline + fault bars + events
    n_rows = len(_MODE_BITS) + len(spans)
    fig, ax = plt.subplots(figsize=(10, 2.8 + 0.25 * len(spans)))
    modes = nav.get("mode", [])
    for i, (bit, name) in enumerate(_MODE_BITS):
        on = [1 if (not math.isnan(m) and int(m) & bit) else 0 for m in modes]
        ax.fill_between(t, i, [i + 0.8 * v for v in on], step="post", alpha=0.6, label=name)
    for j, (t0, t1, _label) in enumerate(spans):
        row = len(_MODE_BITS) + j
        ax.broken_barh([(t0, max(t1 - t0, 1e-3))], (row, 0.8), color="orange", alpha=0.8)
    ax.set_yticks([i + 0.4 for i in range(n_rows)])
    ax.set_yticklabels([n for _, n in _MODE_BITS] + [label for _, _, label in spans], fontsize=8)
    many = {k: v for k, v in digest.marks.items() if len(v) > MARKS_PER_KIND}
    for kind, times in sorted(digest.marks.items()):
        if kind in many:
            continue
        color = "red" if "fault" in kind or "miss" in kind or "reject" in kind else "k"
        ax.vlines(list(times), 0, n_rows, colors=color, lw=0.6, alpha=0.7, label=kind)  # one collection per kind
    ax.set_xlabel("time (s)")
    ax.set_title("mode timeline, faults (orange) and events"
                 + (f" ({len(many)} kind(s) with more than {MARKS_PER_KIND} events: see Event rate)" if many else ""))
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=6, ncol=1, borderaxespad=0.0)
    out.append(("Mode timeline", _png(fig)))
    if many:
        out.append(("Event rate", _event_rate_figure(plt, many, t)))
    return out


def _event_rate_figure(plt: Any, many: dict[str, array[float]], t: list[float]) -> str:
    """Events per second of each kind with more than :data:`MARKS_PER_KIND` events: a step histogram of
    :data:`RATE_BINS` bins (the cost of drawing it does not depend on the number of events)."""
    import numpy as np

    fig, ax = plt.subplots(figsize=(10, 2.8))
    lo = min([min(v) for v in many.values()] + [t[0]])
    hi = max([max(v) for v in many.values()] + [t[-1]])
    edges = np.linspace(lo, hi if hi > lo else lo + 1.0, RATE_BINS + 1)
    width = float(edges[1] - edges[0])
    for kind, times in sorted(many.items()):
        counts, _ = np.histogram(np.frombuffer(times, dtype=np.float64), bins=edges)
        ax.stairs(counts / width, edges, label=f"{kind} ({len(times):,} events)".replace(",", " "))
    ax.set_yscale("symlog", linthresh=1.0)
    ax.set_ylabel("events per second")
    ax.set_xlabel("time (s)")
    ax.set_title(f"event rate (kinds with more than {MARKS_PER_KIND} events; {RATE_BINS} bins)")
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=6, borderaxespad=0.0)
    return _png(fig)


def _nees_figure(plt: Any, nav: dict[str, list[float]], spans: list[tuple[float, float, str]]) -> str | None:
    """NEES of this run over time (diagonal form, ``sum (error / sigma)^2`` of the group) for velocity, position and
    heading, with the two-sided 95 % chi-square bounds of one run (``psns-hil campaign --consistency`` averages N runs
    and narrows them; emulator/distributed/campaign/consistency.py). Points outside the band are expected about 5 % of
    the time; most of them above: the sigma is too small."""
    from ..scenario.consistency_schema import chi2_bounds

    t = nav.get("time_s", [])
    groups = [("velocity", [f"vel_{a}_mps" for a in "enu"]), ("position", [f"pos_{a}_m" for a in "enu"])]
    fig, axes = plt.subplots(3, 1, figsize=(10, 7), sharex=True)
    drawn = False
    for ax, (name, cols) in zip(axes, [*groups, ("heading", None)]):
        tt, vals = [], []
        for i, ti in enumerate(t):
            try:
                if cols is None:  # heading error against the vertical tilt sigma
                    e, sg = nav["err_heading_deg"][i], nav["sig_att_u_deg"][i]
                    v = (e / sg) ** 2
                else:
                    v = sum((nav[f"err_{c}"][i] / nav[f"sig_{c}"][i]) ** 2 for c in cols)
            except (KeyError, IndexError, ZeroDivisionError):
                continue
            if math.isfinite(v):
                tt.append(ti)
                vals.append(v)
        dof = 1 if cols is None else len(cols)
        lo, hi = chi2_bounds(1, dof, 0.95)
        if vals:
            drawn = True
            ax.semilogy(tt, [max(v, 1e-6) for v in vals], lw=0.6, label=f"NEES {name}")
            inside = sum(lo <= v <= hi for v in vals) / len(vals)
            ax.set_title(f"{name}: {100 * inside:.0f} % inside the 95 % band of one run ({dof} dof)", fontsize=9)
        for b in (lo, hi):
            ax.axhline(b, color="r", lw=0.8, ls="--")
        ax.axhline(dof, color="k", lw=0.6, ls=":")
        _shade(ax, spans)
        ax.set_ylabel("NEES")
    axes[-1].set_xlabel("time (s)")
    fig.suptitle("normalised estimation error squared against the chi-square bounds")
    if not drawn:
        plt.close(fig)
        return None
    return _png(fig)


def _plt() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _en_m(lat: list[float], lon: list[float], lat0: float, lon0: float) -> tuple[list[float], list[float]]:
    """East/North offsets (m) from (lat0, lon0), local flat-Earth (a report plot, not a navigation equation)."""
    r = 6378137.0
    c = math.cos(math.radians(lat0))
    return ([math.radians(b - lon0) * r * c for b in lon], [math.radians(a - lat0) * r for a in lat])


def _bit_spans(t: list[float], flags: list[float], bit: int, want: bool) -> list[tuple[float, float]]:
    """Time spans where ``flags & bit`` is ``want`` (NaN rows count as not set)."""
    spans, start = [], None
    for tt, m in zip(t, flags):
        on = (not math.isnan(m) and bool(int(m) & bit)) == want
        if on and start is None:
            start = tt
        elif not on and start is not None:
            spans.append((start, tt))
            start = None
    if start is not None and t:
        spans.append((start, t[-1]))
    return spans


#: how many sigma ellipses the trajectory map draws along the estimate
MAP_ELLIPSES = 12
#: the ellipses' scale: 3 sigma of the filter's own East/North position sigma
MAP_ELLIPSE_SIGMAS = 3.0


def _trajectory_figure(nav: dict[str, list[float]], truth: dict[str, list[float]],
                       events: list[dict[str, Any]]) -> list[tuple[str, str]]:
    """Truth and estimate of the navigating frames (NAVIGATING bit set: not the frames sent before the coarse
    alignment ends, which carry lat = lon = 0) on a local map, East/North metres of the ENU frame about the true
    position at the first navigating frame (WGS-84, pymap3d). Periods without GNSS aiding (>= 2 s) and fault
    windows are drawn over the estimate, and the filter's 3 sigma East/North position ellipse at
    :data:`MAP_ELLIPSES` instants."""
    import numpy as np
    import pymap3d

    t = np.asarray(nav.get("time_s", []), dtype=float)
    lat, lon = np.asarray(nav.get("lat_deg", []), dtype=float), np.asarray(nav.get("lon_deg", []), dtype=float)
    h = np.asarray(nav.get("height_m", [0.0] * len(t)), dtype=float)
    modes = np.asarray(nav.get("mode", []), dtype=float)
    tl = np.asarray(truth.get("time_s", []), dtype=float)
    if not t.size or not tl.size or modes.size != t.size:
        return []
    bits = np.where(np.isfinite(modes), modes, 0).astype(np.int64)
    on = ((bits & 0x0002) != 0) & np.isfinite(lat) & np.isfinite(lon)
    if not on.any():
        return []
    t, lat, lon, h, bits = t[on], lat[on], lon[on], h[on], bits[on]
    t0, t1 = float(t[0]), float(t[-1])
    tsel = (tl >= t0 - 1e-9) & (tl <= t1 + 1e-9)
    if not tsel.any():
        tsel = np.abs(tl - t0) == np.abs(tl - t0).min()
    tlat = np.asarray(truth["lat_deg"], dtype=float)[tsel]
    tlon = np.asarray(truth["lon_deg"], dtype=float)[tsel]
    th = np.asarray(truth.get("height_m", [0.0] * tl.size), dtype=float)[tsel]
    lat0, lon0, h0 = float(tlat[0]), float(tlon[0]), float(th[0])
    te, tn, _ = pymap3d.geodetic2enu(tlat, tlon, th, lat0, lon0, h0)
    ee, en, _ = pymap3d.geodetic2enu(lat, lon, h, lat0, lon0, h0)
    te, tn, ee, en = (np.atleast_1d(np.asarray(v, dtype=float)) for v in (te, tn, ee, en))
    plt = _plt()
    from matplotlib.patches import Ellipse

    fig, ax = plt.subplots(figsize=(8.5, 7.0))
    ax.plot(te, tn, "k-", lw=1.6, label="truth")
    ax.plot(ee, en, "-", color="tab:blue", lw=0.9, alpha=0.85, label="estimate")
    ax.plot(te[:1], tn[:1], "o", color="tab:green", ms=7, label=f"start of navigation (t = {t0:.1f} s)")
    ax.plot(te[-1:], tn[-1:], "s", color="k", ms=6, label=f"end (t = {t1:.1f} s)")

    def mark(spans: list[tuple[float, float]], label: str, **style: Any) -> None:
        first = True
        for a, b in spans:
            sel = (t >= a) & (t <= b)
            if sel.any():
                ax.plot(ee[sel], en[sel], label=label if first else None, **style)
                first = False

    outages = [s for s in _bit_spans(t.tolist(), bits.astype(float).tolist(), 0x0004, False) if s[1] - s[0] >= 2.0]
    mark(outages, "no GNSS aiding (>= 2 s)", color="tab:orange", lw=5.0, alpha=0.5, solid_capstyle="round")
    mark([(a, b) for a, b, _ in fault_spans(events)], "fault active", color="tab:red", lw=1.6, ls=(0, (2, 2)))
    se = np.asarray(nav.get("sig_pos_e_m", []), dtype=float)
    sn = np.asarray(nav.get("sig_pos_n_m", []), dtype=float)
    if se.size == on.size and sn.size == on.size:
        se, sn = se[on], sn[on]
        first = True
        for k in np.unique(np.linspace(0, t.size - 1, MAP_ELLIPSES).astype(int)):
            if np.isfinite(se[k]) and np.isfinite(sn[k]) and se[k] > 0 and sn[k] > 0:
                ax.add_patch(Ellipse((ee[k], en[k]), 2 * MAP_ELLIPSE_SIGMAS * se[k], 2 * MAP_ELLIPSE_SIGMAS * sn[k],
                                     fill=False, ec="tab:purple", lw=0.9, alpha=0.8,
                                     label=f"filter {MAP_ELLIPSE_SIGMAS:g} sigma (E, N)" if first else None))
                first = False
    ax.set_xlabel("East (m)")
    ax.set_ylabel("North (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.autoscale_view()
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
    ax.set_title(f"navigating track, ENU metres about {lat0:.5f} N, {lon0:.5f} E ({t.size} frames)", fontsize=10)
    return [("Trajectory map", _png(fig))]


def _attitude_vs_truth_figure(nav: dict[str, list[float]], truth: dict[str, list[float]],
                              events: list[dict[str, Any]]) -> list[tuple[str, str]]:
    """Roll, pitch and heading: the estimate with the filter's 3 sigma band, against truth."""
    t = nav.get("time_s", [])
    if not t or not truth.get("time_s"):
        return []
    plt = _plt()
    import numpy as np

    tt = np.asarray(truth["time_s"])
    fig, axes = plt.subplots(3, 1, figsize=(10, 7.5), sharex=True)
    sig_h = nav.get("sig_att_u_deg", [])
    se, sn = nav.get("sig_att_e_deg", []), nav.get("sig_att_n_deg", [])
    sig_tilt = [math.hypot(a, b) / math.sqrt(2) for a, b in zip(se, sn)]
    for ax, col, sig in zip(axes, ("roll_deg", "pitch_deg", "heading_deg"), (sig_tilt, sig_tilt, sig_h)):
        est = np.asarray(nav.get(col, []), dtype=float)
        if est.size == 0:
            continue
        tv = np.asarray(truth.get(col, []), dtype=float)
        ta = np.asarray(t, dtype=float)
        if col == "heading_deg" and tv.size:  # unwrap both on the truth's branch, so 359 -> 1 is no jump
            ref = np.interp(ta, tt, np.unwrap(np.radians(tv)))
            est = np.degrees(ref + (np.radians(est) - ref + np.pi) % (2 * np.pi) - np.pi)
            tv = np.degrees(np.unwrap(np.radians(tv)))
        nav_on = np.asarray([not math.isnan(m) and bool(int(m) & 0x0002) for m in nav.get("mode", [])], dtype=bool)
        if nav_on.size == est.size:
            est = np.where(nav_on, est, np.nan)  # before alignment there is no estimate to show
        if tv.size:
            ax.plot(tt, tv, "k-", lw=1.2, label="truth")
        ax.plot(ta, est, "-", color="tab:blue", lw=0.8, label="estimate")
        if len(sig) == est.size:
            s3 = 3.0 * np.asarray(sig, dtype=float)
            ax.fill_between(ta, est - s3, est + s3, color="tab:blue", alpha=0.2, lw=0, label="estimate +-3 sigma")
        _shade(ax, fault_spans(events))
        ax.set_ylabel(col.replace("_deg", " (deg)"))
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    axes[-1].set_xlabel("time (s)")
    fig.suptitle("attitude and heading against truth")
    return [("Attitude and heading against truth", _png(fig))]


def _error_cdf_figure(nav: dict[str, list[float]]) -> list[tuple[str, str]]:
    """Empirical CDF of the absolute errors while navigating (heading, attitude, position, velocity)."""
    cols = [("err_heading_deg", "heading (deg)"), ("err_att_deg", "attitude (deg)"), ("err_pos_m", "position (m)"),
            ("err_vel_mps", "velocity (m/s)")]
    data = [(label, sorted(abs(v) for v in nav.get(c, []) if not math.isnan(v))) for c, label in cols]
    data = [(label, v) for label, v in data if v]
    if not data:
        return []
    plt = _plt()
    fig, axes = plt.subplots(1, len(data), figsize=(3.0 * len(data) + 1, 3.2), squeeze=False)
    for ax, (label, v) in zip(axes[0], data):
        n = len(v)
        ax.step(v, [(i + 1) / n for i in range(n)], where="post", lw=1.0)
        for q, ls in ((0.5, ":"), (0.95, "--")):
            x = v[min(n - 1, int(q * n))]
            # the quantile in the legend, not as text beside the line: a label at the axis' right edge is clipped
            ax.axvline(x, color="grey", ls=ls, lw=0.8, label=f"{int(q * 100)} %: {_fmt(x)}")
        ax.legend(loc="lower right", fontsize=7)
        ax.set_xlabel(f"|error| {label}")
        ax.set_ylim(0, 1.02)
        ax.grid(True, alpha=0.3)
    axes[0][0].set_ylabel("fraction of navigating frames")
    fig.suptitle("error CDF (while navigating)")
    return [("Error CDF", _png(fig))]


def _gnss_figure(nav: dict[str, list[float]], digest: EventDigest,
                 series: dict[str, list[float]] | None = None) -> list[tuple[str, str]]:
    """GNSS: updates used (measurements per update, largest normalised innovation), the aided periods, and what the
    receiver reported (satellites used and DOP, decoded from the capture: :func:`sensor_series`)."""
    ups = digest.gnss_t
    t = nav.get("time_s", [])
    sv = series or {}
    if not ups and not t and not sv.get("gnss_t"):
        return []
    plt = _plt()
    fig, axes = plt.subplots(3, 1, figsize=(10, 6.5), sharex=True)
    ax3 = axes[2]
    if sv.get("gnss_t"):
        ax3.plot(sv["gnss_t"], sv["gnss_sats"], "b.", ms=3, label="satellites used")
        ax3.set_ylabel("satellites")
        ax3.set_ylim(0, max([x for x in sv["gnss_sats"] if x == x] + [4]) + 2)
        ax3b = ax3.twinx()
        ax3b.plot(sv["gnss_t"], sv["gnss_dop"], "g-", lw=0.8, label="DOP (HDOP, or pDOP for UBX)")
        ax3b.set_ylabel("DOP")
        ax3b.set_ylim(0, max([x for x in sv["gnss_dop"] if x == x] + [2]) * 1.2)
        ax3b.legend(loc="upper right", fontsize=7)
        ax3.set_title(f"receiver: {len(sv['gnss_t'])} fixes in the capture")
    else:
        ax3.text(0.5, 0.5, "no modelled or captured receiver output", transform=ax3.transAxes, ha="center")
    ax3.legend(loc="upper left", fontsize=7)
    ax3.grid(True, alpha=0.3)
    ax = axes[0]
    if ups:
        ax.plot(list(ups), list(digest.gnss_n), "o", ms=3, label="measurements per update")
        ax2 = ax.twinx()
        ax2.plot(list(ups), list(digest.gnss_innov), "r.", ms=3, label="largest normalised innovation")
        ax2.set_ylabel("innovation (sigma)")
        ax2.legend(loc="upper right", fontsize=7)
    else:
        ax.text(0.5, 0.5, "no GNSS update in this run", transform=ax.transAxes, ha="center")
    ax.set_ylabel("measurements")
    ax.legend(loc="upper left", fontsize=7)
    ax.set_title(f"GNSS: {len(ups)} updates")
    ax.grid(True, alpha=0.3)
    modes = nav.get("mode", [])
    axes[1].fill_between(t, 0, [1 if not math.isnan(m) and int(m) & 0x0004 else 0 for m in modes], step="post",
                         alpha=0.6, label="GNSS-aided")
    status = nav.get("gnss_status", [])
    if status:
        axes[1].plot(t, [min(v, 255) / 255 if not math.isnan(v) else math.nan for v in status], "k-", lw=0.6,
                     label="gnss_status (/255)")
    axes[1].set_ylim(-0.05, 1.1)
    axes[2].set_xlabel("time (s)")
    axes[1].legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7)
    return [("GNSS", _png(fig))]


def sensor_series(run_dir: Path) -> dict[str, list[float]]:
    """What the sensors sent, decoded from the run's capture with the ports' own stream decoders.

    ``gnss_t``/``gnss_sats``/``gnss_dop``: per GGA (satellites used, HDOP) or NAV-PVT (numSV, pDOP / 100);
    ``psns_t``/``psns_points``/``psns_dop``: per polarization frame (points sent, their mean DOP) or compass frame
    (units, mean DOP). Times are arrival times at the FPGA (s). Empty lists when the capture holds no such link.
    """
    from protocols.nmea import Gga
    from protocols.psns import CompassFrame, PolarizationObs
    from protocols.stream import StreamDecoder
    from protocols.ubx import NavPvt

    from ..assembly.ports import port_formats
    from ..recording.capture import iter_capture

    out: dict[str, list[float]] = {k: [] for k in ("gnss_t", "gnss_sats", "gnss_dop", "psns_t", "psns_points",
                                                    "psns_dop")}
    cap = run_dir / "capture.psnscap"
    if not cap.exists():
        return out
    decoders = {name: StreamDecoder(port_formats(name)["in"]) for name in ("gnss", "psns")}
    try:
        _header, records = iter_capture(cap)
        for r in records:
            dec = decoders.get(r.link) if r.direction == "in" else None
            if dec is None:
                continue
            for fr in dec.feed(r.data):
                if isinstance(fr, Gga) and fr.quality > 0:
                    out["gnss_t"].append(r.t_s)
                    out["gnss_sats"].append(math.nan if fr.num_sats is None else fr.num_sats)
                    out["gnss_dop"].append(math.nan if fr.hdop is None else fr.hdop)
                elif isinstance(fr, NavPvt) and fr.fixType >= 2:
                    out["gnss_t"].append(r.t_s)
                    out["gnss_sats"].append(fr.numSV)
                    out["gnss_dop"].append(fr.pDOP / 100.0)
                elif isinstance(fr, PolarizationObs | CompassFrame):
                    pts = fr.points if isinstance(fr, PolarizationObs) else fr.units
                    out["psns_t"].append(r.t_s)
                    out["psns_points"].append(len(pts))
                    out["psns_dop"].append(sum(p.dop for p in pts) / 65535.0 / len(pts) if pts else math.nan)
    except (OSError, ValueError):  # a truncated capture of an interrupted run: what was read is kept
        pass
    return out


def _sun_track(summary: dict[str, Any], truth: dict[str, list[float]]) -> tuple[list[float], list[float],
                                                                                list[float]]:
    """Sun azimuth and elevation (deg) over the run at the truth's position, 200 samples (world sun model)."""
    t = truth.get("time_s", [])
    epoch = summary.get("epoch")
    if not t or not epoch:
        return [], [], []
    import datetime as _dt

    from ..world.sun import SunModel

    sun = SunModel(_dt.datetime.fromisoformat(epoch))
    step = max(1, len(t) // 200)
    ts, az, el = [], [], []
    for k in range(0, len(t), step):
        a, e = sun.az_el(t[k], math.radians(truth["lat_deg"][k]), math.radians(truth["lon_deg"][k]),
                         truth["height_m"][k])
        ts.append(t[k])
        az.append(math.degrees(a) % 360.0)
        el.append(math.degrees(e))
    return ts, az, el


def _psns_figure(nav: dict[str, list[float]], events: list[dict[str, Any]],
                 counters: dict[str, Any] | None = None, series: dict[str, list[float]] | None = None,
                 sun: tuple[list[float], list[float], list[float]] = ([], [], [])) -> list[tuple[str, str]]:
    """PSNS / sky: the per-frame PSNS status (solar vector used / rejected), the PSNS-aided periods, the firmware's
    PSNS counters (frames, solutions, updates, rejections), the sun's azimuth and elevation (world model) and what
    the sensor sent (points per frame and their mean DOP, decoded from the capture)."""
    t = nav.get("time_s", [])
    modes = nav.get("mode", [])
    status = nav.get("psns_status", [])
    aided = [1 if not math.isnan(m) and int(m) & 0x0008 else 0 for m in modes]
    used = [x for x, v in zip(t, status) if v == 1]
    rejected = [x for x, v in zip(t, status) if v == 2]
    c = {k: v for k, v in (counters or {}).items() if k.startswith("psns_")}
    if not used and not rejected and not any(aided) and not c.get("psns_frames") \
            and not (series or {}).get("psns_t"):
        return []  # no polarization sensor in this run: no empty panel
    plt = _plt()
    fig, axes = plt.subplots(4, 1, figsize=(10, 8.5), sharex=True)
    sv = series or {}
    ax = axes[2]
    if sun[0]:
        ax.plot(sun[0], sun[2], "-", color="tab:orange", label="sun elevation")
        ax.set_ylabel("elevation (deg)")
        axb = ax.twinx()
        axb.plot(sun[0], sun[1], "--", color="tab:brown", lw=0.8, label="sun azimuth")
        axb.set_ylabel("azimuth (deg)")
        axb.legend(loc="upper right", fontsize=7)
        ax.set_title(f"sun: elevation {min(sun[2]):.1f} to {max(sun[2]):.1f} deg, azimuth {min(sun[1]):.1f} to "
                     f"{max(sun[1]):.1f} deg")
        ax.legend(loc="upper left", fontsize=7)
    else:
        ax.text(0.5, 0.5, "no truth or epoch: sun track not shown", transform=ax.transAxes, ha="center")
    ax.grid(True, alpha=0.3)
    ax = axes[3]
    if sv.get("psns_t"):
        ax.plot(sv["psns_t"], sv["psns_points"], "b.", ms=3, label="points (or compass units) per frame")
        ax.set_ylabel("points")
        axb = ax.twinx()
        axb.plot(sv["psns_t"], sv["psns_dop"], "g.", ms=2, label="mean DOP of the frame")
        axb.set_ylabel("DOP")
        axb.set_ylim(0, 1)
        axb.legend(loc="upper right", fontsize=7)
        ax.legend(loc="upper left", fontsize=7)
        ax.set_title(f"sensor: {len(sv['psns_t'])} frames in the capture")
    else:
        ax.text(0.5, 0.5, "no polarization frames in the capture", transform=ax.transAxes, ha="center")
    ax.grid(True, alpha=0.3)
    ax.set_xlabel("time (s)")
    ax = axes[0]
    ax.plot(used, [1] * len(used), "|", color="tab:green", ms=8, label=f"solar vector used ({len(used)} frames)")
    ax.plot(rejected, [0] * len(rejected), "|", color="tab:red", ms=8, label=f"rejected ({len(rejected)} frames)")
    ax.set_yticks([0, 1])
    ax.set_yticklabels(["rejected", "used"])
    ax.set_ylim(-0.5, 1.5)
    ax.set_title("PSNS / sky: " + (", ".join(f"{k[5:]} {_fmt(v)}" for k, v in c.items()) or "solar-vector use"))
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7)
    axes[1].fill_between(t, 0, aided, step="post", alpha=0.6, color="tab:purple", label="PSNS-aided")
    axes[1].set_ylim(-0.05, 1.1)
    axes[1].legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7)
    return [("PSNS and sky", _png(fig))]


def load_psns_csv(path: Path) -> dict[str, list[Any]]:
    """``psns.csv`` (the recorder's solved solar vectors against truth, emulator/recording/psns_error.py) as
    columns: numbers as floats (an empty cell NaN), ``source`` and ``use`` as text; {} without the file."""
    return load_nav_csv(path, text_columns=("source", "use")) if path.exists() else {}


def _solar_error_figure(psns: dict[str, list[Any]]) -> list[tuple[str, str]]:
    """The solved solar vector against truth over time (``psns.csv``): the angle between the solved and the true
    bi-direction vector and its azimuth / elevation parts in ENU, deg, accepted solves apart from the others."""
    t = psns.get("time_s", [])
    if not t:
        return []
    plt = _plt()
    fig, axes = plt.subplots(2, 1, figsize=(10, 5.5), sharex=True)
    use = psns.get("use", [])
    for ax, key, title in ((axes[0], "err_deg", "angle between solved and true solar vector"),
                           (axes[1], None, "azimuth and elevation parts (solve turned to ENU with the true attitude)")):
        if key is not None:
            for accepted, color, label in ((True, "tab:green", "accepted by the filter"),
                                           (False, "tab:gray", "not used (refused, alignment, sun low...)")):
                sel = [i for i, u in enumerate(use) if (u == "accepted") == accepted]
                ax.plot([t[i] for i in sel], [psns[key][i] for i in sel], ".", ms=3, color=color,
                        label=f"{label} ({len(sel)})")
            ax.set_ylabel("deg")
        else:
            ax.plot(t, psns.get("err_az_deg", []), ".", ms=3, color="tab:blue", label="azimuth")
            ax.plot(t, psns.get("err_el_deg", []), ".", ms=3, color="tab:orange", label="elevation")
            ax.axhline(0.0, color="k", lw=0.6)
            ax.set_ylabel("signed error (deg)")
        ax.set_title(title)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="upper right", fontsize=7)
    axes[1].set_xlabel("time (s)")
    return [("Solar vector against truth", _png(fig))]


def _timeline_figures(path: Path) -> list[tuple[str, str]]:
    if not path.exists():
        return []
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cols = load_nav_csv(path)
    t = cols.get("time_s", [])
    if not t:
        return []
    out = []
    err_cols = [c for c in cols if c.endswith(("crc_errors", "dropped", "garbage_bytes", "framing_errors"))
                and any(v for v in cols[c] if not math.isnan(v))]
    if err_cols:  # no plot at all when no link ever counted an error (an empty axis reads as a failure)
        fig, ax = plt.subplots(figsize=(10, 3.5))
        for c in err_cols:
            ax.plot(t, cols[c], lw=0.8, label=c)
        ax.set_yscale("symlog", linthresh=1.0)
        ax.set_xlabel("time (s)")
        ax.set_ylabel("cumulative count (symlog)")
        ax.set_title("link error counters")
        ax.grid(True, alpha=0.3)
        if ax.lines:
            ax.legend(fontsize=7)
        out.append(("Link errors over time", _png(fig)))
    if "cpu_load_pct" in cols:
        fig, ax = plt.subplots(figsize=(10, 3))
        ax.plot(t, cols["cpu_load_pct"], lw=0.8, label="CPU load (% of each second)")
        ax.set_xlabel("time (s)")
        ax.set_ylabel("% of 1 s")
        ax.set_title("DSP CPU load and deadline misses")
        ax.grid(True, alpha=0.3)
        if "deadline_misses" in cols:  # drawn also when it stays 0: a flat trace says none, no trace says nothing
            misses = cols["deadline_misses"]
            total = max([v for v in misses if not math.isnan(v)] + [0.0])
            ax2 = ax.twinx()
            ax2.plot(t, misses, "r-", lw=1.0, label=f"deadline misses (cumulative): {_fmt(int(total))}")
            ax2.set_ylabel("deadline misses")
            ax2.set_ylim(-0.05 * max(total, 1.0), 1.1 * max(total, 1.0))
            ax2.legend(loc="upper left", fontsize=7)
        ax.legend(loc="upper right", fontsize=7)
        out.append(("DSP load over time", _png(fig)))
    return out


def _task_figure(summary: dict[str, Any]) -> list[tuple[str, str]]:
    tasks = summary.get("dsp", {}).get("tasks", [])
    if not tasks:
        return []
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    dsp = summary["dsp"]
    budget = dsp.get("tick_budget_cycles") or 1
    names = [x["task"] for x in tasks]
    avg = [100.0 * x["cycles_avg"] / budget for x in tasks]
    mx = [x["utilization_max_pct"] for x in tasks]
    if dsp.get("extra_load_ticks"):  # an injected dsp_extra_load fault, outside the firmware's own meter
        per_tick = 100.0 * dsp["extra_cycles_total"] / dsp["extra_load_ticks"] / budget
        names.append("injected extra load")
        avg.append(per_tick)
        mx.append(per_tick)
    fig, ax = plt.subplots(figsize=(10, 0.4 * len(names) + 1.2))
    y = list(range(len(names)))
    ax.barh([v + 0.2 for v in y], mx, height=0.4, color="tab:red", alpha=0.7, label="worst call")
    ax.barh([v - 0.2 for v in y], avg, height=0.4, color="tab:blue", alpha=0.7, label="average call")
    ax.set_yticks(y)
    ax.set_yticklabels(names, fontsize=8)
    ax.invert_yaxis()
    ax.set_xlabel(f"% of the tick budget ({budget} cycles)")
    ax.set_title("DSP load per task")
    ax.grid(True, axis="x", alpha=0.3)
    ax.legend(fontsize=7)
    return [("DSP load per task", _png(fig))]


class _At:
    """A value of summary.json shown in the page, with its dotted path (``nav_error.heading_deg.rms``, ``faults[0]
    .active_from_s``: the :func:`emulator.recording.formatting.finite_json` convention): the cell carries the path
    as ``data-path`` so that every number on the page can be traced to the file (tests/emulator/recording/
    test_report_numbers.py)."""

    __slots__ = ("path", "value")

    def __init__(self, summary: dict[str, Any], path: str) -> None:
        self.path = path
        self.value = _lookup(summary, path)


def _lookup(summary: dict[str, Any], path: str) -> Any:
    """The value at a dotted path with ``[i]`` list indices; None when it is not there."""
    cur: Any = summary
    for part in path.replace("[", ".[").split("."):
        if part.startswith("["):
            i = int(part[1:-1])
            cur = cur[i] if isinstance(cur, list) and i < len(cur) else None
        else:
            cur = cur.get(part) if isinstance(cur, dict) else None
        if cur is None:
            return None
    return cur


def _cell(x: Any, tag: str = "td") -> str:
    """One table cell (or ``span``): a summary value with its ``data-path``, or text."""
    if isinstance(x, _At):
        return f"<{tag} data-path='{html.escape(x.path)}'>{html.escape(_fmt(x.value))}</{tag}>"
    return f"<{tag}>{html.escape(_fmt(x))}</{tag}>"


def _table(rows: list[list[Any]], header: list[str]) -> str:
    h = "".join(f"<th>{html.escape(str(x))}</th>" for x in header)
    body = "".join("<tr>" + "".join(_cell(x) for x in r) + "</tr>" for r in rows)
    return f"<table><tr>{h}</tr>{body}</table>"


#: the page's one number format (emulator/recording/formatting.py)
_fmt = readable_number


def expectation_status(e: dict[str, Any]) -> str:
    """The result column of an expectation (summary.json's ``expectations[i]``): ``pass`` / ``FAIL``, ``not run``
    (a Python hook without ``--allow-hooks``: neither passed nor failed) or ``not applied`` (a campaign-level
    check in one run, a sensor check in a replay)."""
    if e.get("status") == "not_run" or (e.get("kind") == "python" and e.get("applicable") is False):
        return "not run"
    if e.get("applicable") is False:
        return "not applied"
    return "pass" if e.get("passed") else "FAIL"


def _nav_error_note(summary: dict[str, Any]) -> str:
    """What the navigation error table's rms and max are over (docs/runtime.md "Position rms")."""
    return ("<p>rms and max over every navigation frame that carries the NAVIGATING bit: fine alignment (the filter "
            "still settling, ALIGNING set too) and navigating proper (ALIGNING clear). Frames before the coarse "
            "alignment ends carry no solution and are not counted. <code>nav_error_by_phase</code> in summary.json "
            "holds each phase apart.</p>")


def _hz(x: Any) -> str:
    """A clock frequency in MHz (``300 MHz``, not ``3e+08 Hz``)."""
    return "-" if not isinstance(x, (int, float)) else f"{x / 1e6:g} MHz"


def write_report(run_dir: str | Path) -> Path:
    """Write ``report.html`` into ``run_dir`` and return its path."""
    run_dir = Path(run_dir)
    from ..recording.summary_model import load_summary

    summary = load_summary(run_dir).model_dump(mode="json")  # validated: a clear error for a foreign file
    nav = load_nav_csv(run_dir / "nav.csv") if (run_dir / "nav.csv").exists() else {}
    digest = digest_events(run_dir / "events.jsonl")  # streamed, aggregated per kind
    truth = load_nav_csv(run_dir / "truth.csv") if (run_dir / "truth.csv").exists() else {}
    series = sensor_series(run_dir)
    figs = (_trajectory_figure(nav, truth, digest.faults) + _attitude_vs_truth_figure(nav, truth, digest.faults)
            + _nav_figures(nav, digest) + _error_cdf_figure(nav) + _gnss_figure(nav, digest, series)
            + _psns_figure(nav, digest.faults, summary.get("firmware", {}).get("counters"), series,
                           _sun_track(summary, truth))
            + _solar_error_figure(load_psns_csv(run_dir / "psns.csv"))
            + _timeline_figures(run_dir / "timeline.csv") + _task_figure(summary))

    what = "replay" if summary.get("replay") else "run"
    parts = [f"<h1>psns-hil {what}: {html.escape(str(summary.get('scenario')))}</h1>"]
    valid = summary.get("valid", True)
    passed = summary.get("passed")
    verdict = ("INVALID: a scheduled fault never took effect" if valid is False else
               "passed" if passed else "interrupted" if summary.get("interrupted") else "FAILED")
    color = "#2a2" if passed and valid is not False else "#c22"
    parts.append(f"<p style='font-size:1.3em;color:{color}'><b>{html.escape(verdict)}</b></p>")
    def at(path: str) -> _At:
        return _At(summary, path)

    parts.append(_table([
        ["scenario file", at("scenario_file")], ["seed", at("seed")], ["mode", at("mode")],
        ["simulated (s)", at("sim_duration_s")], ["wall (s)", at("wall_s")],
        ["real-time factor", at("realtime_factor")], ["interrupted", at("interrupted")],
        ["valid (every fault took effect)", at("valid")], ["passed", at("passed")],
    ], ["item", "value"]))
    if summary.get("warnings"):
        parts.append("<h2>Warnings (fallbacks the run took)</h2><ul>" + "".join(
            f"<li>{_cell(at(f'warnings[{i}].message'), 'span')}</li>" for i in range(len(summary["warnings"])))
                     + "</ul>")
    if summary.get("faults"):
        parts.append("<h2>Faults</h2>")

        def pairs(i: int, key: str, signed: bool) -> str:
            items = (summary["faults"][i].get(key) or {})
            return ", ".join(f"{html.escape(str(k))} " + ("+" if signed and isinstance(v, (int, float)) and v > 0
                                                         else "") + _cell(at(f"faults[{i}].{key}.{k}"), "span")
                             for k, v in items.items())

        rows = []
        for i, f in enumerate(summary["faults"]):
            took = "-" if f.get("fired") is None else "yes" if f["fired"] else "NO"
            rows.append("<tr>" + "".join(_cell(at(f"faults[{i}].{k}")) for k in (
                "index", "kind", "target", "active_from_s", "active_until_s"))
                        + f"<td>{pairs(i, 'evidence', False)}</td><td>{pairs(i, 'firmware', True)}</td>"
                        + f"<td>{took}</td></tr>")
        head = "".join(f"<th>{h}</th>" for h in ("#", "fault", "target", "from (s)", "until (s)",
                                                   "evidence while active", "firmware counters", "took effect"))
        parts.append(f"<table><tr>{head}</tr>{''.join(rows)}</table>")
    parts.append("<h2>Navigation error against truth</h2>")
    parts.append(_nav_error_note(summary))
    parts.append(_table([[k, at(f"nav_error.{k}.rms"), at(f"nav_error.{k}.max")]
                         for k in summary.get("nav_error", {})], ["quantity", "rms", "max"]))
    psns = summary.get("psns") or {}
    if psns.get("solves"):
        parts.append("<h2>Solved solar vector against truth (" + _cell(at("psns.solves"), "span") + " solves: "
                     + ", ".join(f"{html.escape(str(k))} " + _cell(at(f"psns.uses.{k}"), "span")
                                 for k in (psns.get("uses") or {}))
                     + ")</h2>")
        parts.append(_table([[label, at(f"psns.{key}.median"), at(f"psns.{key}.p95"), at(f"psns.{key}.max")]
                             for key, label in (("solar_vector_error_deg", "angle (deg)"),
                                                ("azimuth_error_deg", "|azimuth| (deg)"),
                                                ("elevation_error_deg", "|elevation| (deg)"))],
                            ["quantity", "median", "p95", "max"]))
    if summary.get("expectations"):
        parts.append("<h2>Expectations</h2>")
        parts.append(_table([[at(f"expectations[{i}].index"), at(f"expectations[{i}].description"),
                              at(f"expectations[{i}].value"), at(f"expectations[{i}].message"), expectation_status(e)]
                             for i, e in enumerate(summary["expectations"])],
                            ["#", "check", "value", "note", "result"]))
    parts.append("<h2>Links</h2>")
    counters = ["bytes", "frames", "crc_errors", "dropped", "garbage_bytes", "framing_errors"]
    parts.append(_table([[k, *(at(f"links.{k}.{c}") for c in counters)] for k in summary.get("links", {})],
                        ["link", *counters]))
    dsp = summary.get("dsp", {})
    parts.append(f"<h2>DSP load (<span data-path='dsp.clock_hz' data-format='MHz'>{_hz(dsp.get('clock_hz'))}</span>"
                 f", tick budget {_cell(at('dsp.tick_budget_cycles'), 'span')} cycles)</h2>")
    task_keys = ["task", "calls", "cycles_min", "cycles_avg", "cycles_max", "utilization_max_pct"]
    parts.append(_table([[at(f"dsp.tasks[{i}].{k}") for k in task_keys] for i in range(len(dsp.get("tasks", [])))],
                        ["task", "calls", "min", "avg", "max", "max % budget"]))
    parts.append(f"<p>worst 1 s CPU load {_cell(at('dsp.cpu_load_pct_max'), 'span')} %, deadline misses "
                 f"{_cell(at('dsp.deadline_misses'), 'span')}</p>")
    for title, b64 in figs:
        parts.append(f"<h2>{html.escape(title)}</h2><img alt='{html.escape(title)}' "
                     f"src='data:image/png;base64,{b64}'/>")
    style = ("body{font-family:sans-serif;max-width:1100px;margin:auto}table{border-collapse:collapse;margin:8px 0}"
             "td,th{border:1px solid #bbb;padding:2px 8px;text-align:right}th{background:#eee}img{max-width:100%}")
    doc = (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>psns-hil "
           f"{html.escape(str(summary.get('scenario')))}</title><style>{style}</style></head><body>{''.join(parts)}</body></html>")
    out = run_dir / "report.html"
    tmp = run_dir / f".report.html.{os.getpid()}.tmp"
    try:  # whole or not at all: written aside and renamed (a link named report.html is replaced, never followed)
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_TRUNC | getattr(os, "O_NOFOLLOW", 0), 0o644)
        with open(fd, "w", encoding="utf-8") as f:
            f.write(doc)
        os.replace(tmp, out)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return out
