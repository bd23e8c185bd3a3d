"""Differential testing of a foreign firmware against the reference (``psns-hil diff-firmware``).

The same scenario runs twice on the same seeded world, in fast mode: once with the built-in firmware in the virtual
DSP (the reference) and once with a foreign firmware in lockstep in its place (docs/icd.md section 10). The two
``nav.csv`` files are compared frame by frame on what each NAV_SOLUTION says (every column from ``time_s`` up to
``arrival_s``: solution, sigmas, mode and status words; docs/icd.md section 7): the first differing frame with
its fields, and per field the largest difference, the first frame it differs at and the largest difference per
second of scenario time. When the solutions agree the arrival times are compared as well: a foreign firmware that
reports other cycles leaves its frames at other instants, which is a difference of timing, not of navigation.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Any

__all__ = ["compare_nav_frames"]

#: columns compared with the heading's wrap at 360 deg
_ANGLE_WRAP = {"heading_deg": 360.0}


def _read(path: Path) -> tuple[list[str], list[list[str]]]:
    with open(path, newline="", encoding="utf-8") as f:
        rows = list(csv.reader(f))
    return (rows[0], rows[1:]) if rows else ([], [])


def _num(s: str) -> float | None:
    try:
        return float(s)
    except ValueError:
        return None


def _diff(col: str, a: str, b: str) -> float:
    """|b - a| of one cell (inf when only one side is a number or the text differs)."""
    if a == b:
        return 0.0
    x, y = _num(a), _num(b)
    if x is None or y is None:
        return math.inf
    d = y - x
    wrap = _ANGLE_WRAP.get(col)
    if wrap is not None:
        d = (d + wrap / 2) % wrap - wrap / 2
    return abs(d)


def _key(time_s: str) -> int | str:
    """A frame's pairing key: its time of validity in whole microseconds (the FPGA counter's unit; two programs
    may print the same instant as different doubles), the text itself when it is no number."""
    x = _num(time_s)
    return round(x * 1e6) if x is not None and math.isfinite(x) else time_s


def compare_nav_frames(reference: str | Path, foreign: str | Path) -> dict[str, Any]:
    """Compare two ``nav.csv`` frame by frame (see module docstring); a JSON-ready report.

    Frames are paired by their time of validity (``time_s``, the FPGA time of the IMU trigger, as both runs print
    it): a frame only one side has is a difference of its own (``missing_in``); ``frame`` numbers are the
    reference's rows (0-based; the foreign's when the reference has no such frame)."""
    head_r, rows_r = _read(Path(reference))
    head_f, rows_f = _read(Path(foreign))
    end = head_r.index("arrival_s") if "arrival_s" in head_r else len(head_r)
    cols = [c for c in head_r[:end] if c in head_f and c != "time_s"]
    ir = {c: i for i, c in enumerate(head_r)}
    jf = {c: i for i, c in enumerate(head_f)}
    tr, tf = ir.get("time_s", 0), jf.get("time_s", 0)
    by_time_f = {_key(row[tf]): (k, row) for k, row in enumerate(rows_f) if len(row) > tf}
    times_r = {_key(row[tr]) for row in rows_r if len(row) > tr}
    fields: dict[str, dict[str, Any]] = {}
    per_second: dict[int, dict[str, float]] = {}
    first: dict[str, Any] | None = None
    frames_differing = compared = 0
    missing = {"foreign": 0, "reference": sum(1 for row in rows_f if len(row) > tf and _key(row[tf]) not in times_r)}
    first_only_foreign = next(((k, row) for k, row in enumerate(rows_f)
                               if len(row) > tf and _key(row[tf]) not in times_r), None)
    arrival: list[float] = []
    for k, a in enumerate(rows_r):
        if len(a) <= tr:
            continue
        t = _num(a[tr])
        got = by_time_f.get(_key(a[tr]))
        if got is None:
            missing["foreign"] += 1
            frames_differing += 1
            if first is None:
                first = {"frame": k, "time_s": t, "fields": {}, "missing_in": "foreign"}
            continue
        b = got[1]
        compared += 1
        if "arrival_s" in ir and "arrival_s" in jf:
            x, y = _num(a[ir["arrival_s"]]), _num(b[jf["arrival_s"]])
            if x is not None and y is not None:
                arrival.append(abs(y - x))
        here: dict[str, list[Any]] = {}
        for c in cols:
            va, vb = a[ir[c]], b[jf[c]]
            d = _diff(c, va, vb)
            if d == 0.0:
                continue
            here[c] = [va, vb, d]
            f = fields.get(c)
            if f is None:
                f = fields[c] = {"max_abs_diff": d, "first_frame": k, "first_time_s": t, "frames_differing": 0}
            f["max_abs_diff"] = max(f["max_abs_diff"], d)
            f["frames_differing"] += 1
            if t is not None:
                sec = per_second.setdefault(math.floor(t), {})
                sec[c] = max(sec.get(c, 0.0), d)
        if here:
            frames_differing += 1
            if first is None:
                first = {"frame": k, "time_s": t,
                         "fields": {c: {"reference": v[0], "foreign": v[1], "abs_diff": v[2]} for c, v in here.items()}}
    if first_only_foreign is not None:
        k, row = first_only_foreign
        t = _num(row[tf])
        if first is None or (t is not None and first["time_s"] is not None and t < first["time_s"]):
            first = {"frame": k, "time_s": t, "fields": {}, "missing_in": "reference"}
        frames_differing += missing["reference"]
    return {
        "reference": str(reference),
        "foreign": str(foreign),
        "frames": {"reference": len(rows_r), "foreign": len(rows_f), "compared": compared,
                   "missing_in_foreign": missing["foreign"], "missing_in_reference": missing["reference"]},
        "columns_compared": cols,
        "identical": first is None,
        "frames_differing": frames_differing,
        "first_difference": first,
        "fields": fields,
        "max_abs_diff_per_second": {str(sec): v for sec, v in sorted(per_second.items())},
        "arrival": {"max_abs_diff_s": max(arrival), "frames_differing": sum(1 for x in arrival if x > 0)}
        if arrival else None,
    }
