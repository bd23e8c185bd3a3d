"""Scenario expectations, evaluated at the end of a run against the recorder's results and the summary.

Every kind of ``expectations:`` item (``emulator.scenario.expectations_schema``) has its evaluator here, a function
registered for its kind with :func:`evaluates` (the table :data:`EVALUATORS`; a test checks that every kind of the
schema has one).
A check that has nothing to measure fails (no navigation frames in the window, a summary value
that does not exist): nothing measured proves nothing. A Python hook that raises fails with the
exception's message; it never stops the evaluation of the other checks.
"""

from __future__ import annotations

import copy
import itertools
import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..recording.psns_error import solar_error_stats
from ..scenario.expectations_schema import NAV_MODE_FLAGS, EventExpectation, FieldRange, HookError, load_hook
from ..scenario.schema import Expectation

__all__ = ["EVALUATORS", "ExpectationResult", "RunView", "evaluate_expectations", "evaluates", "matching_events"]


@dataclass
class ExpectationResult:
    """Outcome of one expectation: what was checked, the measured value, pass/fail and why."""

    index: int
    kind: str
    description: str
    value: float | int | str | None
    passed: bool
    message: str = ""
    #: False when the expectation cannot apply to this run (a replay has no sensor links): it does not fail
    applicable: bool = True
    #: True for a Python hook that was not run (no ``--allow-hooks``): neither passed nor failed
    not_run: bool = False

    @property
    def status(self) -> str:
        """``pass``, ``fail``, ``not_applicable`` or ``not_run`` (summary.json's ``expectations[i].status``)."""
        if self.not_run:
            return "not_run"
        if not self.applicable:
            return "not_applicable"
        return "pass" if self.passed else "fail"

    def as_dict(self) -> dict[str, Any]:
        return {"index": self.index, "kind": self.kind, "description": self.description,
                "value": self.value, "passed": self.passed, "message": self.message, "applicable": self.applicable,
                "status": self.status}


def _bounds(lo: float | None, hi: float | None) -> str:
    parts = []
    if lo is not None:
        parts.append(f">= {lo:g}")
    if hi is not None:
        parts.append(f"<= {hi:g}")
    return " and ".join(parts)


def _within(v: float, lo: float | None, hi: float | None) -> bool:
    return (lo is None or v >= lo) and (hi is None or v <= hi)


def _field_ok(have: Any, want: Any) -> bool:
    if isinstance(want, FieldRange):
        if isinstance(have, bool) or not isinstance(have, (int, float)):
            return False
        return _within(float(have), want.min, want.max)
    if isinstance(want, bool) or isinstance(have, bool):
        return isinstance(have, bool) and isinstance(want, bool) and have == want
    if isinstance(want, (int, float)) and isinstance(have, (int, float)):
        return float(have) == float(want)
    return str(have) == str(want)


def matching_events(events: Iterable[dict[str, Any]], e: EventExpectation) -> list[dict[str, Any]]:
    """The events that match name, source, window and field values of ``e``."""
    out = []
    for ev in events:
        if ev.get("event") != e.name:
            continue
        if e.source is not None and ev.get("source") != e.source:
            continue
        t = ev.get("t_s")
        if t is None or not e.covers(float(t)):
            continue
        if all(k in ev and _field_ok(ev[k], w) for k, w in e.fields.items()):
            out.append(ev)
    return out


def _lookup(summary: dict[str, Any], path: str) -> Any:
    cur: Any = summary
    for part in path.split("."):
        if isinstance(cur, dict) and part in cur:
            cur = cur[part]
        elif isinstance(cur, list) and part.isdigit() and int(part) < len(cur):
            cur = cur[int(part)]
        else:
            raise KeyError(part)
    return cur


def _arrival_times(run_dir: str | Path | None) -> list[float] | None:
    """The host's arrival times of the navigation frames (``nav.csv`` ``arrival_s``), s; None without the file."""
    import csv

    if run_dir is None or not (Path(run_dir) / "nav.csv").exists():
        return None
    out = []
    with open(Path(run_dir) / "nav.csv", newline="", encoding="utf-8") as f:
        for row in csv.DictReader(f):
            try:
                out.append(float(row["arrival_s"]))
            except (KeyError, TypeError, ValueError):
                continue
    return out


