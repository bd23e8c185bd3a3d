"""C674x cycle costs of the Kalman filter's kernels: the time update, one scalar measurement update, the closed-loop
feedback (docs/reference/c674x-cycles.md sections 4 and 6).

Each function returns the cycles (int) of one call for ``n`` states on the :class:`~firmware_model.c674x.KernelCosts`
of the build's precision ([S]: from TI's published formulas, [D]: derived; docs/firmware.md "Cycle budget"); the
filters charge them on their :class:`~firmware_model.c674x.CycleMeter` (``kf_predict``, ``kf_update``,
``kf_feedback``). Shared by every filter that runs the error-state KF (the base filter, the federated sub-filters).
"""

from __future__ import annotations

from .. import c674x
from ..kf import N_STATES

__all__ = [
    "feedback_cycles",
    "kf_predict_cycles",
    "kf_scalar_update_cycles",
]


def kf_scalar_update_cycles(c: c674x.KernelCosts, n: int = N_STATES) -> int:
    """One scalar Joseph update over ``n`` states [D, docs/reference/c674x-cycles.md section 6 fallback].

    ``a = P h`` and ``c = B h`` (2 x n^2 MAC), ``B = P - K a^T`` (n^2 MAC),
    ``P' = B - c K^T + r K K^T`` (2 n^2 MAC), symmetrise (n(n-1)/2 ADD), one reciprocal (MATHLIB [S]).
    """
    n2 = n * n
    return (2 * c.flops(n2, n2) + c.flops(n2, n2) + c.flops(2 * n2, 2 * n2) + c.flops(0, n * (n - 1) // 2)
            + c.math("recip") + c.flops(2 * n, 2 * n))


def kf_predict_cycles(c: c674x.KernelCosts, n: int = N_STATES) -> int:
    """Time update [S formulas, D sum]: F elements (~40 MUL/ADD, DP sin/cos and 4 divisions of the
    latitude terms), ``Phi = I + F T`` (DSPF_sp_w_vec, n^2), ``Phi P`` and ``(Phi P) Phi^T``
    (2 x DSPF_sp_mat_mul n x n x n), one transpose (DSPF_sp_mat_trans), Q on the diagonal, symmetrise."""
    return (c.flops(40, 40) + c674x.mathlib("divdp", 4) + c674x.mathlib("sindp") + c674x.mathlib("cosdp")
            + c.w_vec(n * n) + 2 * c.mat_mul(n, n, n) + c.mat_trans(n, n) + c.flops(0, n)
            + c.flops(0, n * (n - 1) // 2))


def feedback_cycles(c: c674x.KernelCosts) -> int:
    """Closed-loop feedback: rv2q (sqrt, sin, cos, div), qmul (16 MUL, 12 ADD), normalise (rsqrt),
    3 DP position subtractions, 9 additions [S/D]."""
    return (c.math("sqrt") + c.math("sin") + c.math("cos") + c.math("div") + c.math("rsqrt")
            + c.flops(20, 24) + c674x.dp_flops(0, 3))
