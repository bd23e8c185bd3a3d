"""Plugins by entry point, as python-can finds its interfaces (``can.interface`` entry points): a package
installed next to psns-hil adds to the emulator's registries without editing it (docs/plugins.md).

=========================  ======================================================  ================================
group                      value                                                   merged into
=========================  ======================================================  ================================
``psns_hil.filters``       a :class:`~firmware_model.filters.interface.NavFilter`  ``firmware.filter`` names
                           subclass (``params_model``: its parameter dataclass)    (:func:`filter_names`)
``psns_hil.links``         a :class:`emulator.links.base.Link` subclass            URL schemes (:mod:`emulator.links`)
                           (``url_options``, ``url_usage``)
``psns_hil.firmware``      ``(FirmwareConfig) -> FirmwareProtocol``                ``firmware.implementation``
                                                                                   (:func:`firmware_names`)
=========================  ======================================================  ================================

The entry point's name is the registered name. Built-in names cannot be replaced (a plugin that tries is
refused and reported). A plugin that fails to import does not stop anything else: the failure is kept in
:data:`PLUGIN_ERRORS` and shows in the error of a scenario that names it. The groups are read once per process
(:func:`entry_points_of`); :func:`reset` forgets them (tests).

This module imports nothing of the emulator's layers and nothing of the firmware, and loads nothing at import:
the scenario schema (which the world and the sensors import: the independence rule) and the links read their
names from it. The firmware's tables are filled where the emulator meets the firmware,
:func:`emulator.dsp.firmware_setup.register_plugins`, with the plugins a scenario names only: a run imports no
plugin it does not use (issue 41), and ``psns-hil validate`` checks the named ones' kinds
(:func:`emulator.dsp.firmware_setup.check_firmware`).
"""

from __future__ import annotations

import difflib
from functools import cache
from importlib.metadata import EntryPoint, entry_points
from typing import Any

from protocols.host import FILTER_VARIANT_NAMES

__all__ = [
    "BUILTIN_FIRMWARE",
    "GROUPS",
    "PLUGIN_ERRORS",
    "did_you_mean",
    "entry_points_of",
    "filter_names",
    "firmware_names",
    "load_object",
    "plugin",
    "plugin_names",
    "reset",
]

#: the firmware implementation of this package (``firmware_model.Firmware``)
BUILTIN_FIRMWARE = ("psns_hil",)

GROUPS = ("psns_hil.filters", "psns_hil.links", "psns_hil.firmware")

#: (group, name) -> why the plugin could not be registered
PLUGIN_ERRORS: dict[tuple[str, str], str] = {}


@cache
def entry_points_of(group: str) -> tuple[EntryPoint, ...]:
    """The installed entry points of ``group``, sorted by name (read once per process)."""
    return tuple(sorted(entry_points(group=group), key=lambda ep: ep.name))


def reset() -> None:
    """Forget what was read (a test that installs a plugin package in the running process)."""
    entry_points_of.cache_clear()
    PLUGIN_ERRORS.clear()
    _objects.clear()


_objects: dict[tuple[str, str], Any] = {}


def load_object(group: str, ep: EntryPoint) -> Any | None:
    """``ep.load()``, or None with the reason in :data:`PLUGIN_ERRORS`."""
    try:
        return ep.load()
    except Exception as exc:  # a broken plugin is reported, never fatal to the others
        PLUGIN_ERRORS[(group, ep.name)] = f"{ep.value}: {type(exc).__name__}: {exc}"
        return None


def filter_names() -> list[str]:
    """Every ``firmware.filter`` name: the built-in variants (the host protocol's ``FilterVariant`` table) and the
    ``psns_hil.filters`` entry points (their names only: nothing is imported)."""
    return sorted({*FILTER_VARIANT_NAMES, *(ep.name for ep in entry_points_of("psns_hil.filters"))})


def firmware_names() -> list[str]:
    """Every ``firmware.implementation`` name: ``psns_hil`` and the ``psns_hil.firmware`` entry points."""
    return sorted({*BUILTIN_FIRMWARE, *(ep.name for ep in entry_points_of("psns_hil.firmware"))})


def plugin(group: str, name: str) -> Any | None:
    """The object the entry point ``name`` of ``group`` names (imported once), None when there is none or it
    failed to load (:data:`PLUGIN_ERRORS`)."""
    key = (group, name)
    if key in _objects:
        return _objects[key]
    obj = None
    for ep in entry_points_of(group):
        if ep.name == name:
            obj = load_object(group, ep)
            break
    _objects[key] = obj
    return obj


def plugin_names(group: str) -> list[str]:
    """The entry-point names of ``group``."""
    return [ep.name for ep in entry_points_of(group)]


def did_you_mean(what: str, name: str, known: list[str], group: str) -> str:
    """``unknown WHAT 'x'; did you mean 'y'? registered: a, b, c`` (+ a broken plugin of that name, if any)."""
    close = difflib.get_close_matches(name, known, n=1)
    msg = f"unknown {what} {name!r}"
    if close:
        msg += f"; did you mean {close[0]!r}?"
    msg += f" registered: {', '.join(known)}"
    broken = PLUGIN_ERRORS.get((group, name))
    if broken:
        msg += f" (the plugin {name!r} of the entry-point group {group} failed to load: {broken})"
    return msg
