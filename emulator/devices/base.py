"""Shared pieces of the emulated devices: seeded randomness and the event sink."""

from __future__ import annotations

import zlib
from typing import Any, Protocol

import numpy as np

__all__ = ["EventSink", "NullEvents", "device_rng"]


class EventSink(Protocol):
    """Receives device events (faults, mode switches, deadline misses, ...)."""

    def emit(self, t: float, source: str, kind: str, /, **data: Any) -> None: ...


class NullEvents:
    """An :class:`EventSink` that drops everything."""

    def emit(self, t: float, source: str, kind: str, /, **data: Any) -> None:
        return None


def device_rng(seed: int, name: str) -> np.random.Generator:
    """Independent, reproducible generator for device ``name`` under scenario ``seed``.

    Streams are keyed by a stable hash of the name, so adding a device does not change the
    random numbers of the others.
    """
    return np.random.default_rng([seed & 0xFFFFFFFF, zlib.crc32(name.encode("utf-8"))])
