"""docs/hostile-input.md keeps its promises by name: every row of a promise table (header ``| promise | kept by |``)
names at least one test as ``tests/<path>.py::<name>`` (or ``::<Class>::<name>``), and every such reference on the
page, in a table or in the prose, resolves to a test function that exists (read with ``ast``: nothing is imported
or collected). The format is written at the top of the page; other pages may adopt it."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from tests.conftest import ROOT

PAGE = ROOT / "docs" / "hostile-input.md"
#: a test reference: tests/<path>.py::<function> or tests/<path>.py::<Class>::<method>
REF = re.compile(r"(tests/[\w/.-]+\.py)::(\w+)(?:::(\w+))?")
HEADER = re.compile(r"^\|\s*promise\s*\|\s*kept by\s*\|\s*$", re.I)


def _promise_rows(text: str) -> list[tuple[int, str]]:
    rows: list[tuple[int, str]] = []
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        if HEADER.match(lines[i].strip()):
            i += 2  # the header and its |---|---| line
            while i < len(lines) and lines[i].lstrip().startswith("|"):
                rows.append((i + 1, lines[i]))
                i += 1
        i += 1
    return rows


def _defined(path: Path) -> set[str]:
    """``name`` of every module-level test function and ``Class::name`` of every method in ``path``."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    out: set[str] = set()
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            out.add(node.name)
        elif isinstance(node, ast.ClassDef):
            out |= {f"{node.name}::{m.name}" for m in node.body if isinstance(m, (ast.FunctionDef,
                                                                                   ast.AsyncFunctionDef))}
    return out


def test_the_page_states_the_format_and_has_promise_tables():
    text = PAGE.read_text(encoding="utf-8")
    head = "\n".join(text.splitlines()[:40])
    assert "| promise | kept by |" in head, "the format of a promise row is written at the top of the page"
    assert len(_promise_rows(text)) >= 20


def test_every_promise_row_names_a_test():
    bad = [f"line {n}: {row.strip()[:80]}" for n, row in _promise_rows(PAGE.read_text(encoding="utf-8"))
           if not REF.search(row)]
    assert not bad, "promise rows without a tests/...::name reference:\n" + "\n".join(bad)


def test_every_named_test_exists():
    text = PAGE.read_text(encoding="utf-8")
    refs = {(m.group(1), m.group(2) + (f"::{m.group(3)}" if m.group(3) else "")) for m in REF.finditer(text)}
    assert refs
    missing = []
    cache: dict[str, set[str]] = {}
    for path, name in sorted(refs):
        f = ROOT / path
        if not f.is_file():
            missing.append(f"{path}::{name} (no such file)")
            continue
        if path not in cache:
            cache[path] = _defined(f)
        if name not in cache[path] or not name.split("::")[-1].startswith("test"):
            missing.append(f"{path}::{name}")
    assert not missing, "docs/hostile-input.md names tests that do not exist:\n" + "\n".join(missing)


@pytest.mark.parametrize("row, ok", [("| x | `tests/a.py::test_b` |", True), ("| x | tests/a.py |", False)])
def test_the_reference_pattern(row, ok):
    assert bool(REF.search(row)) is ok
