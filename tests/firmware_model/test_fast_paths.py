"""Every fast path of the firmware model gives bit for bit its reference's result (fast_path_cases.CASES)."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import pytest

from tests.firmware_model.fast_path_cases import CASES


@pytest.mark.parametrize(("reference", "fast", "inputs"), CASES)
def test_fast_path_is_bit_identical_to_its_reference(reference: Callable[..., Any], fast: Callable[..., Any],
                                                     inputs: list[tuple[Any, ...]]) -> None:
    assert inputs
    for args in inputs:
        assert fast(*args) == reference(*args), args
