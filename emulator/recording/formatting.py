"""How values are written into the run directory's files: CSV rows and JSON values.

:func:`csv_row` is the reference (every value by the rule: finite floats by ``repr``, non-finite ones empty,
anything else by ``str``); :func:`csv_row_fast` gives the same text by joining ``repr`` s and falling back to
:func:`csv_row` when that could differ (the recorder writes a row per navigation frame;
``tests/emulator/fast_path_cases.py`` holds the equivalence cases).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["csv_cell", "csv_row", "csv_row_fast", "json_default"]


def csv_cell(x: Any) -> str:
    """One CSV cell: floats (numpy floats too) by ``repr`` of the Python float, NaN and infinities empty,
    anything else by ``str``."""
    if isinstance(x, float):
        return repr(float(x)) if x - x == 0.0 else ""
    return str(x)


def csv_row(values: Sequence[Any]) -> str:
    """One CSV line (``\\r\\n`` as the csv module writes) of :func:`csv_cell` cells."""
    return ",".join([repr(x) if x.__class__ is float and x - x == 0.0 else csv_cell(x) for x in values]) + "\r\n"


def csv_row_fast(values: Sequence[Any]) -> str:
    """:func:`csv_row`, faster for rows of finite Python floats, ints and bools (the recorder's rows)."""
    line = ",".join(map(repr, values))
    # repr is already right for finite Python floats, ints and bools; anything else (NaN, inf, numpy
    # scalars, strings, enums) shows one of these characters in its repr and takes the reference path
    if "n" in line or "i" in line or "'" in line or "(" in line or "<" in line or " " in line:
        return csv_row(values)
    return line + "\r\n"


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
