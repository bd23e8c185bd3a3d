"""How values are written into the run directory's files (CSV rows, JSON values) and shown to a person
(:func:`readable_number`: report.html and the console).

:func:`csv_row` is the reference (every value by the rule: finite floats by ``repr``, non-finite ones empty,
anything else by ``str``); :func:`csv_row_fast` gives the same text by joining ``repr`` s and falling back to
:func:`csv_row` when that could differ (the recorder writes a row per navigation frame;
``tests/emulator/fast_path_cases.py`` holds the equivalence cases).
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

__all__ = [
    "NON_FINITE_KEY", "READABLE_SIGNIFICANT_DIGITS", "csv_cell", "csv_row", "csv_row_fast", "finite_json",
    "json_default", "readable_number", "reprs_are_cells", "strict_json",
]

#: significant digits :func:`readable_number` keeps for a float below 1000 in magnitude
READABLE_SIGNIFICANT_DIGITS = 4

#: the thin space that groups thousands (``22 710``): not a comma, which reads as a decimal point in half the world
THOUSANDS_SEPARATOR = "\u2009"


#: the key under which :func:`finite_json` lists the paths of the values it turned into ``null``
NON_FINITE_KEY = "non_finite"


def csv_cell(x: Any) -> str:
    """One CSV cell: floats (numpy floats too) by ``repr`` of the Python float, NaN and infinities empty,
    anything else by ``str``."""
    if isinstance(x, float):
        return repr(float(x)) if x - x == 0.0 else ""
    return str(x)


def csv_row(values: Sequence[Any]) -> str:
    """One CSV line (``\\r\\n`` as the csv module writes) of :func:`csv_cell` cells."""
    return ",".join([repr(x) if x.__class__ is float and x - x == 0.0 else csv_cell(x) for x in values]) + "\r\n"


def reprs_are_cells(line: str) -> bool:
    """True when ``line``, the ``","``-joined ``repr`` s of some values, is also their :func:`csv_row` cells.

    ``repr`` is already the cell of a finite Python float, an int or a bool; anything else (NaN, inf, numpy
    scalars, strings, enums) shows one of these characters in its ``repr``, and then the row takes the reference
    path.
    """
    return not ("n" in line or "i" in line or "'" in line or "(" in line or "<" in line or " " in line)


def csv_row_fast(values: Sequence[Any]) -> str:
    """:func:`csv_row`, faster for rows of finite Python floats, ints and bools (the recorder's rows)."""
    line = ",".join(map(repr, values))
    if reprs_are_cells(line):
        return line + "\r\n"
    return csv_row(values)


def json_default(o: Any) -> Any:
    """``json.dumps(default=...)`` for the run's files: numpy scalars and arrays as numbers, anything else
    (paths included) as its ``str``."""
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    return str(o)


def finite_json(obj: Any) -> tuple[Any, list[str]]:
    """``obj`` with every NaN / infinity (numpy ones too) replaced by ``None``, and the dotted paths of the
    values replaced (``nav_error.heading_deg.max``), so strict JSON parsers read the result."""
    paths: list[str] = []

    def walk(o: Any, path: str) -> Any:
        if isinstance(o, (float, np.floating)):
            if o - o == 0.0:
                return float(o)
            paths.append(path or "$")
            return None
        if isinstance(o, dict):
            return {k: walk(v, f"{path}.{k}" if path else str(k)) for k, v in o.items()}
        if isinstance(o, (list, tuple)):
            return [walk(v, f"{path}[{i}]") for i, v in enumerate(o)]
        if isinstance(o, np.ndarray):
            return walk(o.tolist(), path)
        return o

    return walk(obj, ""), paths


def strict_json(obj: Any, indent: int | None = 2) -> str:
    """``obj`` as strict JSON (RFC 8259: no bare ``NaN`` / ``Infinity``): non-finite numbers become ``null``
    and, for a dict, their paths are listed under :data:`NON_FINITE_KEY` (the flag that they were not
    numbers)."""
    clean, paths = finite_json(obj)
    if isinstance(clean, dict) and (paths or NON_FINITE_KEY in clean):
        clean[NON_FINITE_KEY] = sorted(set(paths) | set(clean.get(NON_FINITE_KEY) or []))
    return json.dumps(clean, indent=indent, default=json_default, allow_nan=False)


def readable_number(x: Any) -> str:
    """A value as a person reads it, the one rule of report.html and the console.

    * ``None`` and non-finite floats (NaN, +-inf: ``null`` in summary.json) -> ``"-"``;
    * ``bool`` -> ``"True"`` / ``"False"`` (never a number);
    * ``int`` -> every digit, thousands grouped with a thin space (``22 710``);
    * ``float`` with ``|x| >= 1000`` -> rounded to an integer, grouped (``1 000 000``);
      ``0.01 <= |x| < 1000`` -> :data:`READABLE_SIGNIFICANT_DIGITS` significant digits, trailing zeros of the
      fraction dropped and never those of the integer part (``120``, ``0.5``, ``123.5``, ``-0.0123``);
      ``0 < |x| < 0.01`` -> scientific with 3 significant digits (``1.23e-05``); zero -> ``"0"``;
    * anything else -> ``str``.
    """
    if x is None:
        return "-"
    if isinstance(x, bool):
        return str(x)
    if isinstance(x, (int, np.integer)):
        return f"{int(x):,}".replace(",", THOUSANDS_SEPARATOR)
    if isinstance(x, (float, np.floating)):
        x = float(x)
        if not math.isfinite(x):
            return "-"
        a = abs(x)
        if a == 0.0:
            return "0"
        if a >= 999.95:  # what would round to 1000 in 4 digits takes the integer form too
            return f"{x:,.0f}".replace(",", THOUSANDS_SEPARATOR)
        if a >= 0.01:
            # the "g" format keeps the integer part whole below 10**digits and drops only fractional zeros
            return f"{x:.{READABLE_SIGNIFICANT_DIGITS}g}"
        return f"{x:.2e}"
    return str(x)
