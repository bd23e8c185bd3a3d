"""The capture file (``capture.psnscap``): every chunk on every tapped link, with its time and direction.

Format (little-endian): the 9-byte magic ``PSNSCAP1\\n``, one JSON header line
``{"version": 2, "links": [...], ...}\\n``, then records ``<d t_s> <H link_index> <B direction (0 out, 1 in)>
<B flags> <I length>``, with flag :data:`FLAG_PITCH` an ``<d pitch_s>`` after it, followed by ``length`` bytes.
``docs/capture-format.md`` has the details. :class:`CaptureWriter` writes one (the recorder owns it);
:func:`iter_capture` and :func:`read_capture` read one, ignoring a truncated last record (an interrupted run).

A capture may come from anyone (docs/hostile-input.md): the reader reads the header line in one bounded piece
(:data:`MAX_HEADER_BYTES`), checks its nesting (:data:`MAX_HEADER_DEPTH`) before decoding it and the types of the
fields readers use, refuses a record declaring more than :data:`MAX_RECORD_BYTES` and reads a record's bytes in
pieces; each is a :class:`~emulator.errors.RecordingError` naming the file and the line, field or byte offset.
Records whose time is not finite or negative, or earlier than the previous record of the same link and direction,
are counted in the header dict (``bad_time_records``, ``backward_time_records``) as they are read.
"""

from __future__ import annotations

import json
import math
import struct
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

from ..errors import RecordingError
from ..scenario.paths import MAX_JSON_DEPTH
from ..scenario.paths import json_depth as _json_depth
from .formatting import json_default
from .rundir import open_no_follow

