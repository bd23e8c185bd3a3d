"""A self-contained HTML report of one run directory.

``write_report(run_dir)`` reads the files the recorder wrote (``summary.json``, ``nav.csv``,
``events.jsonl`` and, when present, ``timeline.csv`` with per-second link and DSP counters) and
writes ``report.html``. The plots are embedded as base64 PNG, so the report is one file.

* attitude (roll, pitch, heading), velocity and position errors against truth, each with the
  filter's own +-3 sigma envelope;
* the mode timeline (aligning / navigating / GNSS- and PSNS-aided / degraded) with faults and
  other events marked;
* link error counters over time (from ``timeline.csv``) and the link table;
* DSP load: per-task cycle statistics and the CPU load over time.
"""

from __future__ import annotations

import base64
import csv
import html
import io
import json
import math
from pathlib import Path
from typing import Any

__all__ = ["write_report", "load_nav_csv"]

_MODE_BITS = [(0x0001, "aligning"), (0x0002, "navigating"), (0x0004, "GNSS-aided"), (0x0008, "PSNS-aided"),
              (0x0010, "degraded")]


def load_nav_csv(path: Path) -> dict[str, list[float]]:
    """Columns of ``nav.csv`` as float lists (empty cells become NaN)."""
    cols: dict[str, list[float]] = {}
    with open(path, newline="", encoding="utf-8") as f:
        r = csv.reader(f)
        header = next(r, None)
        if header is None:
            return {}
        for h in header:
            cols[h] = []
        for row in r:
            for h, v in zip(header, row):
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


def _err_panel(ax: Any, t: list[float], err: list[float], sig: list[float] | None, label: str, unit: str) -> None:
    ax.plot(t, err, lw=0.8, label=f"{label} error")
    if sig is not None:
        s3 = [3 * s for s in sig]
        ax.plot(t, s3, "r--", lw=0.6, label="+-3 sigma (filter)")
        ax.plot(t, [-v for v in s3], "r--", lw=0.6)
    ax.set_ylabel(unit)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="upper right", fontsize=7)


def _nav_figures(nav: dict[str, list[float]], events: list[dict[str, Any]]) -> list[tuple[str, str]]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out: list[tuple[str, str]] = []
    t = nav.get("time_s", [])
    if not t:
        return out
    # The filter's tilt sigmas are about East/North; roll is about the body's forward axis and pitch
    # about its right axis, so rotate them by the heading h: forward = (sin h, cos h), right = (cos h, -sin h).
    sig_roll, sig_pitch = [], []
    for h, se, sn in zip(nav.get("heading_deg", []), nav.get("sig_att_e_deg", []), nav.get("sig_att_n_deg", [])):
        sh, ch = math.sin(math.radians(h)), math.cos(math.radians(h))
        sig_roll.append(math.sqrt((sh * se) ** 2 + (ch * sn) ** 2))
        sig_pitch.append(math.sqrt((ch * se) ** 2 + (sh * sn) ** 2))
    fig, axes = plt.subplots(3, 1, figsize=(10, 7), sharex=True)
    for ax, (col, sig, name) in zip(axes, [("err_roll_deg", sig_roll, "roll"),
                                           ("err_pitch_deg", sig_pitch, "pitch"),
                                           ("err_heading_deg", nav.get("sig_att_u_deg"), "heading")]):
        _err_panel(ax, t, nav.get(col, []), sig, name, "deg")
    axes[-1].set_xlabel("time (s)")
    fig.suptitle("attitude error against truth")
    out.append(("Attitude error", _png(fig)))

    fig, axes = plt.subplots(3, 1, figsize=(10, 7), sharex=True)
    for ax, ax_name in zip(axes, ("e", "n", "u")):
        _err_panel(ax, t, nav.get(f"err_vel_{ax_name}_mps", []), nav.get(f"sig_vel_{ax_name}_mps"),
                   f"v_{ax_name.upper()}", "m/s")
    axes[-1].set_xlabel("time (s)")
    fig.suptitle("velocity error against truth")
    out.append(("Velocity error", _png(fig)))

    fig, axes = plt.subplots(3, 1, figsize=(10, 7), sharex=True)
    for ax, ax_name in zip(axes, ("e", "n", "u")):
        _err_panel(ax, t, nav.get(f"err_pos_{ax_name}_m", []), nav.get(f"sig_pos_{ax_name}_m"),
                   f"p_{ax_name.upper()}", "m")
    axes[-1].set_xlabel("time (s)")
    fig.suptitle("position error against truth")
    out.append(("Position error", _png(fig)))

    # mode timeline + events
    fig, ax = plt.subplots(figsize=(10, 2.8))
    modes = nav.get("mode", [])
    for i, (bit, name) in enumerate(_MODE_BITS):
        on = [1 if (not math.isnan(m) and int(m) & bit) else 0 for m in modes]
        ax.fill_between(t, i, [i + 0.8 * v for v in on], step="post", alpha=0.6, label=name)
    ax.set_yticks([i + 0.4 for i in range(len(_MODE_BITS))])
    ax.set_yticklabels([n for _, n in _MODE_BITS], fontsize=8)
    shown: set[str] = set()
    for ev in events:
        kind = ev.get("event", "")
        if kind in ("gnss_update", "psns_update"):
            continue
        tt = ev.get("t_s")
        if tt is None:
            continue
        color = "red" if "fault" in kind or "miss" in kind or "reject" in kind else "k"
        ax.axvline(tt, color=color, lw=0.6, alpha=0.7, label=None if kind in shown else kind)
        shown.add(kind)
    ax.set_xlabel("time (s)")
    ax.set_title("mode timeline and events")
    ax.legend(loc="upper right", fontsize=6, ncol=3)
    out.append(("Mode timeline", _png(fig)))
    return out


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
    err_cols = [c for c in cols if c.endswith(("crc_errors", "dropped", "garbage_bytes"))]
    if err_cols:
        fig, ax = plt.subplots(figsize=(10, 3.5))
        for c in err_cols:
            if any(v for v in cols[c] if not math.isnan(v)):
                ax.plot(t, cols[c], lw=0.8, label=c)
        ax.set_xlabel("time (s)")
        ax.set_ylabel("cumulative count")
        ax.set_title("link error counters")
        ax.grid(True, alpha=0.3)
        if ax.lines:
            ax.legend(fontsize=7)
        out.append(("Link errors over time", _png(fig)))
    if "cpu_load_pct" in cols:
        fig, ax = plt.subplots(figsize=(10, 3))
        ax.plot(t, cols["cpu_load_pct"], lw=0.8)
        ax.set_xlabel("time (s)")
        ax.set_ylabel("% of 1 s")
        ax.set_title("DSP CPU load")
        ax.grid(True, alpha=0.3)
        out.append(("DSP load over time", _png(fig)))
    return out


