"""The tasks of the firmware's cyclic executive, one module per concept.

:class:`firmware_model.firmware.Firmware` (the cyclic executive, no base class) owns the decoders and the tick order,
builds these task objects and hands each its collaborators explicitly: the config, the cycle meter, the counter
table, the :class:`~.timekeeping.Clock`, the :class:`~.navigation.NavCore` (navigation state, filter, INS history)
and the :class:`~.state.LoopStatus` record (mode manager, aiding times). Each task owns its state and is used
through its public methods only; no task reads another's attributes (tests/firmware_model/test_task_boundaries.py,
issue 42 item 3):

==========================  ====================================================================
:mod:`.state`               mode-manager states, ``TickResult``, ``LoopStatus``, ``CpuLoad``
:mod:`.timekeeping`         FPGA time base (32-bit unwrap), PPS, UTC from GNSS (:class:`Clock`)
:mod:`.navigation`          bias compensation, coning/sculling, strapdown, time update, INS and MAG history
                            (:class:`NavCore`, the filters' ``FilterHost``)
:mod:`.gnss`                GNSS staging: NMEA GGA/RMC and UBX NAV-PVT to a pending measurement (:class:`GnssTask`)
:mod:`.psns`                PSNS: exposure time, solve, body frame, solar-vector update (:class:`PsnsTask`)
:mod:`.alignment`           coarse alignment (levelling, TRIAD heading, restart; :class:`AlignmentTask`)
:mod:`.output`              NAV_SOLUTION, ``$PSNS`` text and NMEA output (:class:`OutputTask`)
:mod:`.host`                host commands, acknowledgements, STATUS (:class:`HostTask`)
==========================  ====================================================================
"""

from __future__ import annotations
