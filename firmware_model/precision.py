"""Working-precision arithmetic on Python floats: round a few values to float32 (or leave float64).

The per-tick kernels work on 3-vectors; a numpy operation on a 3-element array costs about 0.3-0.4 us
in Python, ten times the arithmetic. The firmware's hot paths therefore compute on Python floats
(IEEE double) and round every intermediate result to the working precision with :func:`rounder`:
``struct`` packs several doubles into C ``float`` and unpacks them again (round to nearest even, one
call for up to six values).

Why this is *exactly* float32 arithmetic (bit for bit what numpy's float32 operations give), when
every operand is already a float32 value and each double result is rounded before it is used again:

* ``a * b``: the product of two 24-bit significands has at most 48 bits and is exact in double
  (53 bits), so rounding it to float32 is the correctly rounded float32 product;
* ``a + b``, ``a - b``, ``a / b``, ``sqrt(a)``: double has more than ``2 * 24 + 2`` significand bits, so
  rounding the correctly rounded double result again to float32 gives the correctly rounded float32
  result (double rounding is innocuous; Figueroa, "When is double rounding innocuous?", SIGNUM 1995);
* multiplying by 0.5 is exact in both precisions (no subnormals occur in these kernels).

Range is not an issue: the kernels' values are far inside float32's exponent range. In float64 the
rounder returns its arguments (no rounding, the same double operations as numpy float64).
``tests/firmware_model/test_precision.py`` checks the rounding against numpy float32 operations.
"""

from __future__ import annotations

import struct
from typing import Callable

import numpy as np

__all__ = ["rounder"]


def _identity(*xs: float) -> tuple[float, ...]:
    return xs


def rounder(dtype: type, n: int) -> Callable[..., tuple[float, ...]]:
    """``f(x1, ..., xn) -> (x1', ..., xn')``, each value rounded to ``dtype`` (float32 or float64).

    The values come back as Python floats (float32 values are exactly representable in double).
    """
    if np.dtype(dtype) == np.float64:
        return _identity
    if np.dtype(dtype) != np.float32:
        raise ValueError(f"working precision must be float32 or float64, got {dtype!r}")
    s = struct.Struct(f"<{n}f")
    pack, unpack = s.pack, s.unpack

    def round_f32(*xs: float) -> tuple[float, ...]:
        return unpack(pack(*xs))

    return round_f32
