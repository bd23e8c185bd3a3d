"""Facts declared once (issue 42 item 4): the units, the version, the dependency list."""

from __future__ import annotations

import re
import tomllib

from tests.conftest import ROOT

PACKAGES = ("protocols", "firmware_model", "emulator")


def _assignments(pattern: str) -> list[str]:
    rx = re.compile(pattern, re.M)
    return sorted(p.relative_to(ROOT).as_posix() for pkg in PACKAGES for p in (ROOT / pkg).rglob("*.py")
                  if rx.search(p.read_text(encoding="utf-8")))


def test_units_are_declared_once_in_the_lowest_layer():
    for name in ("DEG", "DPH", "G_STD"):
        assert _assignments(rf"^{name}\s*(:[^=]*)?=") == ["protocols/constants.py"], name


def test_the_version_is_declared_once():
    assert _assignments(r"^__version__\s*(:[^=]*)?=") == ["protocols/__init__.py"]
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    assert "version" not in project and "version" in project["dynamic"]


def test_every_dependency_is_listed_once():
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    lists = [project["dependencies"], *project["optional-dependencies"].values()]
    names = [re.split(r"[<>=!~\[; ]", req, maxsplit=1)[0].lower().replace("_", "-") for deps in lists for req in deps]
    assert len(names) == len(set(names)), sorted(n for n in set(names) if names.count(n) > 1)
