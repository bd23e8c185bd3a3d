"""Confinement of the file paths a scenario names (docs/hostile-input.md, "Untrusted scenarios").

A scenario may come from anyone: every file it names (recorded sensor data, Python hooks) must lie inside the
scenario's own directory. Absolute paths and ``..`` that leave it are refused, symbolic links are resolved before
the test. The environment variable ``PSNS_HIL_ALLOW_PATHS`` (directories separated by ``os.pathsep``) widens the
set of allowed roots, for a trusted setup that keeps recordings elsewhere.

Python hooks (``expectations[].python``) are never imported by ``validate``; ``run`` imports them only with
``--allow-hooks`` (which sets ``PSNS_HIL_ALLOW_HOOKS=1`` for the run and its processes).
"""

from __future__ import annotations

import fnmatch
import json
import os
import re
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import RecordingError

__all__ = ["ALLOW_HOOKS_ENV", "ALLOW_PATHS_ENV", "FRAME_INDEX_MAX_BYTES", "LINK_FILE_OPTIONS", "MAX_JSON_DEPTH",
           "RECORDED_LINE_MAX", "PathNotAllowed", "allowed_roots", "confine", "confined_glob", "confined_link_url",
           "decode_utf8", "hooks_allowed", "json_depth", "read_bounded", "read_frame_index", "read_json_bounded"]

ALLOW_PATHS_ENV = "PSNS_HIL_ALLOW_PATHS"
ALLOW_HOOKS_ENV = "PSNS_HIL_ALLOW_HOOKS"

#: longest line of a recorded CSV or a camera index (characters); a real row is < 200 (issue 41: a 50 MB line gave
#: a traceback)
RECORDED_LINE_MAX = 65536
#: largest camera index CSV read (bytes): one ``time_s,file`` line is about 40 bytes, so 64 MiB lists over a
#: million frames (an hour at 300 frames/s); checked while reading, never after
FRAME_INDEX_MAX_BYTES = 64 << 20
#: deepest JSON nesting accepted in a file a scenario names or a capture header (the deepest real one, a capture's
#: scenario spec, nests about 8 deep); checked before decoding (Python's decoder recurses)
MAX_JSON_DEPTH = 64


class PathNotAllowed(ValueError):
    """A scenario names a file outside the directories it may read (the message names the path, never content)."""


def allowed_roots(base_dir: str | Path | None) -> list[Path]:
    """The scenario's directory and the directories of ``PSNS_HIL_ALLOW_PATHS``, resolved."""
    roots = [Path(base_dir).resolve()] if base_dir is not None else [Path.cwd().resolve()]
    for extra in os.environ.get(ALLOW_PATHS_ENV, "").split(os.pathsep):
        if extra.strip():
            roots.append(Path(extra).expanduser().resolve())
    return roots


def confine(base_dir: str | Path | None, name: str, what: str = "file") -> Path:
    """The resolved path of ``name`` (relative to ``base_dir``, the scenario's directory) if it lies inside an
    allowed root (:func:`allowed_roots`); :class:`PathNotAllowed` otherwise."""
    if "\x00" in name:
        raise PathNotAllowed(f"{what} path contains a NUL character")
    p = Path(name).expanduser()
    base = Path(base_dir) if base_dir is not None else Path.cwd()
    full = (p if p.is_absolute() else base / p).resolve()
    for root in allowed_roots(base_dir):
        if full == root or full.is_relative_to(root):
            return full
    raise PathNotAllowed(f"{what} {name!r} is outside the scenario's directory (set {ALLOW_PATHS_ENV} to allow "
                         "other directories)")


_MAGIC = re.compile(r"[*?[]")


def confined_glob(base_dir: str | Path | None, pattern: str, what: str = "file") -> list[Path]:
    """The files matching ``pattern`` (``*``, ``?``, ``[...]`` per path component, as :func:`glob.glob`; hidden
    names only by a pattern starting with ``.``), sorted, each confined by :func:`confine`.

    The walk confines every entry a wildcard selects *before* looking inside it, so a component that leads out of
    the allowed roots (``frames_lin?`` matching a symbolic link to another directory) is refused
    (:class:`PathNotAllowed`) whatever lies behind it: the result never depends on files outside the roots (no
    existence oracle). The fixed prefix of the pattern is confined first, the same way.
    """
    parts = Path(pattern).expanduser().parts
    first = next((i for i, part in enumerate(parts) if _MAGIC.search(part)), len(parts))
    prefix = Path(*parts[:first]) if first else Path(".")
    start = confine(base_dir, str(prefix), what)  # the fixed part: inside, or refused by name
    if first == len(parts):
        return [start] if start.is_file() else []
    dirs = [start]
    for k, part in enumerate(parts[first:], start=first):
        last = k == len(parts) - 1
        found: list[Path] = []
        for d in dirs:
            if _MAGIC.search(part):
                try:
                    names = sorted(e.name for e in os.scandir(d))
                except OSError:
                    continue
                names = [n for n in names if fnmatch.fnmatchcase(n, part)
                         and (part.startswith(".") or not n.startswith("."))]
            else:
                names = [part]
            for n in names:
                full = confine(base_dir, str(d / n), what)  # before anything behind it is looked at
                if full.is_file() if last else full.is_dir():
                    found.append(full)
        dirs = found
    return sorted(dirs)


