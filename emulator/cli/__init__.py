"""The ``psns-hil`` command (:func:`main`) and its tools (monitor)."""

from .main import main

__all__ = ["main"]
