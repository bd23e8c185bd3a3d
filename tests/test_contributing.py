"""CONTRIBUTING.md names the code as it stands: every repository path it names exists, every dotted name of the three
packages it names imports, every link resolves, and the README and the guide's index link to it.

A path is a backquoted span whose first segment is a top-level entry of the repository (``emulator/faults/base.py``,
``tests/vectors/``); a placeholder segment (``emulator/links/<scheme>.py``) is checked up to the folder that holds
it. A dotted name is a backquoted ``protocols.X``, ``firmware_model.X`` or ``emulator.X``: the longest importable
module prefix, then attributes (``emulator.faults.base.INJECTORS``, ``firmware_model.filters.interface.NavFilter``).
"""

from __future__ import annotations

import importlib
import re

import pytest

from tests.conftest import ROOT

CONTRIBUTING = ROOT / "CONTRIBUTING.md"
#: a backquoted span on one line
SPAN = re.compile(r"`([^`\n]+)`")
#: a dotted name in one of the shipped packages
DOTTED = re.compile(r"^(?:protocols|firmware_model|emulator)(?:\.\w+)+$")
#: a markdown link ``[text](target)``
LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")


def _top_level() -> set[str]:
    return {p.name for p in ROOT.iterdir() if not p.name.startswith(".")}


def named_paths(text: str, top: set[str]) -> list[str]:
    """The repository paths a text names in backquotes (see the module docstring)."""
    out = []
    for span in SPAN.findall(text):
        token = span.split()[0] if span.split() else ""
        if "/" in token and token.split("/")[0] in top:
            out.append(token)
    return out


def path_exists(token: str) -> bool:
    """Whether a named path exists; with a ``<placeholder>`` or ``*``, whether the folder above it does."""
    parts = token.rstrip("/").split("/")
    for i, part in enumerate(parts):
        if "<" in part or "*" in part:
            return (ROOT.joinpath(*parts[:i])).is_dir()
    return (ROOT / token.rstrip("/")).exists()


def resolves(name: str) -> bool:
    """Whether a dotted name is a module, or an attribute chain on the longest importable module prefix."""
    parts = name.split(".")
    for cut in range(len(parts), 0, -1):
        try:
            obj = importlib.import_module(".".join(parts[:cut]))
        except ImportError:
            continue
        for attr in parts[cut:]:
            if not hasattr(obj, attr):
                return False
            obj = getattr(obj, attr)
        return True
    return False


def test_the_extractors_find_paths_and_tell_missing_ones():
    text = "see `emulator/faults/base.py`, `emulator/links/<scheme>.py`, `tests/nowhere.py`, `make golden`, `a/b`"
    got = named_paths(text, {"emulator", "tests"})
    assert got == ["emulator/faults/base.py", "emulator/links/<scheme>.py", "tests/nowhere.py"]
    assert [path_exists(p) for p in got] == [True, True, False]
    assert path_exists("emulator/nowhere/<scheme>.py") is False
    assert resolves("emulator.faults.base.INJECTORS") and resolves("protocols.stream")
    assert not resolves("emulator.faults.scheduler.NO_SUCH_TABLE")


def test_every_path_named_in_contributing_exists():
    paths = named_paths(CONTRIBUTING.read_text(encoding="utf-8"), _top_level())
    assert len(paths) > 40  # the recipes name files: an extractor that finds none checks nothing
    missing = sorted({p for p in paths if not path_exists(p)})
    assert not missing, f"CONTRIBUTING.md names paths that do not exist: {missing}"


def test_every_dotted_name_in_contributing_resolves():
    names = [s for s in SPAN.findall(CONTRIBUTING.read_text(encoding="utf-8")) if DOTTED.match(s)]
    assert len(names) > 20
    missing = sorted({n for n in names if not resolves(n)})
    assert not missing, f"CONTRIBUTING.md names what the packages do not have: {missing}"


def test_every_link_in_contributing_resolves():
    targets = [t for t in LINK.findall(CONTRIBUTING.read_text(encoding="utf-8")) if "://" not in t]
    assert targets
    broken = sorted({t for t in targets if t.split("#")[0] and not (ROOT / t.split("#")[0]).exists()})
    assert not broken, broken


@pytest.mark.parametrize("index", ["README.md", "docs/README.md"])
def test_the_readme_and_the_guide_link_to_contributing(index: str):
    page = ROOT / index
    targets = {(page.parent / t.split("#")[0]).resolve() for t in LINK.findall(page.read_text(encoding="utf-8"))}
    assert CONTRIBUTING.resolve() in targets
