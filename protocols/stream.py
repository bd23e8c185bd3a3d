"""The one sans-IO streaming decoder shared by every interface.

A :class:`StreamDecoder` is given byte chunks of any size with :meth:`StreamDecoder.feed`
and returns the whole frames found so far. It never raises on bad bytes: it counts garbage
bytes, checksum failures, bad lengths and resynchronisations (:class:`DecoderStats`) and
carries on. After a failed candidate it resynchronises at *header + 1*, never after a
declared length that may itself be corrupt, so the next good frame is found within one
frame length of the corruption.

What a frame looks like is told by :class:`FrameFormat` objects (one per frame family:
a STIM datagram format, the FPGA IMU frame, NMEA sentences, UBX, ...). A port that carries
several families (a GNSS port with NMEA and UBX) gives the decoder several formats; the
earliest sync in the buffer wins.

The firmware model (``firmware_model``) and the emulator's monitor use this same class.

Fast paths sit next to their reference under one naming scheme: :meth:`StreamDecoder._scan` is the
reference scanner (any number of formats); :meth:`StreamDecoder._scan_fast` is the same scan specialised
for one format, and :meth:`StreamDecoder.feed` hands a chunk that is exactly one whole frame straight to
the format. ``StreamDecoder(formats, fast_paths=False)`` runs the reference alone;
``tests/protocols/fast_path_cases.py`` checks that both give the same frames and counters.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

__all__ = ["BAD_LENGTH", "NEED_MORE", "PARSE_REFUSALS", "DecoderStats", "FrameFormat", "StreamDecoder", "parse_one"]

#: ``FrameFormat.frame_length`` result: not enough bytes yet to know the length.
NEED_MORE = -1
#: ``FrameFormat.frame_length`` result: the header declares an impossible length.
BAD_LENGTH = -2

#: The exceptions by which a format's ``parse`` refuses a frame (a parse error). Any other exception of a format's
#: code is contained as well and counted in :attr:`DecoderStats.format_faults` besides: no exception from input
#: escapes :meth:`StreamDecoder.feed`, and the scan always advances past the candidate that raised.
PARSE_REFUSALS: tuple[type[Exception], ...] = (ValueError, KeyError, IndexError, UnicodeDecodeError)


#: Marker of the fast path in :meth:`StreamDecoder.feed`: no frame (a parse may return any object, None included).
_NONE = object()


@runtime_checkable
class FrameFormat(Protocol):
    """How one frame family is delimited, checked and parsed.

    Attributes
    ----------
    name:
        Short name used in statistics (``"stim210"``, ``"nmea"``, ...).
    sync:
        The byte string that starts every frame of this family.
    """

    name: str
    sync: bytes

    def frame_length(self, buf: bytes | bytearray, start: int) -> int:
        """Length in bytes of the frame starting at ``buf[start]``.

        Returns :data:`NEED_MORE` when more bytes are needed to tell, :data:`BAD_LENGTH`
        when the header is impossible.
        """

    def check(self, frame: bytes) -> bool:
        """True when the frame's checksum (or other integrity check) holds."""

    def parse(self, frame: bytes) -> Any:
        """Decode a checked frame into its frame object. Refuses a frame by raising ``ValueError`` (or ``KeyError``,
        ``IndexError``, ``UnicodeDecodeError``); the decoder contains any other exception too
        (:attr:`DecoderStats.format_faults`).

        Every format in :mod:`protocols` also has ``encode(obj) -> bytes``, the inverse of
        ``parse`` (``encode(parse(frame)) == frame`` for frames its own encoder wrote); the
        decoder does not need it.
        """


@dataclass
class DecoderStats:
    """Counters of a :class:`StreamDecoder` (monotonic, never reset implicitly)."""

    bytes_in: int = 0
    frames: int = 0
    garbage_bytes: int = 0
    crc_errors: int = 0
    length_errors: int = 0
    parse_errors: int = 0
    resyncs: int = 0
    #: exceptions a format's own code raised other than a refusal (``OverflowError``, ``RecursionError``, ...):
    #: contained and also counted as the failure of their step (a length, checksum or parse error); 0 unless a
    #: parser meets a case nobody foresaw, so a test asserting 0 finds it
    format_faults: int = 0
    per_format: dict[str, int] = field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return {
            "bytes_in": self.bytes_in,
            "frames": self.frames,
            "garbage_bytes": self.garbage_bytes,
            "crc_errors": self.crc_errors,
            "length_errors": self.length_errors,
            "parse_errors": self.parse_errors,
            "resyncs": self.resyncs,
            "format_faults": self.format_faults,
            "per_format": dict(self.per_format),
        }


