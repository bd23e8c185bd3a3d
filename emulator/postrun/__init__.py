"""Post-run work: what is made of a run after it, above the assembly (one import-linter layer).

:mod:`.golden` (the change indicator: golden records of the library scenarios), :mod:`.replay` (the firmware
re-run on a capture, through the assembly's :class:`~emulator.assembly.session.Emulator`), :mod:`.report`
(``report.html`` of a run directory). They read what :mod:`emulator.recording` wrote; nothing below imports them.
"""
