"""A self-contained HTML report of one run directory.

``write_report(run_dir)`` reads the files the recorder wrote (``summary.json``, ``nav.csv``,
``events.jsonl`` and, when present, ``timeline.csv`` with per-second link and DSP counters) and
writes ``report.html``. The plots are embedded as base64 PNG, so the report is one file.

* whether the run is valid (every scheduled fault took effect) and passed, the faults with their
  evidence, the expectations with their measured values;
* attitude (roll, pitch, heading), velocity and position errors against truth, each with the
  filter's own +-3 sigma envelope, with the fault windows shaded;
* the mode timeline (aligning / navigating / GNSS- and PSNS-aided / degraded) with the fault
  windows as bars and other events marked;
* link error counters over time (from ``timeline.csv``) and the link table;
* DSP load: cycles per task (bars, % of the tick budget), the CPU load and deadline misses over time.

``psns-hil run`` writes it at the end of every run; ``psns-hil report RUN_DIR`` writes it again.
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

__all__ = ["fault_spans", "load_nav_csv", "write_report"]

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


def fault_spans(events: list[dict[str, Any]]) -> list[tuple[float, float, str]]:
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


def _nav_figures(nav: dict[str, list[float]], events: list[dict[str, Any]]) -> list[tuple[str, str]]:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out: list[tuple[str, str]] = []
    t = nav.get("time_s", [])
    if not t:
        return out
    spans = fault_spans(events)
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
        _shade(ax, spans)
    axes[-1].set_xlabel("time (s)")
    fig.suptitle("attitude error against truth")
    out.append(("Attitude error", _png(fig)))

    fig, axes = plt.subplots(3, 1, figsize=(10, 7), sharex=True)
    for ax, ax_name in zip(axes, ("e", "n", "u")):
        _err_panel(ax, t, nav.get(f"err_vel_{ax_name}_mps", []), nav.get(f"sig_vel_{ax_name}_mps"),
                   f"v_{ax_name.upper()}", "m/s")
        _shade(ax, spans)
    axes[-1].set_xlabel("time (s)")
    fig.suptitle("velocity error against truth")
    out.append(("Velocity error", _png(fig)))

    fig, axes = plt.subplots(3, 1, figsize=(10, 7), sharex=True)
    for ax, ax_name in zip(axes, ("e", "n", "u")):
        _err_panel(ax, t, nav.get(f"err_pos_{ax_name}_m", []), nav.get(f"sig_pos_{ax_name}_m"),
                   f"p_{ax_name.upper()}", "m")
        _shade(ax, spans)
    axes[-1].set_xlabel("time (s)")
    fig.suptitle("position error against truth")
    out.append(("Position error", _png(fig)))

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
    shown: set[str] = set()
    for ev in events:
        kind = ev.get("event", "")
        if kind in ("gnss_update", "psns_update") or ev.get("source") == "fault":
            continue
        tt = ev.get("t_s")
        if tt is None:
            continue
        color = "red" if "fault" in kind or "miss" in kind or "reject" in kind else "k"
        ax.axvline(tt, color=color, lw=0.6, alpha=0.7, label=None if kind in shown else kind)
        shown.add(kind)
    ax.set_xlabel("time (s)")
    ax.set_title("mode timeline, faults (orange) and events")
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
    err_cols = [c for c in cols if c.endswith(("crc_errors", "dropped", "garbage_bytes", "framing_errors"))]
    if err_cols:
        fig, ax = plt.subplots(figsize=(10, 3.5))
        for c in err_cols:
            if any(v for v in cols[c] if not math.isnan(v)):
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
        if "deadline_misses" in cols and any(v for v in cols["deadline_misses"] if not math.isnan(v)):
            ax2 = ax.twinx()
            ax2.plot(t, cols["deadline_misses"], "r-", lw=0.8, label="deadline misses (cumulative)")
            ax2.set_ylabel("deadline misses")
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
    from .summary_model import load_summary

    summary = load_summary(run_dir).model_dump(mode="json")  # validated: a clear error for a foreign file
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
    figs = _nav_figures(nav, events) + _timeline_figures(run_dir / "timeline.csv") + _task_figure(summary)

    parts = [f"<h1>psns-hil run: {html.escape(str(summary.get('scenario')))}</h1>"]
    valid = summary.get("valid", True)
    passed = summary.get("passed")
    verdict = ("INVALID: a scheduled fault never took effect" if valid is False else
               "passed" if passed else "interrupted" if summary.get("interrupted") else "FAILED")
    color = "#2a2" if passed and valid is not False else "#c22"
    parts.append(f"<p style='font-size:1.3em;color:{color}'><b>{html.escape(verdict)}</b></p>")
    rtf = summary.get("realtime_factor")
    parts.append(_table([
        ["scenario file", summary.get("scenario_file")],
        ["seed", summary.get("seed")], ["mode", summary.get("mode")],
        ["simulated (s)", summary.get("sim_duration_s")], ["wall (s)", summary.get("wall_s")],
        ["real-time factor", rtf], ["interrupted", summary.get("interrupted")],
        ["valid (every fault took effect)", valid], ["passed", passed],
    ], ["item", "value"]))
    if summary.get("faults"):
        parts.append("<h2>Faults</h2>")
        parts.append(_table([[f["index"], f["kind"], f["target"], f.get("active_from_s"), f.get("active_until_s"),
                              ", ".join(f"{k} {v}" for k, v in f.get("evidence", {}).items()),
                              ", ".join(f"{k} {v:+d}" for k, v in f.get("firmware", {}).items()),
                              "-" if f.get("fired") is None else "yes" if f["fired"] else "NO"]
                             for f in summary["faults"]],
                            ["#", "fault", "target", "from (s)", "until (s)", "evidence while active",
                             "firmware counters", "took effect"]))
    parts.append("<h2>Navigation error against truth</h2>")
    parts.append(_table([[k, v.get("rms"), v.get("max")] for k, v in summary.get("nav_error", {}).items()],
                        ["quantity", "rms", "max"]))
    if summary.get("expectations"):
        parts.append("<h2>Expectations</h2>")
        parts.append(_table([[e["index"], e["description"], e["value"], e.get("message", ""),
                              "pass" if e["passed"] else "FAIL"]
                             for e in summary["expectations"]], ["#", "check", "value", "note", "result"]))
    parts.append("<h2>Links</h2>")
    parts.append(_table([[k, v.get("bytes"), v.get("frames"), v.get("crc_errors"), v.get("dropped"),
                          v.get("garbage_bytes"), v.get("framing_errors")]
                         for k, v in summary.get("links", {}).items()],
                        ["link", "bytes", "frames", "crc_errors", "dropped", "garbage_bytes", "framing_errors"]))
    dsp = summary.get("dsp", {})
    parts.append(f"<h2>DSP load ({_fmt(dsp.get('clock_hz'))} Hz, tick budget "
                 f"{_fmt(dsp.get('tick_budget_cycles'))} cycles)</h2>")
    parts.append(_table([[t["task"], t["calls"], t["cycles_min"], t["cycles_avg"], t["cycles_max"],
                          t["utilization_max_pct"]] for t in dsp.get("tasks", [])],
                        ["task", "calls", "min", "avg", "max", "max % budget"]))
    parts.append(f"<p>worst 1 s CPU load {_fmt(dsp.get('cpu_load_pct_max'))} %, deadline misses "
                 f"{_fmt(dsp.get('deadline_misses'))}</p>")
    for title, b64 in figs:
        parts.append(f"<h2>{html.escape(title)}</h2><img alt='{html.escape(title)}' "
                     f"src='data:image/png;base64,{b64}'/>")
    style = ("body{font-family:sans-serif;max-width:1100px;margin:auto}table{border-collapse:collapse;margin:8px 0}"
             "td,th{border:1px solid #bbb;padding:2px 8px;text-align:right}th{background:#eee}img{max-width:100%}")
    doc = (f"<!DOCTYPE html><html><head><meta charset='utf-8'><title>psns-hil "
           f"{html.escape(str(summary.get('scenario')))}</title><style>{style}</style></head><body>{''.join(parts)}</body></html>")
    out = run_dir / "report.html"
    out.write_text(doc, encoding="utf-8")
    return out
