"""The tasks of the firmware's cyclic executive, one module per concept.

:class:`firmware_model.firmware.Firmware` (the loop) is composed of these task classes; each holds the
methods of one task and reads and writes the loop's state declared once in :class:`~.state.LoopState`:

==========================  ====================================================================
:mod:`.state`               mode-manager states, ``TickResult``, the loop's shared state
:mod:`.timekeeping`         FPGA time base (32-bit unwrap), PPS, UTC from GNSS (:class:`Clock`, a task object)
:mod:`.gnss`                GNSS staging: NMEA GGA/RMC and UBX NAV-PVT to a pending measurement
:mod:`.navigation`          bias compensation, coning/sculling, strapdown, INS history, MAG history
:mod:`.psns`                PSNS staging: exposure time, solve, body frame, solar-vector update
:mod:`.alignment`           coarse alignment glue (levelling, TRIAD heading, restart)
:mod:`.output`              NAV_SOLUTION and the CPU load it reports
:mod:`.host`                host commands, acknowledgements, STATUS
==========================  ====================================================================
"""

from __future__ import annotations
