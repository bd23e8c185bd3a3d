"""The scenario's ``expectations`` section: one model per kind of check, their time windows, and the
Python hooks.

Expectations (``emulator.verification.expectations`` evaluates them at the end of the run): a list; each item
has exactly one key naming the kind of check. Time windows are ``after_s`` / ``until_s`` or
``between_s: [a, b]`` (scenario seconds, inclusive). Cross-field checks (an expectation on a link the scenario does
not have, a Python hook that does not import) are in :func:`emulator.scenario.cross_checks.cross_check`. An
expectation window after the end of the run is not an error here (tests shorten library scenarios by overriding
``duration_s``); it fails at the end with "nothing measured".
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from typing import Any, ClassVar, Literal

from pydantic import ConfigDict, Field, model_validator

from .base import Model, OneKindModel
from .consistency_schema import ConsistencyExpectation

__all__ = [
    "EXPECTATION_KINDS",
    "LINK_COUNTERS",
    "NAV_MODE_FLAGS",
    "DspBound",
    "EventExpectation",
    "Expectation",
    "FieldRange",
    "HookError",
    "LinkCounterBound",
    "NavErrorBound",
    "NavGapExpectation",
    "NavModeExpectation",
    "NavRateExpectation",
    "PsnsErrorBound",
    "PythonHook",
    "SummaryValueBound",
    "TimeWindow",
    "load_hook",
]

LINK_COUNTERS = ("bytes", "frames", "crc_errors", "dropped", "garbage_bytes", "framing_errors")


# ============================================================================ expectations
class TimeWindow(Model):
    """``after_s`` / ``until_s``, or ``between_s: [a, b]`` (inclusive, scenario seconds)."""

    after_s: float = Field(0.0, ge=0.0)
    until_s: float | None = Field(None, gt=0.0)
    between_s: tuple[float, float] | None = Field(None, description="[after_s, until_s] in one field")

    @model_validator(mode="after")
    def _window(self) -> TimeWindow:
        if self.between_s is not None:
            a, b = (float(x) for x in self.between_s)
            if a < 0 or b <= a:
                raise ValueError(f"between_s must be [a, b] with 0 <= a < b, got [{a:g}, {b:g}]")
            # a re-validated dump carries all three; only a contradiction is an error
            if ("after_s" in self.model_fields_set and self.after_s != a) or (
                    "until_s" in self.model_fields_set and self.until_s != b):
                raise ValueError("give between_s or after_s/until_s, not both")
            self.after_s, self.until_s = a, b
        if self.until_s is not None and self.until_s <= self.after_s:
            raise ValueError(f"until_s {self.until_s:g} must be after after_s {self.after_s:g}")
        return self

    def describe_window(self) -> str:
        if self.until_s is None:
            return f"t >= {self.after_s:g} s"
        return f"{self.after_s:g} s <= t <= {self.until_s:g} s"

    def covers(self, t: float) -> bool:
        return t >= self.after_s and (self.until_s is None or t <= self.until_s)


class NavErrorBound(TimeWindow):
    """RMS or max of a navigation error against truth inside a window, at most ``max``."""

    metric: Literal["attitude_deg", "heading_deg", "position_m", "velocity_mps"]
    stat: Literal["rms", "max"] = "max"
    max: float = Field(ge=0)


class PsnsErrorBound(TimeWindow):
    """A statistic of the firmware's solar-vector error against truth (``psns.csv``: the angle between each solved
    bi-direction solar vector and the world's sun in the body frame) over the solves exposed inside a window, at
    most ``max``; needs a polarization camera."""

    metric: Literal["solar_vector_deg"] = "solar_vector_deg"
    stat: Literal["median", "p95", "max"] = "p95"
    max: float = Field(ge=0)


class FieldRange(Model):
    min: float | None = None
    max: float | None = None


class EventExpectation(TimeWindow):
    """An event (``events.jsonl``) that must occur (``min_count``, default 1, or 0 when only ``max_count`` is
    given) or must not (``max_count: 0``)
    inside a window, optionally from one ``source`` and with field values (``fields``: exact values, or
    ``{min, max}`` for numbers)."""

    name: str = Field(min_length=1, description="the event's name (its 'event' field)")
    source: str | None = Field(None, description="firmware, fault, dsp, fpga, ... (omit: any)")
    min_count: int = Field(1, ge=0)
    max_count: int | None = Field(None, ge=0)
    fields: dict[str, str | int | float | bool | FieldRange] = Field(default_factory=dict)

    @model_validator(mode="after")
    def _counts(self) -> EventExpectation:
        if self.max_count is not None and "min_count" not in self.model_fields_set:
            self.min_count = 0  # "at most N" (max_count: 0 = must not occur)
        if self.max_count is not None and self.max_count < self.min_count:
            raise ValueError(f"max_count {self.max_count} is below min_count {self.min_count}")
        return self


class LinkCounterBound(Model):
    """A link counter of the summary's link table between ``min`` and ``max``."""

    name: str = Field(description="gyro, gnss, psns, host, monitor or uart0..uart3")
    counter: Literal["bytes", "frames", "crc_errors", "dropped", "garbage_bytes", "framing_errors"]
    min: int | None = Field(None, ge=0)
    max: int | None = Field(None, ge=0)

    @model_validator(mode="after")
    def _some(self) -> LinkCounterBound:
        if self.min is None and self.max is None:
            raise ValueError("a link expectation needs min, max or both")
        if self.min is not None and self.max is not None and self.max < self.min:
            raise ValueError(f"max {self.max} is below min {self.min}")
        return self


