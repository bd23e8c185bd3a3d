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

__all__ = ["fault_spans", "load_nav_csv", "load_psns_csv", "write_report"]

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
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=6, ncol=1, borderaxespad=0.0)
    out.append(("Mode timeline", _png(fig)))
    return out


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


def _trajectory_figure(nav: dict[str, list[float]], truth: dict[str, list[float]],
                       events: list[dict[str, Any]]) -> list[tuple[str, str]]:
    """Truth and estimate on a local East/North map; GNSS outages (not GNSS-aided) and fault windows marked."""
    t, lat, lon = nav.get("time_s", []), nav.get("lat_deg", []), nav.get("lon_deg", [])
    tl, tlat, tlon = truth.get("time_s", []), truth.get("lat_deg", []), truth.get("lon_deg", [])
    if not tlat or not lat:
        return []
    plt = _plt()
    lat0, lon0 = tlat[0], tlon[0]
    te, tn = _en_m(tlat, tlon, lat0, lon0)
    ee, en = _en_m(lat, lon, lat0, lon0)
    fig, ax = plt.subplots(figsize=(7.5, 6.5))
    ax.plot(te, tn, "k-", lw=1.4, label="truth")
    ax.plot(ee, en, "-", color="tab:blue", lw=0.8, alpha=0.8, label="estimate")
    ax.plot(te[:1], tn[:1], "go", label="start")
    modes = nav.get("mode", [])

    def mark(spans: list[tuple[float, float]], color: str, label: str) -> None:
        for k, (a, b) in enumerate(spans):
            idx = [i for i, x in enumerate(t) if a <= x <= b]
            if idx:
                ax.plot([ee[i] for i in idx], [en[i] for i in idx], ".", ms=2, color=color,
                        label=label if k == 0 else None)

    mark([s for s in _bit_spans(t, modes, 0x0004, False) if s[1] - s[0] >= 2.0 and s[0] > (t[0] if t else 0)],
         "tab:orange", "no GNSS aiding (>= 2 s)")
    mark([(a, b) for a, b, _ in fault_spans(events)], "tab:red", "fault active")
    ax.set_xlabel("East (m)")
    ax.set_ylabel("North (m)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=7, loc="best")
    ax.set_title(f"trajectory: truth vs estimate (origin {lat0:.5f} N, {lon0:.5f} E; {len(tl)} truth rows)")
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
        for q in (0.5, 0.95):
            x = v[min(n - 1, int(q * n))]
            ax.axvline(x, color="grey", ls=":", lw=0.8)
            ax.text(x, q, f" {int(q * 100)} %: {_fmt(x)}", fontsize=7, va="bottom")
        ax.set_xlabel(f"|error| {label}")
        ax.set_ylim(0, 1.02)
        ax.grid(True, alpha=0.3)
    axes[0][0].set_ylabel("fraction of navigating frames")
    fig.suptitle("error CDF (while navigating)")
    return [("Error CDF", _png(fig))]


def _gnss_figure(nav: dict[str, list[float]], events: list[dict[str, Any]],
                 series: dict[str, list[float]] | None = None) -> list[tuple[str, str]]:
    """GNSS: updates used (measurements per update, largest normalised innovation), the aided periods, and what the
    receiver reported (satellites used and DOP, decoded from the capture: :func:`sensor_series`)."""
    ups = [e for e in events if e.get("event") == "gnss_update"]
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
        ax.plot([e["t_s"] for e in ups], [e.get("n_meas", math.nan) for e in ups], "o", ms=3,
                label="measurements per update")
        ax2 = ax.twinx()
        ax2.plot([e["t_s"] for e in ups], [e.get("max_norm_innov", math.nan) for e in ups], "r.", ms=3,
                 label="largest normalised innovation")
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
    from .capture import iter_capture

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
    """Readable numbers: ``22 710`` not ``2.271e+04``, ``0.0123``, thousands grouped with thin spaces."""
    if x is None:
        return "-"
    if isinstance(x, bool):
        return str(x)
    if isinstance(x, int):
        return f"{x:,}".replace(",", "\u2009")
    if isinstance(x, float):
        if not math.isfinite(x):
            return "-"
        a = abs(x)
        if a == 0.0:
            return "0"
        if a >= 1000:
            return f"{x:,.0f}".replace(",", "\u2009")
        if a >= 0.01:
            return f"{x:.4g}" if a < 1 else f"{x:.{max(0, 3 - len(str(int(a))))}f}".rstrip("0").rstrip(".")
        return f"{x:.2e}"
    return str(x)


def _hz(x: Any) -> str:
    """A clock frequency in MHz (``300 MHz``, not ``3e+08 Hz``)."""
    return "-" if not isinstance(x, (int, float)) else f"{x / 1e6:g} MHz"


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
    truth = load_nav_csv(run_dir / "truth.csv") if (run_dir / "truth.csv").exists() else {}
    series = sensor_series(run_dir)
    figs = (_trajectory_figure(nav, truth, events) + _attitude_vs_truth_figure(nav, truth, events)
            + _nav_figures(nav, events) + _error_cdf_figure(nav) + _gnss_figure(nav, events, series)
            + _psns_figure(nav, events, summary.get("firmware", {}).get("counters"), series,
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
    psns = summary.get("psns") or {}
    if psns.get("solves"):
        parts.append(f"<h2>Solved solar vector against truth ({_fmt(psns['solves'])} solves: "
                     + html.escape(", ".join(f"{k} {_fmt(v)}" for k, v in (psns.get("uses") or {}).items()))
                     + ")</h2>")
        parts.append(_table([[label, (psns.get(key) or {}).get("median"), (psns.get(key) or {}).get("p95"),
                              (psns.get(key) or {}).get("max")]
                             for key, label in (("solar_vector_error_deg", "angle (deg)"),
                                                ("azimuth_error_deg", "|azimuth| (deg)"),
                                                ("elevation_error_deg", "|elevation| (deg)"))],
                            ["quantity", "median", "p95", "max"]))
    if summary.get("expectations"):
        parts.append("<h2>Expectations</h2>")
        parts.append(_table([[e["index"], e["description"], e["value"], e.get("message", ""),
                              "not applied" if e.get("applicable") is False else "pass" if e["passed"] else "FAIL"]
                             for e in summary["expectations"]], ["#", "check", "value", "note", "result"]))
    parts.append("<h2>Links</h2>")
    parts.append(_table([[k, v.get("bytes"), v.get("frames"), v.get("crc_errors"), v.get("dropped"),
                          v.get("garbage_bytes"), v.get("framing_errors")]
                         for k, v in summary.get("links", {}).items()],
                        ["link", "bytes", "frames", "crc_errors", "dropped", "garbage_bytes", "framing_errors"]))
    dsp = summary.get("dsp", {})
    parts.append(f"<h2>DSP load ({_hz(dsp.get('clock_hz'))}, tick budget "
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
