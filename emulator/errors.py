"""Emulator-layer errors; the whole tree is drawn in :mod:`protocols.errors`."""

from __future__ import annotations

import errno

from protocols.errors import PsnsHilError

__all__ = [
    "STORAGE_ERRNOS",
    "EmulatorError",
    "LinkBrokenError",
    "LinkClosedError",
    "LinkConfigError",
    "LinkError",
    "LinkTimeoutError",
    "RecordingError",
    "ScenarioError",
    "ScenarioIssue",
    "StorageError",
    "WriterProcessError",
]


class EmulatorError(PsnsHilError):
    """Base of the emulator's errors."""


class ScenarioIssue:
    """One problem in a scenario file: where (file, line, column, field path) and what."""

    __slots__ = ("column", "file", "line", "message", "path")

    def __init__(self, file: str, line: int | None, column: int | None, path: str, message: str) -> None:
        self.file = file
        self.line = line
        self.column = column
        self.path = path
        self.message = message

    def __str__(self) -> str:
        where = self.file
        if self.line is not None:
            where += f":{self.line}"
            if self.column is not None:
                where += f":{self.column}"
        field = f" {self.path}:" if self.path else ""
        return f"{where}:{field} {self.message}"

    def __repr__(self) -> str:
        return f"ScenarioIssue({str(self)!r})"


class ScenarioError(EmulatorError):
    """A scenario that cannot be loaded; ``issues`` lists every problem found (all at once)."""

    def __init__(self, issues: list[ScenarioIssue] | ScenarioIssue | str, file: str = "<scenario>") -> None:
        if isinstance(issues, str):
            issues = [ScenarioIssue(file, None, None, "", issues)]
        elif isinstance(issues, ScenarioIssue):
            issues = [issues]
        self.issues = issues
        super().__init__("\n".join(str(i) for i in issues))


class LinkError(EmulatorError):
    """A link could not be opened or used."""


class LinkConfigError(LinkError, ValueError):
    """Bad link URL or option; the message shows the accepted form."""


class LinkClosedError(LinkError):
    """The link was closed by us."""


class LinkBrokenError(LinkError):
    """The peer or the hardware went away (``__cause__`` holds the OS/driver error)."""


class LinkTimeoutError(LinkError, TimeoutError):
    """Waiting on a link timed out (in the emulator's clock)."""


class RecordingError(EmulatorError):
    """A capture or recorded-data file is malformed (names file, line and column)."""


class WriterProcessError(EmulatorError):
    """The paced writer's process (:mod:`emulator.pacing`) could not be started or died: what it held is lost
    (counted as dropped) and the paced writer writes from its thread instead."""


#: ``errno`` of an output that cannot be written for a reason of the machine, not of the program: the disk or the
#: quota is full, a file reached the size limit (``ulimit -f``, with SIGXFSZ ignored), a read-only file system, no
#: permission (docs/hostile-input.md section 8)
STORAGE_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS, errno.EACCES, errno.EPERM})


class StorageError(EmulatorError):
    """The run directory (or another output) could not be written: disk full, file-size limit, read-only or no
    permission. The message says what was kept (exit 2 on the command line)."""
