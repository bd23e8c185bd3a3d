"""The mode manager shared by the variants: which measurements are admitted, and why.

Every variant routes each measurement through :meth:`ModeManager.decide` (validity: DOP, sun
elevation, geometry, age, frame status) and/or :meth:`ModeManager.gate` (chi-square innovation test,
docs/reference/algorithms.md 5.2) before it touches a Kalman filter, and reports its mode switches through
:meth:`ModeManager.set_mode` and per-sensor qualities through :meth:`ModeManager.report`. The manager
turns these decisions into events (``TickResult.events``; the DSP writes them to ``events.jsonl`` with
source ``firmware``) and counters.

Event policy: a decision is logged when it *changes* for its channel (admitted <-> rejected, or the
reason changes); the event carries how many identical decisions preceded it (``repeats``), so a run of
5 Hz rejections is one event, not 150, and no decision goes unaccounted. Mode and quality reports are
logged when their value changes. Event names (the scenario expectations match on them):

* ``measurement_admitted`` / ``measurement_rejected``: ``channel``, ``reason``, ``repeats`` and the
  numbers behind the decision (``nis``, ``threshold``, ``dof``, ``dop``, ``lambda``...);
* the variant's own names through :meth:`set_mode` / :meth:`report` (``psns_mode``, ``psns_quality``,
  ``gnss_isolated``, ``gnss_readmitted``, ``federated_mode``, ``kmeans_refused``...), each with ``reason``.

Every event also has ``t_fpga_s`` (FPGA time of the tick) and ``variant``. ``docs/variants.md`` lists
them all.
"""

from __future__ import annotations

from typing import Any

from .common import chi2_threshold
from .params import ModeManagerParams

__all__ = ["ModeManager"]


def _clean(v: Any) -> Any:
    """JSON-friendly scalars (numpy scalars -> Python, floats rounded to 6 significant digits)."""
    if isinstance(v, (list, tuple)):
        return [_clean(x) for x in v]
    if hasattr(v, "item"):
        v = v.item()
    if isinstance(v, float):
        return float(f"{v:.6g}")
    return v


class ModeManager:
    """Admission decisions and mode reports of one variant instance (see module docstring)."""

    def __init__(self, variant: str, params: ModeManagerParams | None = None) -> None:
        self.variant = variant
        self.params = params or ModeManagerParams()
        self.events: list[dict[str, Any]] = []
        self.counters: dict[str, int] = {}
        self._decision: dict[str, list[Any]] = {}  # channel -> [(admitted, reason), repeats]
        self._modes: dict[str, Any] = {}

    # -- admission -----------------------------------------------------------------------------
    def decide(self, t: float, channel: str, admitted: bool, reason: str, **fields: Any) -> bool:
        """Record one admission decision for ``channel``; an event when it differs from the previous one."""
        key = f"{channel}_{'admitted' if admitted else 'rejected'}"
        self.counters[key] = self.counters.get(key, 0) + 1
        prev = self._decision.get(channel)
        state = (admitted, reason)
        if prev is not None and prev[0] == state:
            prev[1] += 1
            return admitted
        ev = {"event": "measurement_admitted" if admitted else "measurement_rejected", "t_fpga_s": t,
              "variant": self.variant, "channel": channel, "reason": reason,
              "repeats": prev[1] if prev is not None else 0}
        ev.update({k: _clean(v) for k, v in fields.items()})
        self.events.append(ev)
        self._decision[channel] = [state, 1]
        return admitted

    def chi2_threshold(self, dof: int) -> float:
        return chi2_threshold(dof, self.params.chi2_alpha)

    def gate(self, t: float, channel: str, nis: float, dof: int, **fields: Any) -> bool:
        """Chi-square innovation test ``lambda = eps^T A^-1 eps <= chi2_{1-alpha}(dof)`` (docs/reference/algorithms.md
        5.2)."""
        thr = self.chi2_threshold(dof)
        ok = nis <= thr
        return self.decide(t, channel, ok, "chi2_pass" if ok else "chi2_fail", nis=nis, threshold=thr, dof=dof,
                           **fields)

    def last_decision(self, channel: str) -> tuple[bool, str] | None:
        d = self._decision.get(channel)
        return None if d is None else d[0]

    # -- modes and reports ---------------------------------------------------------------------
    def set_mode(self, t: float, event: str, value: Any, reason: str, **fields: Any) -> bool:
        """Report the value of a mode (``event`` names it); an event when it changes. Returns True on a change."""
        prev = self._modes.get(event, _UNSET)
        if prev == value:
            return False
        self._modes[event] = value
        ev = {"event": event, "t_fpga_s": t, "variant": self.variant, "mode": _clean(value), "reason": reason}
        if prev is not _UNSET:
            ev["previous"] = _clean(prev)
        ev.update({k: _clean(v) for k, v in fields.items()})
        self.events.append(ev)
        self.counters[f"{event}_changes"] = self.counters.get(f"{event}_changes", 0) + 1
        return True

    def report(self, t: float, event: str, value: Any, reason: str, **fields: Any) -> bool:
        """Same as :meth:`set_mode` (an event when ``value`` changes) for per-sensor qualities and similar."""
        return self.set_mode(t, event, value, reason, **fields)

    def event(self, t: float, event: str, reason: str, **fields: Any) -> None:
        """An event that is a decision by itself (isolation, readmission, refusal): always logged."""
        ev = {"event": event, "t_fpga_s": t, "variant": self.variant, "reason": reason}
        ev.update({k: _clean(v) for k, v in fields.items()})
        self.events.append(ev)
        self.counters[event] = self.counters.get(event, 0) + 1

    def drain(self) -> list[dict[str, Any]]:
        """Events since the last call (the main loop moves them into the tick's ``TickResult.events``)."""
        out, self.events = self.events, []
        return out


class _Unset:
    def __repr__(self) -> str:
        return "<unset>"


_UNSET = _Unset()
