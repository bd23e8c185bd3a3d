"""Equivalence cases of the firmware model's fast paths: ``<name>_fast`` against the reference ``<name>``.

``CASES`` is a list of ``pytest.param(reference, fast, inputs, id=...)``; ``inputs`` is a list of argument
tuples, and for every tuple ``fast(*args) == reference(*args)`` must hold exactly. The kernels work in place
(``strapdown_step*`` advance a ``NavState``) or return arrays, so each callable here is a thin wrapper that
builds its own state from the (immutable) arguments, runs the kernel and returns the result as bytes plus
dtypes: ``==`` is then bit equality, and running the reference first cannot change the fast path's input.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from firmware_model.attitude import a2mat, mat2q, q2mat, q2mat_fast
from firmware_model.nav_state import NavState
from firmware_model.strapdown import coning_sculling, coning_sculling_fast, strapdown_step, strapdown_step_fast
from protocols.constants import DEG

__all__ = ["CASES"]

T = 0.005

#: (pitch, roll, yaw deg; vE, vN, vU m/s; lat, lon deg, h m; a_prev ENU m/s^2)
_STATES = [
    ((2.0, -3.0, 28.6), (3.0, -2.0, 0.1), (40.1, 116.3, 50.0), (0.01, -0.02, 0.003)),
    ((0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)),
    ((-15.0, 30.0, -170.0), (-120.0, 250.0, -4.0), (-62.5, -70.0, 3200.0), (0.5, -1.2, 0.3)),
    ((80.0, -5.0, 91.0), (0.5, 0.5, 0.0), (75.0, 15.0, -20.0), (0.0, 0.0, 0.0)),
]


def _state(k: int, dtype: type[np.floating[Any]]) -> NavState:
    att, v, pos, a = _STATES[k]
    q = mat2q(a2mat(att[0] * DEG, att[1] * DEG, att[2] * DEG))
    return NavState(q.astype(dtype), np.array(v, dtype=dtype), np.array([pos[0] * DEG, pos[1] * DEG, pos[2]]),
                    0.0, np.array(a, dtype=dtype), np.zeros(3, dtype=dtype))


def _result(s: NavState) -> tuple[bytes, tuple[str, ...], float]:
    arrays = (s.q, s.v, s.pos, s.a_prev, s.f_n)
    return (np.array(s.as_floats()).tobytes(), tuple(a.dtype.name for a in arrays), s.t)


def _increments(seed: int, n: int, dtype: type[np.floating[Any]]) -> list[tuple[list[float], list[float]]]:
    """``n`` (phi_m, dv_m) pairs in ``dtype`` as Python floats; tiny rotations (rv2q's series branch) included."""
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        phi = rng.normal(0.0, 1e-9 if k % 3 == 0 else 1e-3, 3).astype(dtype)
        dv = (rng.normal(0.0, 1e-3, 3) + np.array([0.0, 0.0, 9.8 * T])).astype(dtype)
        out.append((phi.tolist(), dv.tolist()))
    return out


def _strapdown(step: Callable[..., NavState], arrays: bool) -> Callable[..., tuple[bytes, tuple[str, ...], float]]:
    def run(k: int, dtype_name: str, seed: int, n: int) -> tuple[bytes, tuple[str, ...], float]:
        dtype = np.dtype(dtype_name).type
        s = _state(k, dtype)
        for phi, dv in _increments(seed, n, dtype):
            if arrays:
                step(s, np.array(phi, dtype=dtype), np.array(dv, dtype=dtype), T, dtype)
            else:
                step(s, phi, dv, T, dtype)
        return _result(s)

    run.__name__ = f"{step.__name__}_run"
    return run


def _q2mat(fn: Callable[[np.ndarray], np.ndarray]) -> Callable[[tuple[float, ...], str], tuple[bytes, str]]:
    def run(q: tuple[float, ...], dtype_name: str) -> tuple[bytes, str]:
        c = fn(np.array(q, dtype=dtype_name))
        return c.tobytes(), c.dtype.name

    run.__name__ = f"{fn.__name__}_bytes"
    return run


def _quaternions(n: int) -> list[tuple[float, ...]]:
    rng = np.random.default_rng(5)
    qs = [tuple(q / np.linalg.norm(q)) for q in rng.normal(size=(n, 4))]
    return [(1.0, 0.0, 0.0, 0.0), (0.0, 1.0, 0.0, 0.0), *[tuple(float(x) for x in q) for q in qs]]


def _coning_ref(dtheta: tuple[float, ...], dv: tuple[float, ...], dtype_name: str) -> tuple[bytes, bytes, str]:
    dt = np.dtype(dtype_name)
    phi, dvm = coning_sculling(np.array([dtheta], dtype=dt), np.array([dv], dtype=dt))
    return phi.astype(dt).tobytes(), dvm.astype(dt).tobytes(), dvm.dtype.name


def _coning_fast(dtheta: tuple[float, ...], dv: tuple[float, ...], dtype_name: str) -> tuple[bytes, bytes, str]:
    dt = np.dtype(dtype_name)
    phi, dvm = coning_sculling_fast(dtheta, dv, dt.type)
    return np.array(phi, dtype=dt).tobytes(), np.array(dvm, dtype=dt).tobytes(), dt.name


def _coning_inputs() -> list[tuple[tuple[float, ...], tuple[float, ...], str]]:
    out = []
    for dtype_name in ("float64", "float32"):
        for phi, dv in _increments(60, 200, np.dtype(dtype_name).type):
            out.append((tuple(phi), tuple(dv), dtype_name))
    return out


CASES = [
    pytest.param(_strapdown(strapdown_step, True), _strapdown(strapdown_step_fast, False),
                 [(k, "float64", 10 + k, 1) for k in range(len(_STATES))]
                 + [(k, "float64", 20 + k, 400) for k in range(len(_STATES))],
                 id="strapdown_step_fast-float64"),
    pytest.param(_strapdown(strapdown_step, True), _strapdown(strapdown_step_fast, False),
                 [(k, "float32", 30 + k, 1) for k in range(len(_STATES))]
                 + [(k, "float32", 40 + k, 400) for k in range(len(_STATES))],
                 id="strapdown_step_fast-float32"),
    pytest.param(_coning_ref, _coning_fast, _coning_inputs(), id="coning_sculling_fast-single-sample"),
    pytest.param(_q2mat(q2mat), _q2mat(q2mat_fast),
                 [(q, dt) for q in _quaternions(50) for dt in ("float64", "float32")],
                 id="q2mat_fast"),
]