def largest_gap(times: list[float], after_s: float, until_s: float | None) -> tuple[float, float]:
    """The largest interval without a frame inside ``[after_s, until_s]`` (gaps clipped to the window; the window's
    edges count when no frame falls on them) and where it starts, s."""
    end = until_s if until_s is not None else (times[-1] if times else after_s)
    inside = [t for t in times if after_s <= t <= end]
    edges = [after_s, *inside, end]
    best, at = 0.0, after_s
    for a, b in itertools.pairwise(edges):
        if b - a > best:
            best, at = b - a, a
    return best, at


def _hook_result(res: Any) -> tuple[bool, Any, str]:
    """Normalise what a hook returned: bool, (passed, value[, message]) or a dict."""
    if isinstance(res, bool):
        return res, None, ""
    if isinstance(res, dict) and "passed" in res:
        return bool(res["passed"]), res.get("value"), str(res.get("message", ""))
    if isinstance(res, tuple) and 1 <= len(res) <= 3 and isinstance(res[0], bool):
        return res[0], res[1] if len(res) > 1 else None, str(res[2]) if len(res) > 2 else ""
    raise TypeError(f"a hook returns bool, (passed, value[, message]) or {{'passed', 'value', 'message'}}; "
                    f"got {type(res).__name__}")


def _plain(v: Any) -> float | int | str | None:
    if v is None or isinstance(v, (int, float, str)):
        return v
    try:
        return float(v)
    except (TypeError, ValueError):
        return str(v)


@dataclass(frozen=True)
class RunView:
    """What an evaluator may look at: the recorder, the summary so far, the run and scenario directories."""

    recorder: Any
    summary: dict[str, Any]
    run_dir: str | Path | None
    base_dir: str | Path | None
    #: the run's simulated duration, s
    t_end: float

    def empty(self, w: Any) -> str:
        """Why a window measured nothing."""
        if w.after_s >= self.t_end:
            return f"the window starts at {w.after_s:g} s, after the run ended ({self.t_end:g} s)"
        return "no navigation frames in the window"


#: ``(index, kind, the kind's parameters, the run) -> result``
Evaluator = Callable[[int, str, Any, RunView], ExpectationResult]

#: the evaluator of every expectation kind, by kind (the field name on
#: :class:`emulator.scenario.expectations_schema.Expectation`); filled by :func:`evaluates`
EVALUATORS: dict[str, Evaluator] = {}


def evaluates(*kinds: str) -> Callable[[Evaluator], Evaluator]:
    """Register the decorated function as the evaluator of ``kinds`` (a kind is evaluated by one function)."""
    def register(fn: Evaluator) -> Evaluator:
        for kind in kinds:
            if kind in EVALUATORS:
                raise ValueError(f"expectation kind {kind!r} already has an evaluator")
            EVALUATORS[kind] = fn
        return fn
    return register


@evaluates("nav_error")
def _nav_error(i: int, kind: str, b: Any, run: RunView) -> ExpectationResult:
    stats = run.recorder.error_window(b.metric, b.after_s, b.until_s).as_dict()
    v = stats[b.stat]
    desc = f"{b.stat} {b.metric} <= {b.max:g} for {b.describe_window()}"
    msg = "" if v is not None else run.empty(b)
    return ExpectationResult(i, kind, desc, v, v is not None and abs(v) <= b.max, msg)


@evaluates("psns")
def _psns(i: int, kind: str, pb: Any, run: RunView) -> ExpectationResult:
    errs = run.recorder.solar_error_window(pb.after_s, pb.until_s)
    v = solar_error_stats(errs)[pb.stat] if errs else None
    desc = f"{pb.stat} {pb.metric} <= {pb.max:g} for solves exposed at {pb.describe_window()}"
    msg = f"{len(errs)} solves" if errs else (
        run.empty(pb) if pb.after_s >= run.t_end else "no solar vector solved in the window")
    return ExpectationResult(i, kind, desc, v, v is not None and v <= pb.max, msg)


