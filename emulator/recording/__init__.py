"""Recording: what a run leaves behind, written while it runs (below the assembly that wires it in).

:mod:`.recorder` (the run directory's listener), :mod:`.capture` (the capture file), :mod:`.nav_error`
(navigation output against truth), :mod:`.counting` (the recorder's counting decoders), :mod:`.formatting`
(CSV rows and JSON values), and the run directory's exports (:mod:`.mcap_out`, :mod:`.live`, :mod:`.tracks`,
:mod:`.sensor_tables`). What is made of a run afterwards (golden, replay, report) is :mod:`emulator.postrun`.
"""
