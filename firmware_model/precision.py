"""Working-precision arithmetic on Python floats: round a few values to float32 (or leave float64).

The per-tick kernels work on 3-vectors; a numpy operation on a 3-element array costs about 0.3-0.4 us
in Python, ten times the arithmetic. The firmware's hot paths therefore compute on Python floats
(IEEE double) and round every intermediate result to the working precision with the ``struct`` from
:func:`rounder`: ``r.unpack(r.pack(...))`` packs several doubles into C ``float`` and unpacks them again
(round to nearest even; one pair of calls for up to six values).

Why this is *exactly* float32 arithmetic (bit for bit what numpy's float32 operations give), when
every operand is already a float32 value and each double result is rounded before it is used again:

* ``a * b``: the product of two 24-bit significands has at most 48 bits and is exact in double
  (53 bits), so rounding it to float32 is the correctly rounded float32 product;
* ``a + b``, ``a - b``, ``a / b``, ``sqrt(a)``: double has more than ``2 * 24 + 2`` significand bits, so
  rounding the correctly rounded double result again to float32 gives the correctly rounded float32
  result (double rounding is innocuous; Figueroa, "When is double rounding innocuous?", SIGNUM 1995);
* multiplying by 0.5 is exact in both precisions (no subnormals occur in these kernels).

Range is not an issue: the kernels' values are far inside float32's exponent range. In float64 the
struct packs C ``double``: the values come back unchanged (the same double operations as numpy float64).
``tests/firmware_model/test_precision.py`` checks the rounding against numpy float32 operations.
"""

from __future__ import annotations

import struct

import numpy as np

from .arrays import FloatDtype

__all__ = ["rounder"]


def rounder(dtype: FloatDtype, n: int) -> struct.Struct:
    """A ``struct.Struct`` of ``n`` C values of the working precision ``dtype`` (``float`` or ``double``).

    ``r.unpack(r.pack(x1, ..., xn))`` rounds each value to ``dtype`` and gives Python floats back (float32
    values are exactly representable in double); for float64 it returns the values unchanged. Callers use the
    Struct directly: a Python wrapper function would cost as much as the packing.
    """
    if np.dtype(dtype) == np.float64:
        return struct.Struct(f"<{n}d")
    if np.dtype(dtype) != np.float32:
        raise ValueError(f"working precision must be float32 or float64, got {dtype!r}")
    return struct.Struct(f"<{n}f")