@evaluates("event")
def _event(i: int, kind: str, ev: Any, run: RunView) -> ExpectationResult:
    recorder = run.recorder
    it = getattr(recorder, "iter_events", None)  # the whole run from events.jsonl (memory: a tail)
    hits = matching_events(it() if it is not None else recorder.events, ev)
    n = len(hits)
    src = f" from {ev.source}" if ev.source else ""
    flds = "".join(f", {k} {'in [' + _bounds(w.min, w.max) + ']' if isinstance(w, FieldRange) else '= ' + repr(w)}"
                   for k, w in ev.fields.items())
    desc = f"event {ev.name}{src}{flds} in {ev.describe_window()}: count {_bounds(ev.min_count, ev.max_count)}"
    msg = f"first at t = {hits[0]['t_s']:.3f} s" if hits else (
        run.empty(ev) if ev.after_s >= run.t_end else "")
    return ExpectationResult(i, kind, desc, n, _within(n, ev.min_count, ev.max_count), msg)


@evaluates("link")
def _link(i: int, kind: str, lb: Any, run: RunView) -> ExpectationResult:
    links = run.summary.get("links", {})
    if lb.name not in links and run.summary.get("replay"):
        return ExpectationResult(i, kind, f"{lb.name}.{lb.counter} {_bounds(lb.min, lb.max)}", None,
                                 True, f"not applicable to a replay: link {lb.name!r} is not part of it "
                                 "(a replay has the host port and the DSP UARTs only)", applicable=False)
    if lb.name not in links:
        return ExpectationResult(i, kind, f"link {lb.name!r} exists", None, False,
                                 f"no link {lb.name!r} in this run")
    v = links[lb.name].get(lb.counter)
    ok = v is not None and _within(v, lb.min, lb.max)
    return ExpectationResult(i, kind, f"{lb.name}.{lb.counter} {_bounds(lb.min, lb.max)}", v, ok)


@evaluates("dsp")
def _dsp(i: int, kind: str, db: Any, run: RunView) -> ExpectationResult:
    v = run.summary.get("dsp", {}).get(db.field)
    ok = v is not None and _within(v, db.min, db.max)
    return ExpectationResult(i, kind, f"dsp.{db.field} {_bounds(db.min, db.max)}", v, ok,
                             "" if v is not None else "not measured")


@evaluates("nav_mode")
def _nav_mode(i: int, kind: str, nm: Any, run: RunView) -> ExpectationResult:
    bit = NAV_MODE_FLAGS[nm.flag]
    ser = run.recorder.mode_series
    total = hit = 0
    for k in range(0, len(ser), 2):
        if nm.covers(ser[k]):
            total += 1
            hit += 1 if int(ser[k + 1]) & bit else 0
    frac = hit / total if total else None
    desc = (f"fraction of nav frames with {nm.flag} in {nm.describe_window()} "
            f"{_bounds(nm.min_fraction, nm.max_fraction)}")
    ok = frac is not None and _within(frac, nm.min_fraction, nm.max_fraction)
    return ExpectationResult(i, kind, desc, frac, ok, f"{hit} of {total} frames" if total else run.empty(nm))


@evaluates("nav_gap")
def _nav_gap(i: int, kind: str, gb: Any, run: RunView) -> ExpectationResult:
    times = _arrival_times(run.run_dir)
    desc = (f"largest gap between nav frames at the host in {gb.describe_window()} "
            f"{_bounds(gb.min_gap_s, gb.max_gap_s)} s")
    if times is None:
        return ExpectationResult(i, kind, desc, None, False, "no nav.csv in the run directory")
    inside = [t for t in times if gb.covers(t)]
    if gb.after_s >= run.t_end:
        return ExpectationResult(i, kind, desc, None, False, run.empty(gb))
    t_end = run.t_end
    gap, at = largest_gap(times, gb.after_s, min(gb.until_s, t_end) if gb.until_s is not None else t_end)
    return ExpectationResult(i, kind, desc, round(gap, 6), _within(gap, gb.min_gap_s, gb.max_gap_s),
                             f"from t = {at:.3f} s; {len(inside)} frames in the window")


@evaluates("nav_rate")
def _nav_rate(i: int, kind: str, rb: Any, run: RunView) -> ExpectationResult:
    times = _arrival_times(run.run_dir)
    desc = (f"nav frames at the host at {rb.rate_hz:g} Hz +- {rb.tolerance:.1%} in "
            f"{rb.describe_window()}")
    if times is None:
        return ExpectationResult(i, kind, desc, None, False, "no nav.csv in the run directory")
    inside = [t for t in times if rb.covers(t)]
    if len(inside) < 2 or inside[-1] <= inside[0]:
        return ExpectationResult(i, kind, desc, None, False,
                                 f"{len(inside)} frame(s) in the window: no rate to measure")
    rate = (len(inside) - 1) / (inside[-1] - inside[0])
    return ExpectationResult(i, kind, desc, rate, abs(rate / rb.rate_hz - 1.0) <= rb.tolerance,
                             f"{len(inside)} frames")


