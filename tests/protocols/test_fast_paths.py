"""Every fast path of ``protocols`` returns what its reference returns (``fast_path_cases.CASES``)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from tests.protocols.fast_path_cases import CASES


def _equal(a: Any, b: Any) -> bool:
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return bool(np.array_equal(a, b))
    return bool(a == b)


@pytest.mark.parametrize(("reference", "fast", "inputs"), CASES)
def test_fast_path_matches_its_reference(reference, fast, inputs):
    assert inputs
    for args in inputs:
        assert _equal(reference(*args), fast(*args)), args