class DspBound(Model):
    """A DSP figure of the summary between ``min`` and ``max``."""

    field: Literal["cpu_load_pct_max", "deadline_misses", "over_budget_ticks", "tick_utilization_max_pct",
                   "watchdog_trips", "resets"]
    min: float | None = Field(None, ge=0)
    max: float | None = Field(None, ge=0)

    @model_validator(mode="after")
    def _some(self) -> DspBound:
        if self.min is None and self.max is None:
            raise ValueError("a dsp expectation needs min, max or both")
        if self.min is not None and self.max is not None and self.max < self.min:
            raise ValueError(f"max {self.max:g} is below min {self.min:g}")
        return self


NAV_MODE_FLAGS = {"aligning": 0x01, "navigating": 0x02, "gnss_aided": 0x04, "psns_aided": 0x08, "degraded": 0x10}


class NavModeExpectation(TimeWindow):
    """The fraction of the host's NAV_SOLUTION frames inside a window that carry a mode flag."""

    flag: Literal["aligning", "navigating", "gnss_aided", "psns_aided", "degraded"]
    min_fraction: float | None = Field(None, ge=0.0, le=1.0)
    max_fraction: float | None = Field(None, ge=0.0, le=1.0)

    @model_validator(mode="after")
    def _some(self) -> NavModeExpectation:
        if self.min_fraction is None and self.max_fraction is None:
            raise ValueError("a nav_mode expectation needs min_fraction, max_fraction or both")
        return self


class NavGapExpectation(TimeWindow):
    """The largest gap between consecutive navigation frames at the host (their arrival times, ``nav.csv``
    ``arrival_s``) inside a window: at least ``min_gap_s`` (a cable pulled: nothing arrives) and/or at most
    ``max_gap_s`` (the output never stalls longer). A gap is measured inside the window only (clipped to it)."""

    min_gap_s: float | None = Field(None, gt=0.0)
    max_gap_s: float | None = Field(None, gt=0.0)

    @model_validator(mode="after")
    def _some(self) -> NavGapExpectation:
        if self.min_gap_s is None and self.max_gap_s is None:
            raise ValueError("a nav_gap expectation needs min_gap_s, max_gap_s or both")
        if self.min_gap_s is not None and self.max_gap_s is not None and self.max_gap_s < self.min_gap_s:
            raise ValueError(f"max_gap_s {self.max_gap_s:g} is below min_gap_s {self.min_gap_s:g}")
        return self


class NavRateExpectation(TimeWindow):
    """The mean rate of navigation frames at the host inside a window (``(frames - 1) / (last - first arrival)``)
    within ``tolerance`` (relative) of ``rate_hz``."""

    rate_hz: float = Field(gt=0.0)
    tolerance: float = Field(0.01, gt=0.0, lt=1.0)