def _table(rows: list[list[Any]], header: list[str]) -> str:
    h = "".join(f"<th>{html.escape(str(x))}</th>" for x in header)
    body = "".join("<tr>" + "".join(f"<td>{html.escape(_fmt(x))}</td>" for x in r) + "</tr>" for r in rows)
    return f"<table><tr>{h}</tr>{body}</table>"


def _fmt(x: Any) -> str:
    if x is None:
        return "-"
    if isinstance(x, float):
        return f"{x:.4g}"
    return str(x)


def write_report(run_dir: str | Path) -> Path:
    """Write ``report.html`` into ``run_dir`` and return its path."""
    run_dir = Path(run_dir)
    summary = json.loads((run_dir / "summary.json").read_text(encoding="utf-8"))
    nav = load_nav_csv(run_dir / "nav.csv") if (run_dir / "nav.csv").exists() else {}
    events: list[dict[str, Any]] = []
    ev_path = run_dir / "events.jsonl"
    if ev_path.exists():
        for line in ev_path.read_text(encoding="utf-8").splitlines():
            if line.strip():
                try:
                    events.append(json.loads(line))
                except json.JSONDecodeError:
                    continue  # a truncated last line of an interrupted run
    figs = _nav_figures(nav, events) + _timeline_figures(run_dir / "timeline.csv")

    parts = [f"<h1>psns-hil run: {html.escape(str(summary.get('scenario')))}</h1>"]
    rtf = summary.get("realtime_factor")
    parts.append(_table([
        ["seed", summary.get("seed")], ["mode", summary.get("mode")],
        ["simulated (s)", summary.get("sim_duration_s")], ["wall (s)", summary.get("wall_s")],
        ["real-time factor", rtf], ["interrupted", summary.get("interrupted")],
        ["expectations passed", summary.get("passed")],
    ], ["item", "value"]))
    parts.append("<h2>Navigation error against truth</h2>")
    parts.append(_table([[k, v.get("rms"), v.get("max")] for k, v in summary.get("nav_error", {}).items()],
                        ["quantity", "rms", "max"]))
    if summary.get("expectations"):
        parts.append("<h2>Expectations</h2>")
        parts.append(_table([[e["index"], e["description"], e["value"], "pass" if e["passed"] else "FAIL"]
                             for e in summary["expectations"]], ["#", "check", "value", "result"]))
    parts.append("<h2>Links</h2>")
    parts.append(_table([[k, v.get("bytes"), v.get("frames"), v.get("crc_errors"), v.get("dropped")]
                         for k, v in summary.get("links", {}).items()],
                        ["link", "bytes", "frames", "crc_errors", "dropped"]))
    dsp = summary.get("dsp", {})
    parts.append(f"<h2>DSP load ({_fmt(dsp.get('clock_hz'))} Hz, tick budget {_fmt(dsp.get('tick_budget_cycles'))} cycles)</h2>")
    parts.append(_table([[t["task"], t["calls"], t["cycles_min"], t["cycles_avg"], t["cycles_max"], t["utilization_max_pct"]]
                         for t in dsp.get("tasks", [])],
                        ["task", "calls", "min", "avg", "max", "max % budget"]))
    parts.append(f"<p>worst 1 s CPU load {_fmt(dsp.get('cpu_load_pct_max'))} %, deadline misses {_fmt(dsp.get('deadline_misses'))}</p>")
    for title, b64 in figs:
        parts.append(f"<h2>{html.escape(title)}</h2><img alt='{html.escape(title)}' src='data:image/png;base64,{b64}'/>")
    style = ("body{font-family:sans-serif;max-width:1100px;margin:auto}table{border-collapse:collapse;margin:8px 0}"
             "td,th{border:1px solid #bbb;padding:2px 8px;text-align:right}th{background:#eee}img{max-width:100%}")
    doc = (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>psns-hil {html.escape(str(summary.get('scenario')))}"
           f"</title><style>{style}</style></head><body>{''.join(parts)}</body></html>")
    out = run_dir / "report.html"
    out.write_text(doc, encoding="utf-8")
    return out
