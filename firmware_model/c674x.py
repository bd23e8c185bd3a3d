"""C674x cycle-cost model and per-task cycle meter.

Every kernel the firmware runs charges cycles from published TI figures
(``shared/reference/c6747_cycles.md``):

* DSPLIB C674x 3.4.0.0 test report (R1) cycle formulas, with odd-size padding for mat_mul;
* MATHLIB C674x 3.1.2.1 (R2) per-call cycles, "Inline" column for single precision
  (the firmware includes the ``_i.h`` headers) and for double precision;
* the fallback model of section 6 for straight-line code: ``max(ceil(mpy/2), ceil(add/4))``
  per software-pipelined iteration, plus call overhead.

Tags as in the reference: [S] stated in the source, [D] derived, [E] estimate.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

__all__ = [
    "COST_MODEL_VERSION",
    "MATHLIB_SP_INLINE",
    "MATHLIB_DP_INLINE",
    "CALL_OVERHEAD",
    "mat_mul",
    "mat_trans",
    "dotprod",
    "w_vec",
    "vecmul",
    "mathlib",
    "flops",
    "dp_flops",
    "TaskMeter",
    "CycleMeter",
]

COST_MODEL_VERSION = "c674x-costs-1 (DSPLIB 3.4.0.0, MATHLIB 3.1.2.1 inline, on-chip memory)"

#: MATHLIB single precision, Inline column, cycles per call [S, R2].
MATHLIB_SP_INLINE: dict[str, int] = {
    "sinsp": 72,
    "cossp": 76,
    "tansp": 103,
    "asinsp": 49,
    "acossp": 52,
    "atansp": 76,
    "atan2sp": 94,
    "sqrtsp": 48,
    "rsqrtsp": 40,
    "divsp": 36,
    "recipsp": 24,
    "expsp": 67,
    "logsp": 66,
    "powsp": 161,
}
#: MATHLIB double precision, Inline column, cycles per call [S, R2].
MATHLIB_DP_INLINE: dict[str, int] = {
    "sindp": 174,
    "cosdp": 182,
    "atan2dp": 530,
    "atandp": 339,
    "asindp": 164,
    "acosdp": 179,
    "sqrtdp": 161,
    "rsqrtdp": 118,
    "divdp": 100,
    "recipdp": 83,
    "expdp": 227,
    "logdp": 328,
    "powdp": 589,
}
#: Function-call overhead for non-library code, cycles [D: range of DSPLIB constant terms 25-60].
CALL_OVERHEAD = 40


def _even(n: int) -> int:
    return n + (n & 1)


def mat_mul(r1: int, c1: int, c2: int) -> int:
    """``DSPF_sp_mat_mul`` (r1 x c1 times c1 x c2): ``1/2 r1 c2 c1 + 6 r1 c2 + 4.5 r1 + 41`` [S, R1].

    Odd r1 or c2 are padded to the next even size (the kernel loads an extra row/column) [D].
    Sizes of 1 (not allowed by the kernel) are treated as 2.
    """
    r1, c2 = _even(max(r1, 2)), _even(max(c2, 2))
    c1 = max(c1, 2)
    return math.ceil(0.5 * r1 * c2 * c1 + 6 * r1 * c2 + 4.5 * r1 + 41)


def mat_trans(rows: int, cols: int) -> int:
    """``DSPF_sp_mat_trans``: ``1/2 R C + 4 R + 38`` [S, R1]."""
    return math.ceil(0.5 * rows * cols + 4 * rows + 38)


def dotprod(n: int) -> int:
    """``DSPF_sp_dotprod``: ``1/2 Nx + 57`` [S, R1]."""
    return math.ceil(0.5 * n + 57)


def w_vec(n: int) -> int:
    """``DSPF_sp_w_vec`` (y = m x1 + x2): ``Nx + 38`` [S, R1]."""
    return n + 38


def vecmul(n: int) -> int:
    """``DSPF_sp_vecmul``: ``3/4 Nx + 32`` [S, R1]."""
    return math.ceil(0.75 * n + 32)


def mathlib(name: str, n: int = 1) -> int:
    """Cycles of ``n`` inline MATHLIB calls (``sinsp``, ``atan2dp``, ...)."""
    if name in MATHLIB_SP_INLINE:
        return n * MATHLIB_SP_INLINE[name]
    if name in MATHLIB_DP_INLINE:
        return n * MATHLIB_DP_INLINE[name]
    raise KeyError(f"no MATHLIB figure for {name!r}")


def flops(n_mul: int, n_add: int, iterations: int = 1, overhead: int = CALL_OVERHEAD) -> int:
    """Fallback model (section 6) for single-precision straight-line or looped code [D/E].

    Per iteration ``max(ceil(mul/2), ceil(add/4))`` cycles (2 MPYSP and 4 ADDSP per cycle),
    never below the 4-cycle ADDSP recurrence for a single accumulator, plus a call overhead.
    """
    ii = max(math.ceil(n_mul / 2), math.ceil(n_add / 4), 1)
    return iterations * ii + overhead


def dp_flops(n_mul: int, n_add: int, iterations: int = 1, overhead: int = CALL_OVERHEAD) -> int:
    """Double-precision code: MPYDP occupies .M for 4 cycles (2 units), ADDDP .L/.S for 2 (4 units) [S]."""
    ii = max(math.ceil(n_mul * 4 / 2), math.ceil(n_add * 2 / 4), 1)
    return iterations * ii + overhead


@dataclass
class TaskMeter:
    """Cycle statistics of one firmware task, TI-report style."""

    name: str
    budget_cycles: int
    calls: int = 0
    cycles_last: int = 0
    cycles_min: int = 0
    cycles_max: int = 0
    cycles_total: int = 0
    kernels: dict[str, int] = field(default_factory=dict)

    @property
    def cycles_avg(self) -> float:
        return self.cycles_total / self.calls if self.calls else 0.0

    @property
    def utilization_max_pct(self) -> float:
        return 100.0 * self.cycles_max / self.budget_cycles if self.budget_cycles else 0.0

    def as_dict(self) -> dict[str, object]:
        return {
            "task": self.name,
            "calls": self.calls,
            "cycles_last": self.cycles_last,
            "cycles_min": self.cycles_min,
            "cycles_avg": round(self.cycles_avg, 1),
            "cycles_max": self.cycles_max,
            "budget_cycles": self.budget_cycles,
            "utilization_max_pct": round(self.utilization_max_pct, 3),
            "kernels": dict(self.kernels),
        }


class CycleMeter:
    """Accumulates charged cycles per task and per kernel.

    Usage: ``meter.begin("imu")``; kernels call ``meter.charge("strapdown", n)``;
    ``meter.end()`` returns the cycles of that task run.
    """

    def __init__(self, clock_hz: float, tick_hz: float) -> None:
        self.clock_hz = clock_hz
        self.tick_hz = tick_hz
        self.tick_budget = int(round(clock_hz / tick_hz))
        self.tasks: dict[str, TaskMeter] = {}
        self._current: TaskMeter | None = None
        self._acc = 0

    def begin(self, task: str) -> None:
        if task not in self.tasks:
            self.tasks[task] = TaskMeter(task, self.tick_budget)
        self._current = self.tasks[task]
        self._acc = 0

    def charge(self, kernel: str, cycles: int) -> None:
        self._acc += cycles
        if self._current is not None:
            k = self._current.kernels
            k[kernel] = k.get(kernel, 0) + cycles

    def end(self) -> int:
        t = self._current
        n = self._acc
        if t is not None:
            t.calls += 1
            t.cycles_last = n
            t.cycles_total += n
            t.cycles_max = max(t.cycles_max, n)
            t.cycles_min = n if t.calls == 1 else min(t.cycles_min, n)
        self._current = None
        self._acc = 0
        return n

    def table(self) -> list[dict[str, object]]:
        return [t.as_dict() for t in self.tasks.values()]
