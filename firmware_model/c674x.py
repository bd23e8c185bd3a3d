"""C674x cycle-cost model and per-task cycle meter.

Every kernel the firmware runs charges cycles from published TI figures
(``docs/reference/c674x-cycles.md``):

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
from typing import ClassVar

__all__ = [
    "CALL_OVERHEAD",
    "COST_MODEL_VERSION",
    "MATHLIB_DP_INLINE",
    "MATHLIB_SP_INLINE",
    "CycleMeter",
    "KernelCosts",
    "TaskMeter",
    "dotprod",
    "dp_flops",
    "flops",
    "mat_mul",
    "mat_mul_dp",
    "mat_trans",
    "mathlib",
    "nmea_sentence",
    "vecmul",
    "w_vec",
    "w_vec_dp",
]

COST_MODEL_VERSION = "c674x-costs-2 (DSPLIB 3.4.0.0, MATHLIB 3.1.2.1 inline, on-chip memory)"

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


#: Cycles per character of an ASCII sentence built by integer code [D]: one decimal digit per character at most,
#: each a division by 10 done as a 32x32 multiply-high by the reciprocal plus a multiply-subtract (MPY32 is 4
#: cycles of latency, issued back to back on two .M units: ~2 cycles/digit), the XOR into the NMEA checksum and
#: the byte store (1 cycle each on .L/.D), and the loop's branch amortised: ~4 cycles per character.
NMEA_CYCLES_PER_CHAR = 4


def nmea_sentence(n_chars: int, n_scaled: int) -> int:
    """One NMEA 0183 sentence of ``n_chars`` characters formatted by integer code, with ``n_scaled`` values first
    scaled from double precision to integer counts (a DP multiply, a DP add for rounding and DPINT each) [D]."""
    return n_chars * NMEA_CYCLES_PER_CHAR + dp_flops(n_scaled, n_scaled) + CALL_OVERHEAD


def dp_flops(n_mul: int, n_add: int, iterations: int = 1, overhead: int = CALL_OVERHEAD) -> int:
    """Double-precision code: MPYDP occupies .M for 4 cycles (2 units), ADDDP .L/.S for 2 (4 units) [S]."""
    ii = max(math.ceil(n_mul * 4 / 2), math.ceil(n_add * 2 / 4), 1)
    return iterations * ii + overhead


def mat_mul_dp(r1: int, c1: int, c2: int) -> int:
    """Double-precision matrix product (no C674x DSPLIB kernel: the same loop nest with MPYDP) [D].

    The single-precision leading term ``1/2 r1 c2 c1`` is 2 MACs per cycle on the two .M units.
    MPYDP occupies its .M unit for 4 cycles (2 DP multiplies every 4 clocks, section 1 [S]), so the
    inner product runs at 0.5 MAC per cycle: ``2 r1 c2 c1``; the other terms as DSPF_sp_mat_mul, with
    loads doubled (``12 r1 c2``).
    """
    r1, c2 = _even(max(r1, 2)), _even(max(c2, 2))
    c1 = max(c1, 2)
    return math.ceil(2.0 * r1 * c2 * c1 + 12 * r1 * c2 + 4.5 * r1 + 41)


def w_vec_dp(n: int) -> int:
    """Double-precision ``y = m x1 + x2``: one MPYDP per element bounds it, 2 cycles/element (2 .M) [D]."""
    return 2 * n + 38


class KernelCosts:
    """Cycle costs of the firmware's kernels in one working precision (``"float32"`` or ``"float64"``).

    The firmware's float32 build uses DSPLIB ``DSPF_sp_*`` and MATHLIB ``*sp`` inline figures; the
    float64 build (the reference build used to check float32 accuracy) pays the C674x's double-precision
    price: MATHLIB ``*dp`` inline figures [S, R2], MPYDP/ADDDP throughput for straight-line code
    (:func:`dp_flops`) and :func:`mat_mul_dp` for matrix products. Carelessly written double precision
    therefore shows in the budget.
    """

    _SP: ClassVar[dict[str, str]] = {"sin": "sinsp", "cos": "cossp", "atan2": "atan2sp", "asin": "asinsp",
                                     "acos": "acossp", "sqrt": "sqrtsp", "rsqrt": "rsqrtsp", "div": "divsp",
                                     "recip": "recipsp"}
    _DP: ClassVar[dict[str, str]] = {"sin": "sindp", "cos": "cosdp", "atan2": "atan2dp", "asin": "asindp",
                                     "acos": "acosdp", "sqrt": "sqrtdp", "rsqrt": "rsqrtdp", "div": "divdp",
                                     "recip": "recipdp"}

    def __init__(self, precision: str = "float32") -> None:
        if precision not in ("float32", "float64"):
            raise ValueError(f"precision must be float32 or float64, got {precision!r}")
        self.precision = precision
        self.double = precision == "float64"
        self._names = self._DP if self.double else self._SP

    def math(self, fn: str, n: int = 1) -> int:
        """``n`` inline MATHLIB calls of ``fn`` (sin, cos, atan2, asin, acos, sqrt, rsqrt, div, recip)."""
        return mathlib(self._names[fn], n)

    def flops(self, n_mul: int, n_add: int, iterations: int = 1, overhead: int = CALL_OVERHEAD) -> int:
        f = dp_flops if self.double else flops
        return f(n_mul, n_add, iterations, overhead)

    def mat_mul(self, r1: int, c1: int, c2: int) -> int:
        return mat_mul_dp(r1, c1, c2) if self.double else mat_mul(r1, c1, c2)

    def mat_trans(self, rows: int, cols: int) -> int:
        """Transposes move twice the bytes in double precision [D]."""
        return mat_trans(rows, cols) + (math.ceil(0.5 * rows * cols) if self.double else 0)

    def w_vec(self, n: int) -> int:
        return w_vec_dp(n) if self.double else w_vec(n)


@dataclass
class TaskMeter:
    """Cycle statistics of one firmware task, TI-report style (docs/reference/c674x-cycles.md section 5).

    ``budget_cycles`` is the tick budget (every task of the cyclic executive must fit in one
    200 Hz tick); ``period_s`` is the task's nominal period (for the average CPU share).
    """

    name: str
    budget_cycles: int
    period_s: float = 0.0
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

    @property
    def utilization_avg_pct(self) -> float:
        return 100.0 * self.cycles_avg / self.budget_cycles if self.budget_cycles else 0.0

    def as_dict(self) -> dict[str, object]:
        return {
            "task": self.name,
            "calls": self.calls,
            "period_s": self.period_s,
            "cycles_last": self.cycles_last,
            "cycles_min": self.cycles_min,
            "cycles_avg": round(self.cycles_avg, 1),
            "cycles_max": self.cycles_max,
            "budget_cycles": self.budget_cycles,
            "utilization_avg_pct": round(self.utilization_avg_pct, 4),
            "utilization_max_pct": round(self.utilization_max_pct, 4),
            "kernels": dict(self.kernels),
        }


class CycleMeter:
    """Accumulates charged cycles per task and per kernel, like a TSC-instrumented firmware.

    Tasks nest: the cyclic executive opens ``begin("imu_tick")`` for the whole 200 Hz tick and each
    task inside it opens its own ``begin("imu")`` ... ``end()``. A kernel's cycles
    (``charge("strapdown", n)``) count for the innermost open task (its kernel breakdown) and for
    every enclosing task (their totals). ``end()`` returns the cycles of the task it closes.
    :attr:`elapsed` is the cycle count since the outermost task began (the TSC read at an output).
    """

    def __init__(self, clock_hz: float, tick_hz: float) -> None:
        self.clock_hz = clock_hz
        self.tick_hz = tick_hz
        self.tick_budget = round(clock_hz / tick_hz)
        self.tasks: dict[str, TaskMeter] = {}
        self._stack: list[tuple[TaskMeter, int]] = []
        self._acc = 0
        #: kernel breakdown of the innermost open task (None: no task open); saves a stack lookup per charge
        self._kernels: dict[str, int] | None = None

    @property
    def elapsed(self) -> int:
        """Cycles charged since the outermost open task began."""
        return self._acc

    def begin(self, task: str, period_s: float = 0.0) -> None:
        t = self.tasks.get(task)
        if t is None:
            t = self.tasks[task] = TaskMeter(task, self.tick_budget, period_s)
        stack = self._stack
        if not stack:
            self._acc = 0
        stack.append((t, self._acc))
        self._kernels = t.kernels

    def charge(self, kernel: str, cycles: int) -> None:
        self._acc += cycles
        k = self._kernels
        if k is not None:
            k[kernel] = k.get(kernel, 0) + cycles

    def end(self) -> int:
        stack = self._stack
        if not stack:
            return 0
        t, start = stack.pop()
        n = self._acc - start
        calls = t.calls = t.calls + 1
        t.cycles_last = n
        t.cycles_total += n
        if calls == 1:
            t.cycles_min = t.cycles_max = n
        elif n > t.cycles_max:
            t.cycles_max = n
        elif n < t.cycles_min:
            t.cycles_min = n
        if stack:
            self._kernels = stack[-1][0].kernels
        else:
            self._acc = 0
            self._kernels = None
        return n

    def table(self) -> list[dict[str, object]]:
        """One row per task (TI test-report layout: calls, min/avg/max cycles, budget, utilisation)."""
        return [t.as_dict() for t in self.tasks.values()]

    def format_table(self) -> str:
        """The table as text, the way a TSC log summary is printed on a board's console."""
        lines = [f"C674x @ {self.clock_hz / 1e6:.0f} MHz, tick budget {self.tick_budget} cycles ({COST_MODEL_VERSION})",
                 f"{'task':<16}{'calls':>9}{'min':>10}{'avg':>10}{'max':>10}{'avg %':>9}{'max %':>9}"]
        for t in self.tasks.values():
            lines.append(f"{t.name:<16}{t.calls:>9}{t.cycles_min:>10}{t.cycles_avg:>10.0f}{t.cycles_max:>10}"
                         f"{t.utilization_avg_pct:>9.3f}{t.utilization_max_pct:>9.3f}")
            for k, v in sorted(t.kernels.items(), key=lambda kv: -kv[1]):
                lines.append(f"  {k:<14}{'':>9}{'':>10}{v / max(t.calls, 1):>10.0f}")
        return "\n".join(lines)
