"""The recorder's counting decoders: frame, CRC-error and garbage counts of a tap without building frames.

Only the totals of the taps other than the navigation port are kept, so their decoders may skip building frame
objects where that cannot change a counter: :func:`counting_format` gives a format's non-parsing twin for the
formats of :data:`COUNT_ONLY_FORMATS`, whose ``parse`` is a fixed-layout unpack of a frame whose length
``frame_length`` has already validated and so cannot fail. :func:`frame_counts` (reference: the full formats)
and :func:`frame_counts_fast` (the counting decoder the recorder uses) give the same counters
(``tests/emulator/fast_path_cases.py``, ``tests/emulator/recording/test_recorder_counting.py``).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

from protocols.imu_frame import FpgaFrameFormat, ImuFrameFormat
from protocols.psns import PsnsFormat
from protocols.stim import Stim210Format
from protocols.stream import FrameFormat, StreamDecoder

__all__ = ["COUNT_ONLY_FORMATS", "counting_decoder", "counting_format", "frame_counts", "frame_counts_fast"]


class _Counted:
    """A frame format that delimits and checks like ``fmt`` but does not build the frame object."""

    __slots__ = ("check", "frame_length", "name", "sync")

    def __init__(self, fmt: FrameFormat) -> None:
        self.name = fmt.name
        self.sync = fmt.sync
        self.frame_length = fmt.frame_length
        self.check = fmt.check

    @staticmethod
    def parse(frame: bytes) -> None:
        return None


#: formats counted without parsing (see :class:`_Counted`)
COUNT_ONLY_FORMATS: tuple[type, ...] = (Stim210Format, ImuFrameFormat, FpgaFrameFormat, PsnsFormat)


def counting_format(fmt: FrameFormat) -> FrameFormat:
    """``fmt`` itself, or its non-parsing twin when counting its frames cannot differ (:class:`_Counted`)."""
    return _Counted(fmt) if type(fmt) in COUNT_ONLY_FORMATS else fmt


def counting_decoder(formats: Sequence[FrameFormat]) -> StreamDecoder:
    """A stream decoder over ``formats`` for counting only (its frames are not for use)."""
    return StreamDecoder([counting_format(f) for f in formats])


def frame_counts(formats: Sequence[FrameFormat], chunks: Iterable[bytes]) -> dict[str, Any]:
    """The decoder counters after ``chunks`` went through a decoder of the full ``formats`` (the reference)."""
    dec = StreamDecoder(list(formats))
    for c in chunks:
        dec.feed(c)
    return dec.stats.as_dict()


def frame_counts_fast(formats: Sequence[FrameFormat], chunks: Iterable[bytes]) -> dict[str, Any]:
    """:func:`frame_counts` through :func:`counting_decoder` (what the recorder's counting taps do)."""
    dec = counting_decoder(formats)
    for c in chunks:
        dec.feed(c)
    return dec.stats.as_dict()
