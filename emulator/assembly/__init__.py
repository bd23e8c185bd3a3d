"""Assembly: a scenario turned into links, devices, world and firmware, and the run session.

:mod:`.ports` (the port table), :mod:`.build` (scenario -> UARTs, FPGA, DSP, port map), :mod:`.session`
(:class:`Emulator`, :func:`run_scenario`, signal handling), :mod:`.summary` (samples and summary sections).
Callers import the module that declares a name (``from emulator.assembly.session import run_scenario``).
"""
