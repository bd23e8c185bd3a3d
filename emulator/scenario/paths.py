"""Confinement of the file paths a scenario names (docs/hostile-input.md, "Untrusted scenarios").

A scenario may come from anyone: every file it names (recorded sensor data, Python hooks) must lie inside the
scenario's own directory. Absolute paths and ``..`` that leave it are refused, symbolic links are resolved before
the test. The environment variable ``PSNS_HIL_ALLOW_PATHS`` (directories separated by ``os.pathsep``) widens the
set of allowed roots, for a trusted setup that keeps recordings elsewhere.

Python hooks (``expectations[].python``) are never imported by ``validate``; ``run`` imports them only with
``--allow-hooks`` (which sets ``PSNS_HIL_ALLOW_HOOKS=1`` for the run and its processes).
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["ALLOW_HOOKS_ENV", "ALLOW_PATHS_ENV", "PathNotAllowed", "allowed_roots", "confine", "hooks_allowed"]

ALLOW_PATHS_ENV = "PSNS_HIL_ALLOW_PATHS"
ALLOW_HOOKS_ENV = "PSNS_HIL_ALLOW_HOOKS"


class PathNotAllowed(ValueError):
    """A scenario names a file outside the directories it may read (the message names the path, never content)."""


def allowed_roots(base_dir: str | Path | None) -> list[Path]:
    """The scenario's directory and the directories of ``PSNS_HIL_ALLOW_PATHS``, resolved."""
    roots = [Path(base_dir).resolve()] if base_dir is not None else [Path.cwd().resolve()]
    for extra in os.environ.get(ALLOW_PATHS_ENV, "").split(os.pathsep):
        if extra.strip():
            roots.append(Path(extra).expanduser().resolve())
    return roots


def confine(base_dir: str | Path | None, name: str, what: str = "file") -> Path:
    """The resolved path of ``name`` (relative to ``base_dir``, the scenario's directory) if it lies inside an
    allowed root (:func:`allowed_roots`); :class:`PathNotAllowed` otherwise."""
    if "\x00" in name:
        raise PathNotAllowed(f"{what} path contains a NUL character")
    p = Path(name).expanduser()
    base = Path(base_dir) if base_dir is not None else Path.cwd()
    full = (p if p.is_absolute() else base / p).resolve()
    for root in allowed_roots(base_dir):
        if full == root or full.is_relative_to(root):
            return full
    raise PathNotAllowed(f"{what} {name!r} is outside the scenario's directory (set {ALLOW_PATHS_ENV} to allow "
                         "other directories)")


def hooks_allowed() -> bool:
    """True when Python hooks may be imported (``psns-hil run --allow-hooks``)."""
    return os.environ.get(ALLOW_HOOKS_ENV, "") not in ("", "0")
