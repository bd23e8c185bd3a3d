"""Build the emulated system from a scenario and run it: the assembly's public names in one place.

The assembly is split by concern: :mod:`.ports` (the port table, time mode, stream formats),
:mod:`~emulator.assembly.build` (scenario -> UARTs, FPGA configuration, virtual DSP, port map), :mod:`.session`
(:class:`Emulator`, the run and its signal handling) and :mod:`.summary` (1 Hz samples, summary sections).
This module re-exports them for the callers that import ``emulator.assembly.runner``.
"""

from __future__ import annotations

from .ports import EMIFA_BYTE_TIME_S, UART_NUM, PortInfo, dsp_uart_baud, port_formats, real_time_ports, resolve_mode
from .session import Emulator, default_run_dir, run_emulator, run_scenario

__all__ = ["EMIFA_BYTE_TIME_S", "UART_NUM", "Emulator", "PortInfo", "default_run_dir", "dsp_uart_baud",
           "port_formats", "real_time_ports", "resolve_mode", "run_emulator", "run_scenario"]
