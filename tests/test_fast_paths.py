"""Every fast path against its reference, in one parametrized test.

A fast path lives next to its reference in the same module and is named ``<name>_fast`` beside ``<name>``. Each
package's test folder lists its pairs in ``fast_path_cases.py`` as ``CASES``: ``pytest.param(reference, fast,
inputs)``, where ``inputs`` is a list of argument tuples. Results must be equal (``==``, or ``numpy.array_equal``
for arrays, bit for bit: ``equal_nan`` only where both sides give NaN).
"""

from __future__ import annotations

import importlib
from typing import Any

import numpy as np
import pytest

PACKAGES = ("protocols", "firmware_model", "emulator")


def _cases() -> list[Any]:
    cases = []
    for package in PACKAGES:
        module = importlib.import_module(f"tests.{package}.fast_path_cases")
        cases.extend(module.CASES)
    return cases


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        return a.dtype == b.dtype and a.shape == b.shape and np.array_equal(a, b, equal_nan=a.dtype.kind == "f")
    if isinstance(a, (tuple, list)) and isinstance(b, (tuple, list)):
        return type(a) is type(b) and len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    return bool(a == b)


CASES = _cases()


@pytest.mark.parametrize(("reference", "fast", "inputs"), CASES)
def test_fast_path_equals_its_reference(reference, fast, inputs):
    assert inputs, "a pair needs at least one input"
    for args in inputs:
        assert _same(reference(*args), fast(*args)), args