class StreamDecoder:
    """Incremental framer over one byte stream.

    Parameters
    ----------
    formats:
        The frame families expected on this stream.
    max_buffer:
        Bytes kept while waiting for the end of a candidate frame; beyond it the oldest
        candidate is abandoned (counted as a length error) so memory stays bounded.
    fast_paths:
        False runs the reference scanner only (for equivalence tests; the results are the same).
    """

    def __init__(self, formats: Sequence[FrameFormat], max_buffer: int = 65536, fast_paths: bool = True) -> None:
        if not formats:
            raise ValueError("StreamDecoder needs at least one FrameFormat")
        self.formats = tuple(formats)
        self.stats = DecoderStats(per_format={f.name: 0 for f in self.formats})
        self._buf = bytearray()
        self._pos = 0
        self._in_garbage = False
        self._max_buffer = max_buffer
        self._max_sync = max(len(f.sync) for f in self.formats)
        #: the one format, when the fast paths apply (one format, fast paths on)
        self._single = self.formats[0] if len(self.formats) == 1 and fast_paths else None

    # -- public API -----------------------------------------------------------------
    def feed(self, data: bytes | bytearray | memoryview) -> list[Any]:
        """Append ``data`` and return every whole, checked frame now available, in order."""
        if data:
            self.stats.bytes_in += len(data)
            fmt = self._single
            if fmt is not None and not self._buf and type(data) is bytes and data.startswith(fmt.sync):
                # Fast path: nothing buffered and the chunk is exactly one whole frame with a good checksum
                # (a driver handing over frame by frame). Counted as the scanner below would count it; any
                # exception of the format falls through to the scanner, which meets it again and counts it.
                try:
                    obj = fmt.parse(data) if fmt.frame_length(data, 0) == len(data) and fmt.check(data) else _NONE
                except Exception:
                    obj = _NONE
                if obj is not _NONE:
                    stats = self.stats
                    stats.frames += 1
                    stats.per_format[fmt.name] += 1
                    self._in_garbage = False
                    return [obj]
            self._buf += data
        out: list[Any] = []
        if self._single is None:
            self._scan(out)
        else:
            self._scan_fast(out)
        return out

    def pending(self) -> int:
        """Bytes held waiting for more input."""
        return len(self._buf) - self._pos

    def flush(self) -> None:
        """Drop everything buffered, counting it as garbage (end of stream)."""
        n = len(self._buf) - self._pos
        if n:
            self.stats.garbage_bytes += n
        self._buf.clear()
        self._pos = 0

    # -- internals ----------------------------------------------------------------
    def _check(self, fmt: FrameFormat, frame: bytes) -> bool:
        """``fmt.check(frame)``; an exception of the check counts as a failed check and a format fault."""
        try:
            return bool(fmt.check(frame))
        except Exception:
            self.stats.format_faults += 1
            return False

    def _parse_failed(self, exc: Exception) -> None:
        """Count a candidate whose parse raised: a parse error, and a format fault unless it was a refusal."""
        self.stats.parse_errors += 1
        if not isinstance(exc, PARSE_REFUSALS):
            self.stats.format_faults += 1

    def _garbage(self, n: int) -> None:
        if n <= 0:
            return
        self.stats.garbage_bytes += n
        if not self._in_garbage:
            self._in_garbage = True
            self.stats.resyncs += 1

    def _find(self, pos: int, nxt: list[int] | None = None) -> tuple[int, FrameFormat | None]:
        """The earliest sync at or after ``pos``. ``nxt`` (one entry per format, for one scan of an unchanged
        buffer) remembers where each format's sync was found, so a flood of one format's sync does not re-search
        the whole buffer for the others at every position (linear time, docs/hostile-input.md)."""
        buf = self._buf
        if self._single is not None:
            return buf.find(self._single.sync, pos), self._single
        best = -1
        best_fmt = None
        for k, fmt in enumerate(self.formats):
            if nxt is not None:
                p = nxt[k]
                if p != -1 and p < pos:  # -1: absent from an earlier pos on, so absent from pos on as well
                    p = nxt[k] = buf.find(fmt.sync, pos)
            else:
                p = buf.find(fmt.sync, pos)
            if p >= 0 and (best < 0 or p < best):
                best, best_fmt = p, fmt
        return best, best_fmt

    def _scan_fast(self, out: list[Any]) -> None:
        """:meth:`_scan` for one format (200 Hz in the emulator, every link of the recorder): pre-bound
        methods, a local frame counter that reaches ``stats`` before return, no call on the common paths.
        Counting is exactly that of :meth:`_scan`."""
        buf = self._buf
        pos = self._pos
        fmt = self._single
        assert fmt is not None  # feed() calls it only with one format
        sync = fmt.sync
        frame_length = fmt.frame_length
        nframes = 0
        while True:
            p = buf.find(sync, pos)
            if p < 0:
                # Keep a tail that might be the beginning of a sync sequence.
                keep_from = len(buf) - self._max_sync + 1
                if keep_from > pos:
                    self._garbage(keep_from - pos)
                    pos = keep_from
                break
            if p != pos:
                self._garbage(p - pos)
                pos = p
            try:
                n = frame_length(buf, p)
            except Exception:
                self.stats.format_faults += 1
                n = BAD_LENGTH
            end = p + n
            if n > 0 and len(buf) >= end:
                frame = bytes(buf[p:end])
                if self._check(fmt, frame):
                    try:
                        obj = fmt.parse(frame)
                    except Exception as exc:
                        self._parse_failed(exc)
                    else:
                        out.append(obj)
                        nframes += 1
                        self._in_garbage = False
                        pos = end
                        continue
                else:
                    self.stats.crc_errors += 1
            elif n == NEED_MORE or n > 0:
                if len(buf) - p <= self._max_buffer and n <= self._max_buffer:
                    break  # wait for more bytes
                self.stats.length_errors += 1
            else:  # BAD_LENGTH or nonsense
                self.stats.length_errors += 1
            # Failed candidate: resynchronise at header + 1.
            self._garbage(1)
            pos = p + 1
        if nframes:
            stats = self.stats
            stats.frames += nframes
            stats.per_format[fmt.name] += nframes
        # Compact the buffer.
        if pos:
            if pos >= len(buf):
                buf.clear()
            else:
                del buf[:pos]
        self._pos = 0

    def _scan(self, out: list[Any]) -> None:
        """The reference scanner: any number of formats, the earliest sync first."""
        buf = self._buf
        pos = self._pos
        stats = self.stats
        max_buffer = self._max_buffer
        nxt = [-2] * len(self.formats)  # -2: not searched yet in this scan
        while True:
            p, fmt = self._find(pos, nxt)
            if p < 0 or fmt is None:
                # Keep a tail that might be the beginning of a sync sequence.
                keep_from = max(pos, len(buf) - (self._max_sync - 1))
                self._garbage(keep_from - pos)
                pos = keep_from
                break
            self._garbage(p - pos)
            pos = p
            try:
                n = fmt.frame_length(buf, p)
            except Exception:
                stats.format_faults += 1
                n = BAD_LENGTH
            if n == NEED_MORE:
                if len(buf) - p > max_buffer:
                    stats.length_errors += 1
                    self._garbage(1)
                    pos = p + 1
                    continue
                break
            if n == BAD_LENGTH or n <= 0:
                stats.length_errors += 1
                self._garbage(1)
                pos = p + 1
                continue
            if len(buf) - p < n:
                if n > max_buffer:
                    stats.length_errors += 1
                    self._garbage(1)
                    pos = p + 1
                    continue
                break
            frame = bytes(buf[p : p + n])
            if not self._check(fmt, frame):
                stats.crc_errors += 1
                self._garbage(1)
                pos = p + 1
                continue
            try:
                obj = fmt.parse(frame)
            except Exception as exc:
                self._parse_failed(exc)
                self._garbage(1)
                pos = p + 1
                continue
            out.append(obj)
            stats.frames += 1
            stats.per_format[fmt.name] += 1
            self._in_garbage = False
            pos = p + n
        # Compact the buffer.
        if pos:
            del buf[:pos]
        self._pos = 0


def parse_one(fmt: FrameFormat, frame: bytes) -> Any:
    """Strictly parse exactly one frame, raising :class:`~protocols.errors.ProtocolError`.

    For tests and tools that hold one frame; streams go through :class:`StreamDecoder`.
    """
    from .errors import ChecksumError, FrameError

    if not frame.startswith(fmt.sync):
        raise FrameError(f"{fmt.name}: frame does not start with sync {fmt.sync.hex()}")
    n = fmt.frame_length(bytearray(frame), 0)
    if n != len(frame):
        raise FrameError(f"{fmt.name}: expected {n} bytes from the header, got {len(frame)}")
    if not fmt.check(frame):
        raise ChecksumError(f"{fmt.name}: checksum mismatch in {frame.hex()}")
    try:
        return fmt.parse(frame)
    except Exception as exc:  # any exception of a parse is a refused frame (PARSE_REFUSALS and the unforeseen)
        raise FrameError(f"{fmt.name}: {type(exc).__name__}: {exc}") from exc
