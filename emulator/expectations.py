"""Scenario expectations, evaluated at the end of a run against the recorder's results."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from .scenario.schema import Expectation

__all__ = ["ExpectationResult", "evaluate_expectations"]


@dataclass
class ExpectationResult:
    """Outcome of one expectation: what was checked, the measured value, and pass/fail."""

    index: int
    kind: str
    description: str
    value: float | int | None
    passed: bool

    def as_dict(self) -> dict[str, Any]:
        return {"index": self.index, "kind": self.kind, "description": self.description,
                "value": self.value, "passed": self.passed}


def evaluate_expectations(expectations: list[Expectation], recorder: Any, summary: dict[str, Any]) -> list[ExpectationResult]:
    """Check every expectation; a metric with no data fails (nothing measured proves nothing)."""
    out: list[ExpectationResult] = []
    for i, e in enumerate(expectations):
        if e.nav_error is not None:
            b = e.nav_error
            stats = recorder.error_window(b.metric, b.after_s, b.until_s).as_dict()
            v = stats[b.stat]
            window = f"t >= {b.after_s:g} s" + (f" and t <= {b.until_s:g} s" if b.until_s is not None else "")
            desc = f"{b.stat} {b.metric} <= {b.max:g} for {window}"
            out.append(ExpectationResult(i, "nav_error", desc, v, v is not None and abs(v) <= b.max))
        elif e.link is not None:
            lb = e.link
            links = summary.get("links", {})
            if lb.name not in links:
                out.append(ExpectationResult(i, "link", f"link {lb.name!r} exists", None, False))
                continue
            v = links[lb.name][lb.counter]
            ok = (lb.min is None or v >= lb.min) and (lb.max is None or v <= lb.max)
            rng = " and ".join(x for x in (f">= {lb.min}" if lb.min is not None else "",
                                           f"<= {lb.max}" if lb.max is not None else "") if x)
            out.append(ExpectationResult(i, "link", f"{lb.name}.{lb.counter} {rng or '(any)'}", v, ok))
        elif e.dsp is not None:
            db = e.dsp
            v = summary.get("dsp", {}).get(db.field)
            out.append(ExpectationResult(i, "dsp", f"dsp.{db.field} <= {db.max:g}", v, v is not None and v <= db.max))
    return out
