"""Every number report.html shows is the number summary.json holds (issue 38: the page once printed 120 as "12").

The page tags each value it takes from the summary with its dotted path (``data-path``). These tests read the
page back, find every cell and span whose text is a number, and check that (1) it carries a path, (2) the path
exists in the raw summary.json, and (3) the number read back from the text agrees with the file's value to the
precision shown. The comparison parses the text independently of the formatter, so a formatter that is wrong
the same way on both sides cannot pass.
"""

from __future__ import annotations

import json
import math
import re
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import pytest

from emulator.postrun.report import write_report
from emulator.recording.formatting import readable_number

THIN = "\u2009"
NUMBER = re.compile(r"^[+-]?(\d{1,3}(\u2009\d{3})+|\d+(\.\d+)?([eE][+-]?\d+)?)$")


# ------------------------------------------------------------------------------------------------ the formatter
@pytest.mark.parametrize(("value", "text"), [
    (120.0, "120"), (300.0, "300"), (140.0, "140"), (200.0, "200"), (100.0, "100"), (990.0, "990"),
    (999.0, "999"), (500.5, "500.5"), (123.456, "123.5"), (0.5, "0.5"), (8.365410178351365, "8.365"),
    (1e6, f"1{THIN}000{THIN}000"), (-1e6, f"-1{THIN}000{THIN}000"), (1234.5, f"1{THIN}234"),
    (999.96, f"1{THIN}000"), (-120.0, "-120"), (-0.0123, "-0.0123"), (0.01, "0.01"), (0.00999, "9.99e-03"),
    (1.5e-7, "1.50e-07"), (0.0, "0"), (-0.0, "0"),
    (math.nan, "-"), (math.inf, "-"), (-math.inf, "-"), (None, "-"),
    (0, "0"), (12, "12"), (120, "120"), (22710, f"22{THIN}710"), (-4500, f"-4{THIN}500"),
    (True, "True"), (False, "False"), ("uart1", "uart1"),
])
def test_readable_number(value: Any, text: str) -> None:
    assert readable_number(value) == text


@pytest.mark.parametrize("value", [v + 0.0 for v in range(100, 1000, 10)])
def test_readable_number_keeps_the_zeros_of_every_value_from_100_to_990(value: float) -> None:
    assert readable_number(value) == str(int(value))
    assert float(readable_number(value)) == value


def test_numpy_scalars_read_like_python_numbers() -> None:
    import numpy as np

    assert readable_number(np.float32(120.0)) == "120" and readable_number(np.int64(22710)) == f"22{THIN}710"


# ------------------------------------------------------------------------------------------------ the page
class _Cells(HTMLParser):
    """(tag, data-path or None, data-format or None, text) of every td and span of the page."""

    def __init__(self) -> None:
        super().__init__()
        self.cells: list[tuple[str, str | None, str | None, str]] = []
        self._open: list[tuple[str, dict[str, str | None], list[str]]] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        if tag in ("td", "span"):
            self._open.append((tag, dict(attrs), []))

    def handle_endtag(self, tag: str) -> None:
        if tag in ("td", "span") and self._open and self._open[-1][0] == tag:
            t, attrs, text = self._open.pop()
            self.cells.append((t, attrs.get("data-path"), attrs.get("data-format"), "".join(text)))

    def handle_data(self, data: str) -> None:
        for _t, _a, text in self._open[-1:]:  # only the innermost element's own text
            text.append(data)


def _at(summary: dict[str, Any], path: str) -> Any:
    cur: Any = summary
    for part in path.replace("[", ".[").split("."):
        if part.startswith("["):
            assert isinstance(cur, list), path
            cur = cur[int(part[1:-1])]
        else:
            assert isinstance(cur, dict) and part in cur, f"{path}: no {part!r} in summary.json"
            cur = cur[part]
    return cur


def _agrees(text: str, value: Any) -> bool:
    """The number read from ``text`` is ``value`` to the precision the text shows."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return False
    shown = float(text.replace(THIN, ""))
    if isinstance(value, int):
        return shown == value
    if "e" in text.lower():
        return math.isclose(shown, value, rel_tol=5e-3)
    decimals = len(text.split(".")[1]) if "." in text else 0
    return abs(shown - value) <= 0.5 * 10.0 ** -decimals + 1e-12 and (decimals > 0 or abs(value) >= 1.0
                                                                      or shown == round(value))


def check_page_against_summary(run_dir: Path) -> int:
    """Assert every numeric cell of report.html against summary.json; the number of cells checked."""
    summary = json.loads((run_dir / "summary.json").read_text(encoding="utf-8"))
    parser = _Cells()
    parser.feed(write_report(run_dir).read_text(encoding="utf-8"))
    checked = 0
    for tag, path, fmt, text in parser.cells:
        text = text.strip()
        if path is None:
            assert not NUMBER.match(text), f"a number without a path in summary.json: <{tag}>{text}</{tag}>"
            continue
        value = _at(summary, path)
        if fmt == "MHz":
            assert text == f"{value / 1e6:g} MHz", (path, text, value)
            checked += 1
            continue
        if value is None:
            assert text == "-", (path, text)
        elif NUMBER.match(text):
            assert _agrees(text, value), f"{path}: the page shows {text!r}, summary.json holds {value!r}"
            checked += 1
        else:
            assert text == str(value) or (isinstance(value, float) and not math.isfinite(value) and text == "-"), \
                f"{path}: the page shows {text!r}, summary.json holds {value!r}"
    return checked


def test_formatter_regression_is_caught(tmp_path: Path) -> None:
    """The check itself fails on the old formatter's output (120 shown as 12)."""
    assert not _agrees("12", 120.0) and not _agrees("3", 300.0) and _agrees("120", 120.0)
    assert _agrees("8.365", 8.365410178351365) and not _agrees("8.37", 8.3)
    assert _agrees(f"1{THIN}316{THIN}449", 1316449) and not _agrees("1316", 1316449)


@pytest.mark.parametrize(("scenario", "overrides"), [
    ("quickstart.yaml", ["duration_s=12"]),
    ("link_fault_storm.yaml", ["expectations=[]"]),
])
def test_every_number_of_the_page_is_the_summarys(tmp_path: Path, scenario: str, overrides: list[str]) -> None:
    from emulator.assembly.session import run_scenario
    from emulator.scenario.loader import load_scenario
    from tests.conftest import SCENARIOS

    scn = load_scenario(SCENARIOS / scenario, overrides)
    run_scenario(scn, tmp_path / "run")
    assert check_page_against_summary(tmp_path / "run") > 40