def hooks_allowed() -> bool:
    """True when Python hooks may be imported (``psns-hil run --allow-hooks``)."""
    return os.environ.get(ALLOW_HOOKS_ENV, "") not in ("", "0")


def _index_lines(path: Path) -> Iterator[tuple[int, str]]:
    """``(line number, text)`` of a camera index, read in bounded pieces (:func:`read_frame_index`)."""
    piece = 4 * RECORDED_LINE_MAX + 2  # a UTF-8 character is at most 4 bytes
    try:
        if path.is_dir():
            raise RecordingError(f"{path}: is a directory, not a camera index")
        with open(path, "rb") as f:
            total = 0
            for i, raw in enumerate(iter(lambda: f.readline(piece), b""), start=1):
                total += len(raw)
                if total > FRAME_INDEX_MAX_BYTES:
                    raise RecordingError(f"{path}: line {i}: the index is larger than "
                                         f"{FRAME_INDEX_MAX_BYTES >> 20} MiB")
                too_long = f"{path}: line {i}, column {RECORDED_LINE_MAX + 1}: line longer than " \
                           f"{RECORDED_LINE_MAX} characters"
                if len(raw) == piece and not raw.endswith(b"\n"):
                    raise RecordingError(too_long)
                try:
                    ln = raw.decode("utf-8").rstrip("\r\n")
                except UnicodeDecodeError as exc:
                    raise RecordingError(f"{path}: line {i}, column {exc.start + 1}: not UTF-8 text") from None
                if len(ln) > RECORDED_LINE_MAX:
                    raise RecordingError(too_long)
                yield i, ln
    except OSError as exc:
        raise RecordingError(f"{path}: cannot read: {exc.strerror or type(exc).__name__}") from None


def read_frame_index(path: Path, base_dir: str | Path | None) -> tuple[np.ndarray, list[Path]]:
    """``(times, files)`` of a camera index CSV ``time_s,file``; each file is relative to the index and confined to
    the scenario's directory (``base_dir``); a refused or missing one is reported by line and column, never by its
    text, and an entry outside is refused before the file system is asked about it (no existence oracle).
    The index is read line by line, bounded: at most :data:`FRAME_INDEX_MAX_BYTES` in all and
    :data:`RECORDED_LINE_MAX` characters a line, UTF-8 (issue 41: it was read whole).
    :class:`emulator.errors.RecordingError` for a bad index; used by the camera and by ``validate``."""
    times: list[float] = []
    files: list[Path] = []
    header_seen = False
    for i, ln in _index_lines(path):
        if not ln.strip() or ln.lstrip().startswith("#"):
            continue
        cells = [c.strip() for c in ln.split(",")]
        if not header_seen:
            if cells[:2] != ["time_s", "file"]:
                raise RecordingError(f"{path}: line {i}, column 1: the header must be 'time_s,file'")
            header_seen = True
            continue
        if len(cells) < 2:
            raise RecordingError(f"{path}: line {i}, column {len(ln) + 1}: expected 'time_s,file'")
        try:
            times.append(float(cells[0]))
        except ValueError:
            raise RecordingError(f"{path}: line {i}, column 1: time_s is not a number") from None
        col = ln.index(",") + 2
        try:  # confined before anything is asked of the file system about it: no existence oracle
            f = confine(base_dir, str(path.parent / cells[1]), "camera frame")
        except PathNotAllowed:
            raise RecordingError(f"{path}: line {i}, column {col}: the frame file is outside the scenario's "
                                 f"directory (set {ALLOW_PATHS_ENV} to allow other directories)") from None
        if not f.is_file():
            raise RecordingError(f"{path}: line {i}, column {col}: the frame file does not exist")
        files.append(f)
    if not times:
        raise RecordingError(f"{path}: line 1, column 1: no frames listed")
    return np.array(times), files


def read_bounded(path: Path, limit: int, what: str = "file") -> bytes:
    """The bytes of ``path`` in one bounded read: at most ``limit`` + 1 bytes are read, so a larger file (or an
    endless one such as ``/dev/zero``, or a FIFO) is refused by its size, never read whole.
    :class:`emulator.errors.RecordingError` naming the file (never its content)."""
    try:
        if path.is_dir():
            raise RecordingError(f"{path}: is a directory, not a {what}")
        with open(path, "rb") as f:
            raw = f.read(limit + 1)
    except FileNotFoundError:
        raise RecordingError(f"{path}: no such file") from None
    except OSError as exc:
        raise RecordingError(f"{path}: cannot read: {exc.strerror or type(exc).__name__}") from None
    if len(raw) > limit:
        raise RecordingError(f"{path}: larger than {_size(limit)} (a {what} is a few KB)")
    return raw


