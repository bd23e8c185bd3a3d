"""The DSP firmware as a pure, synchronous model (numpy only; no asyncio, no emulator).

This is the code a firmware team would port to C for the TMS320C6747: kernels over numpy
arrays with their units, frames and the source paper's equation numbers in the docstrings,
and their C674x cycle costs charged through :mod:`firmware_model.c674x`. ``docs/firmware.md``
describes the tasks, kernels, equations and the cycle budget.
"""

from __future__ import annotations

from .config import FILTER_VARIANTS, UART_GNSS, UART_HOST, UART_IMU, UART_PSNS, FirmwareConfig
from .errors import FirmwareError
from .filters.base import BaseFilter
from .filters.interface import NavFilter, register_filter
from .firmware import Firmware
from .tasks.state import FirmwareState, TickResult

__all__ = [
    "FILTER_VARIANTS",
    "UART_GNSS",
    "UART_HOST",
    "UART_IMU",
    "UART_PSNS",
    "BaseFilter",
    "Firmware",
    "FirmwareConfig",
    "FirmwareError",
    "FirmwareState",
    "NavFilter",
    "TickResult",
    "register_filter",
]
