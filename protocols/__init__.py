"""Wire formats of psns-hil: frame specs, checksums and the one streaming decoder.

Depends on nothing else of ours. Every frame family is a module with a declarative
``construct`` layout, a :class:`~protocols.stream.FrameFormat` for the streaming decoder and
an encoder; ``docs/icd.md`` is the byte-by-byte interface control document. The layouts are declared
once: the fast ``struct`` codecs of the hot paths are derived from the ``construct`` specs at import
time (:mod:`protocols.codec`), and every fast path sits beside its reference as ``<name>_fast``.
"""

from __future__ import annotations

from .errors import ChecksumError, FrameError, ProtocolError, PsnsHilError
from .stream import BAD_LENGTH, NEED_MORE, DecoderStats, FrameFormat, StreamDecoder, parse_one

__version__ = "0.1.0"

__all__ = [
    "BAD_LENGTH",
    "NEED_MORE",
    "ChecksumError",
    "DecoderStats",
    "FrameError",
    "FrameFormat",
    "ProtocolError",
    "PsnsHilError",
    "StreamDecoder",
    "__version__",
    "parse_one",
]
