"""The capture file (``capture.psnscap``): every chunk on every tapped link, with its time and direction.

Format (little-endian): the 9-byte magic ``PSNSCAP1\\n``, one JSON header line
``{"version": 2, "links": [...], ...}\\n``, then records ``<d t_s> <H link_index> <B direction (0 out, 1 in)>
<B flags> <I length>``, with flag :data:`FLAG_PITCH` an ``<d pitch_s>`` after it, followed by ``length`` bytes.
``docs/capture-format.md`` has the details. :class:`CaptureWriter` writes one (the recorder owns it);
:func:`iter_capture` and :func:`read_capture` read one, ignoring a truncated last record (an interrupted run).
"""

from __future__ import annotations

import json
import struct
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from ..errors import RecordingError
from .formatting import json_default
from .rundir import open_no_follow

__all__ = [
    "CAPTURE_MAGIC",
    "CAPTURE_VERSION",
    "FLAG_PITCH",
    "CaptureRecord",
    "CaptureWriter",
    "iter_capture",
    "read_capture",
]

CAPTURE_MAGIC = b"PSNSCAP1\n"
CAPTURE_VERSION = 2
#: record flag: an f64 byte pitch (s, start-to-start spacing of the chunk's bytes) follows the header
FLAG_PITCH = 0x01
_REC = struct.Struct("<dHBBI")
_PITCH = struct.Struct("<d")


@dataclass
class CaptureRecord:
    t_s: float
    link: str
    direction: str
    data: bytes
    #: spacing of the bytes on the wire when it differs from the link's byte time (None otherwise)
    pitch_s: float | None = None


class CaptureWriter:
    """Writes a capture file: the magic and the header line at once, then one record per :meth:`write`.

    ``header`` is any JSON-able dict (the run's description); ``version`` and ``links`` (the link names, whose
    positions are the records' link indices) are set here.
    """

    def __init__(self, path: Path, header: dict[str, Any], links: list[str]) -> None:
        self.file: IO[bytes] = open_no_follow(path, "wb")  # open for the run, closed by close()
        hdr = dict(header)
        hdr["version"] = CAPTURE_VERSION
        hdr["links"] = list(links)
        self.file.write(CAPTURE_MAGIC + json.dumps(hdr, sort_keys=True, default=json_default).encode() + b"\n")
        self.file.flush()

    def write(self, index: int, inbound: bool, t: float, data: bytes, pitch: float | None = None) -> None:
        """One record: link ``index``, direction ``in`` (``inbound``) or ``out``, time ``t`` (s), the bytes, and
        their spacing on the wire when it is not the link's byte time."""
        if pitch is None:  # one buffered write per record (the header and the bytes joined)
            self.file.write(_REC.pack(t, index, 1 if inbound else 0, 0, len(data)) + data)
        else:
            self.file.write(_REC.pack(t, index, 1 if inbound else 0, FLAG_PITCH, len(data)) + _PITCH.pack(pitch) + data)

    def flush(self) -> None:
        if not self.file.closed:
            self.file.flush()

    def close(self) -> None:
        if not self.file.closed:
            self.file.close()


def _read_header(f: IO[bytes], path: str | Path) -> dict[str, Any]:
    magic = f.read(len(CAPTURE_MAGIC))
    if magic != CAPTURE_MAGIC:
        raise RecordingError(f"{path}: not a psns-hil capture (bad magic)")
    line = f.readline()
    if not line.endswith(b"\n"):
        raise RecordingError(f"{path}: capture header line is incomplete")
    try:
        header = json.loads(line)
    except json.JSONDecodeError as exc:
        raise RecordingError(f"{path}: line 2, column {exc.colno}: bad capture header: {exc.msg}") from None
    if not isinstance(header, dict):
        raise RecordingError(f"{path}: line 2: the capture header must be a JSON object")
    return header


def iter_capture(path: str | Path) -> tuple[dict[str, Any], Iterator[CaptureRecord]]:
    """Header and a lazy iterator over the records (constant memory for any file size).

    A truncated last record (interrupted run, a file cut short) ends the iteration; it then sets
    ``header["truncated_record"] = True`` (the header dict returned here).
    """
    f = open(path, "rb")  # noqa: SIM115 - handed to the generator, which closes it
    try:
        header = _read_header(f, path)
    except BaseException:
        f.close()
        raise
    links = header.get("links", [])

    def gen() -> Iterator[CaptureRecord]:
        with f:
            size = _REC.size
            while True:
                head = f.read(size)
                if len(head) < size:
                    if head:
                        header["truncated_record"] = True
                    return
                t, idx, d, flags, n = _REC.unpack(head)
                pitch = None
                if flags & FLAG_PITCH:
                    raw = f.read(_PITCH.size)
                    if len(raw) < _PITCH.size:
                        header["truncated_record"] = True
                        return
                    pitch = _PITCH.unpack(raw)[0]
                data = f.read(n)
                if len(data) < n:
                    header["truncated_record"] = True
                    return
                name = links[idx] if idx < len(links) else f"link{idx}"
                yield CaptureRecord(t, name, "out" if d == 0 else "in", data, pitch)

    return header, gen()


def read_capture(path: str | Path) -> tuple[dict[str, Any], list[CaptureRecord]]:
    """Read a ``.psnscap`` file; a truncated last record (interrupted run) is ignored."""
    header, it = iter_capture(path)
    return header, list(it)
