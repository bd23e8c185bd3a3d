"""Recording: what a run leaves behind and what is made of it.

:mod:`.recorder` (the run directory's listener), :mod:`.capture` (the capture file), :mod:`.nav_error`
(navigation output against truth), :mod:`.counting` (the recorder's counting decoders), :mod:`.formatting`
(CSV rows and JSON values), :mod:`.golden` (the change indicator), :mod:`.report` (``report.html``),
:mod:`.replay` (the firmware re-run on a capture).
"""
