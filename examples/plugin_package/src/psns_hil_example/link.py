"""``logfile://NAME``: an output-only port that writes every byte the emulator sends, at the line's pace, to
``<run_dir>/ports/NAME.bin`` (what a data logger on the port would keep). Nothing ever arrives from it.

URL form: ``logfile://NAME[?append=0|1&baud=N&mode=8N1&queue=BYTES]``.
"""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import IO, Any

from emulator.errors import LinkConfigError
from emulator.links import LineConfig, Link


class LogFileLink(Link):
    """See module docstring."""

    scheme = "logfile"
    paces_input = False
    url_options = frozenset({"append"})
    url_usage = "logfile://NAME[?append=0|1&baud=N&mode=8N1&queue=BYTES]"

    def __init__(self, name: str, url: str, line: LineConfig, loop: asyncio.AbstractEventLoop, *, target: str,
                 options: dict[str, str], run_dir: str | Path | None = None, **_: Any) -> None:
        super().__init__(name, url, line, loop)
        if "/" in target or target in ("", ".", ".."):
            raise LinkConfigError(f"{url!r}: the log file's name must be a plain name; expected {self.url_usage}")
        if options.get("append", "0") not in ("0", "1"):
            raise LinkConfigError(f"{url!r}: append must be 0 or 1; expected {self.url_usage}")
        self.append = options.get("append") == "1"
        self.path = Path(run_dir if run_dir is not None else ".") / f"{target}.bin"
        self._f: IO[bytes] | None = None

    async def open(self) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._f = open(self.path, "ab" if self.append else "wb")  # noqa: SIM115  (open for the whole run)

    def _write_raw(self, data: bytes) -> None:
        if self._f is None:
            self.stats.dropped_out += len(data)
            return
        self._f.write(data)

    async def close(self) -> None:
        if self._f is not None:
            self._f.close()
            self._f = None
        await super().close()

    def describe(self) -> str:
        return str(self.path)
