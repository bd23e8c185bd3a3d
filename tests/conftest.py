"""Shared fixtures. Tests are deterministic: seeded randomness, emulator-clock timeouts."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

# The firmware contains an exception raised while handling one input message (counted, reported: hostile input
# must not end a run, docs/hostile-input.md); the emulator's own tests make such an exception fail loudly instead.
os.environ.setdefault("PSNS_HIL_STRICT", "1")
# The repository's own scenarios and tests are trusted: their Python expectation hooks may run (``--allow-hooks``).
os.environ.setdefault("PSNS_HIL_ALLOW_HOOKS", "1")

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
