"""Firmware-model errors; the whole tree is drawn in :mod:`protocols.errors`."""

from __future__ import annotations

from protocols.errors import PsnsHilError

__all__ = ["FirmwareError"]


class FirmwareError(PsnsHilError):
    """Bad firmware configuration (never raised for bad input bytes)."""