class SummaryValueBound(Model):
    """Any number in ``summary.json`` by its dotted path (e.g. ``firmware.counters.psns_rejected``)."""

    path: str = Field(pattern=r"^[A-Za-z0-9_]+(\.[A-Za-z0-9_]+)*$")
    min: float | None = None
    max: float | None = None

    @model_validator(mode="after")
    def _some(self) -> SummaryValueBound:
        if self.min is None and self.max is None:
            raise ValueError("a summary expectation needs min, max or both")
        return self


class PythonHook(Model):
    """A function in a ``.py`` file next to the scenario: ``function(summary, run_dir, **args)`` returns
    ``bool``, ``(passed, value[, message])`` or ``{"passed", "value", "message"}``."""

    file: str = Field(pattern=r"\.py$", description="path relative to the scenario file")
    function: str = Field(pattern=r"^[A-Za-z_][A-Za-z0-9_]*$")
    args: dict[str, Any] = Field(default_factory=dict, description="keyword arguments passed to the function")
    description: str | None = None


class Expectation(OneKindModel):
    """One check evaluated at the end of the run; exactly one key."""

    kind_label: ClassVar[str] = "an expectation"

    model_config = ConfigDict(json_schema_extra={"minProperties": 1, "maxProperties": 1})

    nav_error: NavErrorBound | None = None
    event: EventExpectation | None = None
    link: LinkCounterBound | None = None
    dsp: DspBound | None = None
    nav_mode: NavModeExpectation | None = None
    nav_gap: NavGapExpectation | None = None
    nav_rate: NavRateExpectation | None = None
    psns: PsnsErrorBound | None = None
    summary: SummaryValueBound | None = None
    python: PythonHook | None = None
    consistency: ConsistencyExpectation | None = None


EXPECTATION_KINDS = tuple(Expectation.model_fields)


# ============================================================================ Python hooks
class HookError(Exception):
    """A Python hook file that cannot be loaded (message says why)."""


def check_hook_path(base_dir: str | Path | None, file: str) -> Path:
    """The hook file's confined path (:func:`emulator.scenario.paths.confine`); :class:`HookError` when it is
    outside the scenario's directory or missing. Imports nothing (what ``validate`` runs)."""
    from .paths import PathNotAllowed, confine

    try:
        p = confine(base_dir, file, "python hook")
    except PathNotAllowed as exc:
        raise HookError(str(exc)) from None
    if not p.is_file():
        raise HookError(f"no such file {file!r}")
    return p


def load_hook(base_dir: str | Path | None, file: str, function: str, allow: bool | None = None) -> Any:
    """Import ``file`` (relative to ``base_dir``, confined to it) and return its ``function``; :class:`HookError`
    otherwise, and always when hooks are not allowed (``allow``; default: ``psns-hil run --allow-hooks``)."""
    from .paths import hooks_allowed

    if not (hooks_allowed() if allow is None else allow):
        raise HookError(f"{file}: python hooks are not run without --allow-hooks (a scenario could run any code)")
    p = check_hook_path(base_dir, file)
    mod_name = f"_psns_hil_hook_{abs(hash(str(p.resolve())))}"
    spec = importlib.util.spec_from_file_location(mod_name, p)
    if spec is None or spec.loader is None:
        raise HookError(f"cannot import {str(p)!r}")
    mod = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(mod)
    except SyntaxError as exc:
        raise HookError(f"{p.name}:{exc.lineno}: syntax error: {exc.msg}") from exc
    except Exception as exc:
        raise HookError(f"importing {p.name} raised {type(exc).__name__}: {exc}") from exc
    fn = getattr(mod, function, None)
    if fn is None:
        names = sorted(n for n in vars(mod) if callable(vars(mod)[n]) and not n.startswith("_"))
        import difflib

        close = difflib.get_close_matches(function, names, n=1, cutoff=0.6)
        hint = f"; did you mean {close[0]!r}?" if close else (f"; it defines {', '.join(names)}" if names else "")
        raise HookError(f"{p.name} has no function {function!r}{hint}")
    if not callable(fn):
        raise HookError(f"{p.name}: {function!r} is not a function")
    sys.modules.pop(mod_name, None)
    return fn
