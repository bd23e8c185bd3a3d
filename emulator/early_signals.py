"""SIGINT / SIGTERM caught from the very start of ``psns-hil run`` (docs/hostile-input.md "Interruption").

:func:`install` runs before the CLI imports anything heavy (``emulator.cli`` calls it for a ``run`` command): a
signal that arrives while the scenario loads or the run is being built is remembered in :data:`PENDING`, and
:func:`emulator.assembly.session.run_emulator` then ends the run at once (run directory and a summary with
``"interrupted": true``) instead of the process dying with nothing written. SIGKILL cannot be caught.
"""

from __future__ import annotations

import contextlib
import os
import signal
import sys
from typing import Any

__all__ = ["PENDING", "install", "install_for_cli"]

#: signals received before the run's event loop installed its own handlers
PENDING: list[int] = []


def _early(signum: int, _frame: Any) -> None:
    PENDING.append(signum)


def install() -> None:
    """Remember SIGINT and SIGTERM instead of dying, and ignore SIGXFSZ (a file at the ``ulimit -f`` size limit
    then fails its write with EFBIG, reported as a storage error with the summary kept, instead of killing the
    process); main thread only, elsewhere nothing happens."""
    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(ValueError, OSError):
            signal.signal(sig, _early)
    if hasattr(signal, "SIGXFSZ"):
        with contextlib.suppress(ValueError, OSError):
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)


def install_for_cli() -> None:
    """:func:`install` when this process is ``psns-hil run`` / ``python -m emulator run`` (other commands, e.g.
    ``monitor``, keep Ctrl-C's KeyboardInterrupt)."""
    if sys.argv[1:2] == ["run"] and os.path.basename(sys.argv[0]) in ("psns-hil", "__main__.py"):
        install()
