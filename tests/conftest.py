"""Shared fixtures. Tests are deterministic: seeded randomness, emulator-clock timeouts."""

from __future__ import annotations

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
SCENARIOS = ROOT / "scenarios"
VECTORS = Path(__file__).resolve().parent / "vectors"


@pytest.fixture
def rng():
    import numpy as np

    return np.random.default_rng(12345)


@pytest.fixture
def quickstart_path() -> Path:
    return SCENARIOS / "quickstart.yaml"