__all__ = [
    "CAPTURE_MAGIC",
    "CAPTURE_VERSION",
    "FLAG_PITCH",
    "MAX_HEADER_BYTES",
    "MAX_HEADER_DEPTH",
    "MAX_RECORD_BYTES",
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
#: longest header line read (bytes): the scenario spec it carries is tens of KB
MAX_HEADER_BYTES = 4 << 20
#: deepest JSON nesting of the header accepted (the scenario spec nests about 8 deep); checked before decoding
MAX_HEADER_DEPTH = MAX_JSON_DEPTH
#: largest record accepted (bytes): a record is one chunk a link delivered at once (a UART burst, KB)
MAX_RECORD_BYTES = 16 << 20
#: a record's bytes are read in pieces of at most this (bytes), so a declared length never allocates by itself
_READ_PIECE = 1 << 20


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


def _check_header(header: dict[str, Any], path: str | Path) -> None:
    """The types of the fields that readers use (a wrong one is named, with what it must be)."""
    def bad(field: str, what: str) -> RecordingError:
        return RecordingError(f"{path}: line 2, field {field!r}: {what}")

    version = header.get("version", 1)
    if type(version) is not int or version not in (1, CAPTURE_VERSION):
        raise bad("version", f"must be 1 or {CAPTURE_VERSION}")
    links = header.get("links", [])
    if not isinstance(links, list) or not all(isinstance(x, str) for x in links) or len(links) > 65536:
        raise bad("links", "must be a list of at most 65536 link names (strings)")
    for field, types, what in (("scenario_spec", (dict,), "an object"), ("seed", (int,), "an integer"),
                               ("link_baud", (dict,), "an object"), ("mode", (str,), "a string"),
                               ("scenario", (str,), "a string"), ("scenario_base_dir", (str,), "a string")):
        v = header.get(field)
        if v is not None and (not isinstance(v, types) or isinstance(v, bool)):
            raise bad(field, f"must be {what}")


def _read_header(f: IO[bytes], path: str | Path) -> dict[str, Any]:
    magic = f.read(len(CAPTURE_MAGIC))
    if magic != CAPTURE_MAGIC:
        raise RecordingError(f"{path}: not a psns-hil capture (bad magic)")
    line = f.readline(MAX_HEADER_BYTES + 1)  # one bounded piece
    if len(line) > MAX_HEADER_BYTES:
        raise RecordingError(f"{path}: line 2: the capture header is longer than {MAX_HEADER_BYTES >> 20} MiB")
    if not line.endswith(b"\n"):
        raise RecordingError(f"{path}: capture header line is incomplete")
    if _json_depth(line) > MAX_HEADER_DEPTH:
        raise RecordingError(f"{path}: line 2: the capture header nests deeper than {MAX_HEADER_DEPTH} levels")
    try:
        header = json.loads(line)
    except json.JSONDecodeError as exc:
        raise RecordingError(f"{path}: line 2, column {exc.colno}: bad capture header: {exc.msg}") from None
    except (UnicodeDecodeError, RecursionError, ValueError) as exc:
        raise RecordingError(f"{path}: line 2: bad capture header ({type(exc).__name__})") from None
    if not isinstance(header, dict):
        raise RecordingError(f"{path}: line 2: the capture header must be a JSON object")
    _check_header(header, path)
    return header


def _read_exact(f: IO[bytes], n: int) -> bytes:
    """Up to ``n`` bytes (fewer at the end of the file), read in pieces of at most 1 MiB."""
    if n <= _READ_PIECE:
        return f.read(n)
    parts = []
    while n > 0:
        piece = f.read(min(n, _READ_PIECE))
        if not piece:
            break
        parts.append(piece)
        n -= len(piece)
    return b"".join(parts)


def iter_capture(path: str | Path) -> tuple[dict[str, Any], Iterator[CaptureRecord]]:
    """Header and a lazy iterator over the records (constant memory for any file size).

    A truncated last record (interrupted run, a file cut short) ends the iteration; it then sets
    ``header["truncated_record"] = True`` (the header dict returned here). A malformed header, or a record declaring
    more than :data:`MAX_RECORD_BYTES`, is a :class:`~emulator.errors.RecordingError` (the latter raised by the
    iterator, naming the record's byte offset). Time stamps that are not finite or negative, or that go back within
    one link and direction, are counted in ``header["bad_time_records"]`` and ``header["backward_time_records"]``
    (the records are still yielded: the reader decides).
    """
    f = open(path, "rb")  # noqa: SIM115 - handed to the generator, which closes it
    try:
        header = _read_header(f, path)
    except BaseException:
        f.close()
        raise
    links = header.get("links", [])
    header["bad_time_records"] = 0
    header["backward_time_records"] = 0

    def gen() -> Iterator[CaptureRecord]:
        last: dict[tuple[int, int], float] = {}
        with f:
            size = _REC.size
            while True:
                offset = f.tell()
                head = f.read(size)
                if len(head) < size:
                    if head:
                        header["truncated_record"] = True
                    return
                t, idx, d, flags, n = _REC.unpack(head)
                if n > MAX_RECORD_BYTES:
                    raise RecordingError(f"{path}: record at byte {offset}: declares {n} bytes, more than "
                                         f"{MAX_RECORD_BYTES >> 20} MiB (not a capture record)")
                pitch = None
                if flags & FLAG_PITCH:
                    raw = f.read(_PITCH.size)
                    if len(raw) < _PITCH.size:
                        header["truncated_record"] = True
                        return
                    pitch = _PITCH.unpack(raw)[0]
                data = _read_exact(f, n)
                if len(data) < n:
                    header["truncated_record"] = True
                    return
                if not (math.isfinite(t) and t >= 0.0):
                    header["bad_time_records"] += 1
                else:
                    prev = last.get((idx, d))
                    if prev is not None and t < prev:
                        header["backward_time_records"] += 1
                    else:
                        last[(idx, d)] = t
                name = links[idx] if idx < len(links) else f"link{idx}"
                yield CaptureRecord(t, name, "out" if d == 0 else "in", data, pitch)

    return header, gen()


def read_capture(path: str | Path) -> tuple[dict[str, Any], list[CaptureRecord]]:
    """Read a ``.psnscap`` file; a truncated last record (interrupted run) is ignored."""
    header, it = iter_capture(path)
    return header, list(it)