@evaluates("summary")
def _summary(i: int, kind: str, sb: Any, run: RunView) -> ExpectationResult:
    summary = run.summary
    desc = f"{sb.path} {_bounds(sb.min, sb.max)}"
    try:
        v = _lookup(summary, sb.path)
    except KeyError as exc:
        if summary.get("replay") and sb.path.split(".")[0] in ("devices", "links", "link_stats", "fpga"):
            return ExpectationResult(i, kind, desc, None, True, f"not applicable to a replay: {sb.path} "
                                     "is measured on the sensors, which a replay does not run",
                                     applicable=False)
        return ExpectationResult(i, kind, desc, None, False, f"no value {sb.path!r} in the summary "
                                                              f"(missing {exc.args[0]!r})")
    if isinstance(v, bool):
        v = int(v)
    if not isinstance(v, (int, float)):
        return ExpectationResult(i, kind, desc, _plain(v), False, f"{sb.path} is not a number")
    return ExpectationResult(i, kind, desc, v, _within(v, sb.min, sb.max))


@evaluates("consistency")
def _consistency(i: int, kind: str, c: Any, run: RunView) -> ExpectationResult:
    what = ", ".join(c.groups + c.measurements)
    if c.include_heading and "heading" not in c.groups:  # asked_groups adds it where there is a heading source
        what += " (and heading, with a camera or compass)"
    desc = f"consistency of {what} at {c.confidence:.0%} over {c.runs} runs"
    return ExpectationResult(i, kind, desc, None, True, "a campaign-level check: run psns-hil campaign "
                             f"SCENARIO --runs {c.runs} --consistency", applicable=False)


@evaluates("python")
def _python(i: int, kind: str, h: Any, run: RunView) -> ExpectationResult:
    desc = h.description or f"{h.file}:{h.function}({', '.join(f'{k}={v!r}' for k, v in h.args.items())})"
    from ..scenario.paths import hooks_allowed

    if not hooks_allowed():
        return ExpectationResult(i, kind, desc, None, True, "not run: python hooks run only with "
                                 "psns-hil run --allow-hooks (a scenario could run any code)",
                                 applicable=False, not_run=True)
    try:
        fn = load_hook(run.base_dir, h.file, h.function)
        ok, v, msg = _hook_result(fn(copy.deepcopy(run.summary),
                                     Path(run.run_dir) if run.run_dir is not None else None, **h.args))
    except HookError as exc:
        return ExpectationResult(i, kind, desc, None, False, f"python hook: {exc}")
    except Exception as exc:
        return ExpectationResult(i, kind, desc, None, False, f"the hook raised {type(exc).__name__}: {exc}")
    return ExpectationResult(i, kind, desc, _plain(v), ok, msg)


def evaluate_expectations(expectations: list[Expectation], recorder: Any, summary: dict[str, Any],
                          run_dir: str | Path | None = None, base_dir: str | Path | None = None
                          ) -> list[ExpectationResult]:
    """Check every expectation (see module docstring): each by the evaluator registered for its kind
    (:data:`EVALUATORS`).

    Parameters
    ----------
    expectations : the scenario's ``expectations``.
    recorder : the run's :class:`emulator.recording.recorder.Recorder` (error series, events, mode series).
    summary : the run summary so far (without ``expectations`` and ``passed``).
    run_dir : the run directory (given to Python hooks).
    base_dir : the scenario file's directory (where Python hooks' files are).
    """
    run = RunView(recorder, summary, run_dir, base_dir, float(summary.get("sim_duration_s") or 0.0))
    return [_not_a_number(EVALUATORS[e.kind](i, e.kind, e.value, run)) for i, e in enumerate(expectations)]


def _not_a_number(r: ExpectationResult) -> ExpectationResult:
    """A NaN / infinite value never passes: no bound holds for it, and the reason says so."""
    v = r.value
    if isinstance(v, float) and not math.isfinite(v):
        why = f"the value is {v!r} (not a finite number: a metric went NaN or infinite in the run)"
        return ExpectationResult(r.index, r.kind, r.description, v, False, f"{why}; {r.message}" if r.message
                                 else why)
    return r
