"""The tasks of the firmware's cyclic executive, one module per concept.

:class:`firmware_model.firmware.Firmware` (the cyclic executive) owns the decoders and the tick order and calls
these tasks. :class:`~.timekeeping.Clock` and :class:`~.gnss.GnssTask` are task objects with their own state and
explicit collaborators (config, the counter table, the clock), used through their public methods only
(tests/firmware_model/test_task_boundaries.py); the others are still mixins of ``Firmware`` over the state declared
in :class:`~.state.LoopState` (issue 42 item 3, in progress):

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
