"""The navigation state of the mechanization (:class:`NavState`) and the layout of its 16 floats, named once.

``NavState.as_floats()`` is the state as 16 Python floats; the strapdown fast path, the INS history and the
output read them by the names below, never by bare position::

    index  0..3       4..6        7..9            10..12       13..15
           Q          V           POS             A_PREV       F_N
           q0 q1 q2 q3 vE vN vU    L lambda h     a_prev ENU   f^n ENU
                      VE VN VU    LAT LON HGT                  FE FN FU

Units: ``q = q_b^n`` (scalar first), ``v`` ENU m/s, ``L``/``lambda`` rad, ``h`` m, ``a_prev`` and ``f^n`` m/s^2.
"""

from __future__ import annotations

import numpy as np

from .arrays import FloatArray, FloatDtype

__all__ = [
    "A_PREV",
    "FE",
    "FN",
    "FU",
    "F_N",
    "HGT",
    "LAT",
    "LON",
    "N_NAV_FLOATS",
    "POS",
    "VE",
    "VN",
    "VU",
    "NavFloats",
    "NavState",
    "Q",
    "V",
]

#: ``NavState.as_floats()``: the 16 values, layout above.
NavFloats = tuple[float, ...]
N_NAV_FLOATS = 16
#: slices of the groups
Q = slice(0, 4)
V = slice(4, 7)
POS = slice(7, 10)
A_PREV = slice(10, 13)
F_N = slice(13, 16)
#: single components
VE, VN, VU = 4, 5, 6
LAT, LON, HGT = 7, 8, 9
FE, FN, FU = 13, 14, 15

#: A state array of the working precision (float32 or float64).


def _array_property(name: str, part: slice, doc: str) -> property:
    """A :class:`NavState` array attribute: the stored array, or built (read-only) from the floats."""
    slot = "_" + name
    is_pos = part == POS

    def get(self: NavState) -> FloatArray:
        a: FloatArray | None = getattr(self, slot)
        if a is None:  # float form (strapdown fast path): build the array once, read-only (D-10.F2)
            assert self._x is not None
            a = np.array(self._x[part], dtype=np.float64 if is_pos else self._xdt)
            a.flags.writeable = False
            setattr(self, slot, a)
        return a

    def set(self: NavState, value: FloatArray) -> None:
        if self._x is not None:
            self._to_arrays()
        setattr(self, slot, value)

    return property(get, set, doc=doc)


class NavState:
    """Navigation state of the mechanization.

    Attributes
    ----------
    q : (4,) quaternion ``q_b^n``, working precision.
    v : (3,) ENU velocity, m/s, working precision.
    pos : (3,) float64 ``[L rad, lambda rad, h m]``.
    t : float64 time of validity, s (FPGA time).
    a_prev : (3,) previous ENU acceleration used for mid-interval extrapolation, m/s^2.
    f_n : (3,) specific force in n of the last step, m/s^2 (for the KF's F matrix).

    Notes
    -----
    Storage: writers assign new arrays, never write into them (docs/decisions/performance.md D-10.F2). The strapdown
    fast path (:func:`firmware_model.strapdown.strapdown_step_fast`) keeps the state as 16 Python floats
    (:meth:`as_floats`, layout in the module docstring) and builds an attribute's array, read-only, when it is
    first read (the filters read them a few times per second, the 200 Hz loop not at all): a step then creates
    no arrays. Assigning an attribute turns the state back into arrays.
    """

    __slots__ = ("_a_prev", "_f_n", "_pos", "_q", "_v", "_x", "_xdt", "t")

    def __init__(self, q: FloatArray, v: FloatArray, pos: FloatArray, t: float = 0.0,
                 a_prev: FloatArray | None = None, f_n: FloatArray | None = None) -> None:
        self._x: NavFloats | None = None
        self._xdt: FloatDtype = np.float64
        self._q: FloatArray | None = q
        self._v: FloatArray | None = v
        self._pos: FloatArray | None = pos
        self._a_prev: FloatArray | None = np.zeros(3) if a_prev is None else a_prev
        self._f_n: FloatArray | None = np.zeros(3) if f_n is None else f_n
        self.t = t

    q = _array_property("q", Q, "(4,) quaternion ``q_b^n``")
    v = _array_property("v", V, "(3,) ENU velocity, m/s")
    pos = _array_property("pos", POS, "(3,) ``[L rad, lambda rad, h m]``, float64")
    a_prev = _array_property("a_prev", A_PREV, "(3,) previous ENU acceleration, m/s^2")
    f_n = _array_property("f_n", F_N, "(3,) specific force in n of the last step, m/s^2")

    def as_floats(self) -> NavFloats:
        """``(q0, q1, q2, q3, vE, vN, vU, L, lambda, h, a_prevE, a_prevN, a_prevU, f_nE, f_nN, f_nU)`` as
        Python floats (exact values of the arrays' elements; layout in the module docstring)."""
        x = self._x
        if x is None:
            x = tuple(self.q.tolist() + self.v.tolist() + self.pos.tolist() + self.a_prev.tolist()
                      + self.f_n.tolist())
        return x

    def _set_floats(self, x: NavFloats, dtype: FloatDtype = np.float64) -> None:
        """Float form: the 16 values of :meth:`as_floats`; arrays built on demand, ``pos`` in float64, the
        others in ``dtype`` (the values must be exactly representable in it)."""
        self._x = x
        self._xdt = dtype
        self._q = self._v = self._pos = self._a_prev = self._f_n = None

    def _to_arrays(self) -> None:
        for name in ("q", "v", "pos", "a_prev", "f_n"):
            getattr(self, name)  # builds the missing arrays from the floats
        self._x = None

    def copy(self) -> NavState:
        return NavState(self.q.copy(), self.v.copy(), self.pos.copy(), self.t, self.a_prev.copy(), self.f_n.copy())

    def __repr__(self) -> str:
        return (f"NavState(q={self.q!r}, v={self.v!r}, pos={self.pos!r}, t={self.t!r}, a_prev={self.a_prev!r}, "
                f"f_n={self.f_n!r})")
