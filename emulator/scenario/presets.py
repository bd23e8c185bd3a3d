"""Named sensor presets (``emulator/presets/<kind>.yaml``) and the preset + override merge.

Each file maps a preset name to a mapping of figures (a ``description`` key is documentation).
:func:`preset` returns a deep copy so callers may modify it; :func:`merged` applies a scenario's
overrides (``None`` values are "not given") on top.
"""

from __future__ import annotations

import copy
from functools import cache
from pathlib import Path
from typing import Any

import yaml

__all__ = ["PRESET_DIR", "merged", "preset", "preset_names"]

PRESET_DIR = Path(__file__).resolve().parents[1] / "presets"


@cache
def _load(kind: str) -> dict[str, Any]:
    path = PRESET_DIR / f"{kind}.yaml"
    with open(path, encoding="utf-8") as fh:
        data = yaml.safe_load(fh)
    if not isinstance(data, dict):
        raise ValueError(f"{path}: a preset file maps names to settings")
    return data


def preset_names(kind: str) -> list[str]:
    """Names of the presets of ``kind`` (``imu``, ``gnss``, ``camera``, ``compass``, ``magnetometer``)."""
    return sorted(_load(kind))


def preset(kind: str, name: str) -> dict[str, Any]:
    """A deep copy of preset ``name`` of ``kind`` without its description."""
    data = _load(kind)
    if name not in data:
        raise KeyError(f"unknown {kind} preset {name!r}; available: {', '.join(sorted(data))}")
    out = copy.deepcopy(data[name])
    out.pop("description", None)
    return out


def merged(base: dict[str, Any], overrides: dict[str, Any]) -> dict[str, Any]:
    """``base`` with every non-None value of ``overrides`` applied (nested mappings merge)."""
    out = copy.deepcopy(base)
    for k, v in overrides.items():
        if v is None:
            continue
        if isinstance(v, dict) and isinstance(out.get(k), dict):
            out[k] = merged(out[k], v)
        else:
            out[k] = copy.deepcopy(v)
    return out
