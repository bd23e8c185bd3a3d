"""The packaging facts are declared once (issue 42 item 8): the version lives in ``protocols.__version__`` and
pyproject.toml reads it from there; no dependency is listed twice; the coverage data file is never committed."""

from __future__ import annotations

import importlib.metadata
import re
import subprocess
import tomllib
from pathlib import Path

import protocols

ROOT = Path(__file__).resolve().parents[1]


def _pyproject() -> dict:
    with (ROOT / "pyproject.toml").open("rb") as f:
        return tomllib.load(f)


def test_version_is_declared_once_and_installed_metadata_agrees() -> None:
    project = _pyproject()["project"]
    assert "version" not in project, "pyproject.toml must take the version from protocols.__version__"
    assert "version" in project["dynamic"]
    assert importlib.metadata.version("psns-hil") == protocols.__version__


def test_no_dependency_is_listed_twice() -> None:
    project = _pyproject()["project"]
    lists = [project["dependencies"], *project.get("optional-dependencies", {}).values()]
    names = [re.split(r"[<>=!~\[; ]", req, maxsplit=1)[0].lower().replace("_", "-") for deps in lists for req in deps]
    dupes = sorted({n for n in names if names.count(n) > 1})
    assert not dupes, f"listed more than once in pyproject.toml: {dupes}"


def test_coverage_data_is_not_tracked() -> None:
    tracked = subprocess.run(["git", "ls-files", ".coverage", ".coverage.*"], cwd=ROOT, capture_output=True,
                             text=True, check=False)
    if tracked.returncode != 0:  # not a git checkout (an sdist): nothing to check
        return
    assert tracked.stdout.strip() == ""