def _size(n: int) -> str:
    return f"{n >> 20} MiB" if n >= 1 << 20 and n % (1 << 20) == 0 else f"{n} bytes"


def json_depth(text: bytes) -> int:
    """Deepest nesting of ``[``/``{`` in a JSON text, brackets inside strings skipped; linear and vectorised (no
    recursion, no backtracking: a quote counts when an even run of backslashes precedes it)."""
    a = np.frombuffer(text, dtype=np.uint8)
    if a.size == 0:
        return 0
    pos = np.arange(a.size, dtype=np.int64)
    bs = a == ord("\\")
    last_other = np.maximum.accumulate(np.where(bs, -1, pos))  # last non-backslash at or before each position
    run_before = np.empty(a.size, dtype=np.int64)
    run_before[0] = 0
    run_before[1:] = pos[:-1] - last_other[:-1]  # backslashes just before each position
    quote = (a == ord('"')) & (run_before % 2 == 0)
    outside = np.cumsum(quote) % 2 == 0  # after an even number of quotes: not inside a string
    step = ((a == ord("[")) | (a == ord("{"))).astype(np.int64) - ((a == ord("]")) | (a == ord("}")))
    return int(np.cumsum(np.where(outside, step, 0)).max(initial=0))


def _no_constant(name: str) -> Any:
    raise ValueError(f"{name} is not JSON")


def decode_utf8(raw: bytes, path: Path | str) -> str:
    """``raw`` as UTF-8 text, or :class:`emulator.errors.RecordingError` naming file, line and column (1-based) and
    the byte offset of the first byte that is not UTF-8, never the content."""
    try:
        return raw.decode("utf-8")
    except UnicodeDecodeError as exc:
        line = raw.count(b"\n", 0, exc.start) + 1
        col = exc.start - (raw.rfind(b"\n", 0, exc.start) + 1) + 1
        raise RecordingError(f"{path}: line {line}, column {col}: not UTF-8 text (byte offset {exc.start})") from None


def read_json_bounded(path: Path, limit: int, what: str = "JSON file") -> Any:
    """The data of a JSON file a scenario names (a calibration file), bounded as a scenario is: one read of at most
    ``limit`` bytes (:func:`read_bounded`), UTF-8, nesting checked (:data:`MAX_JSON_DEPTH`) before decoding,
    strict JSON (``NaN``/``Infinity`` refused). :class:`emulator.errors.RecordingError` naming file, line and column,
    never the content."""
    raw = read_bounded(path, limit, what)
    text = decode_utf8(raw, path)
    if json_depth(raw) > MAX_JSON_DEPTH:
        raise RecordingError(f"{path}: nests deeper than {MAX_JSON_DEPTH} levels (a {what} needs about 3)")
    try:
        return json.loads(text, parse_constant=_no_constant)
    except json.JSONDecodeError as exc:
        raise RecordingError(f"{path}: line {exc.lineno}, column {exc.colno}: not JSON ({exc.msg})") from None
    except (ValueError, RecursionError) as exc:
        raise RecordingError(f"{path}: not JSON ({exc if isinstance(exc, ValueError) else 'too deep'})") from None


#: options of a link URL that name a file: zenoh's ``auth=FILE`` (credentials) and ``config=FILE`` (session
#: configuration); in a scenario they are confined as every file it names (decision D-7.32)
LINK_FILE_OPTIONS = ("auth", "config")


def confined_link_url(url: str, base_dir: str | Path | None) -> str:
    """``url`` of a link a scenario names with each file option (:data:`LINK_FILE_OPTIONS`) resolved against the
    scenario's directory and confined by :func:`confine` (:class:`PathNotAllowed` when one lies outside). A
    scenario may come from anyone: ``auth=~/.other-run/credentials.txt`` with ``connect=tcp/far-host`` would hand
    another run's password to a far host, ``config=`` would parse any file. The command line's own URLs
    (``psns-hil monitor zenoh://...?auth=FILE``) and ``PSNS_HIL_ZENOH_AUTH`` are the user's and are not confined."""
    from urllib.parse import parse_qsl, quote, urlsplit, urlunsplit

    parts = urlsplit(url)
    pieces = parts.query.split("&") if parts.query else []
    out, changed = [], False
    for piece in pieces:  # the other options keep their text as written
        kv = parse_qsl(piece, keep_blank_values=True)
        if len(kv) == 1 and kv[0][0] in LINK_FILE_OPTIONS:
            key, value = kv[0]
            piece = f"{key}={quote(str(confine(base_dir, value, f'link {key} file')), safe='/:')}"
            changed = True
        out.append(piece)
    return urlunsplit(parts._replace(query="&".join(out))) if changed else url
