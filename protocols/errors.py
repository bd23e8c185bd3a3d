"""The psns-hil exception hierarchy, rooted here in the lowest layer.

Every error that psns-hil raises on purpose derives from :class:`PsnsHilError`, so a
caller (the CLI, a test, a user's script) can catch one type. Each layer adds its own
subclasses in its own ``errors`` module and maps foreign exceptions at its boundary with
``raise ... from exc`` (``construct.ConstructError``, ``serial.SerialException``,
``can.CanError``, zenoh errors). The whole tree::

    PsnsHilError                              protocols/errors.py
    +-- ProtocolError                         bad bytes given to a *strict* parse/build
    |   +-- FrameError                        wrong sync, length or layout
    |   +-- ChecksumError                     CRC / checksum mismatch
    +-- FirmwareError                         firmware_model/errors.py: bad configuration
    +-- EmulatorError                         emulator/errors.py
        +-- ScenarioError                     file, line, column and field path of each problem
        +-- LinkError                         link URL or transport problem
        |   +-- LinkConfigError               bad URL / option (shows the accepted form)
        |   +-- LinkClosedError               we closed it
        |   +-- LinkBrokenError               the peer or the hardware went away
        |   +-- LinkTimeoutError(TimeoutError)
        +-- RecordingError                    bad capture / recorded-data file (names file, line, column)
        +-- WriterProcessError                the paced writer's process could not start or died
        +-- StorageError                      an output cannot be written (disk full, ulimit -f, read-only)

Streaming decoders never raise on bad bytes: they count and resynchronise. Only the strict
one-frame helpers (``parse_frame``) raise :class:`ProtocolError`.
"""

from __future__ import annotations

__all__ = ["ChecksumError", "FrameError", "ProtocolError", "PsnsHilError"]


class PsnsHilError(Exception):
    """Root of every error psns-hil raises on purpose."""


class ProtocolError(PsnsHilError):
    """Bytes that do not form a valid frame (strict parse only)."""


class FrameError(ProtocolError):
    """Wrong sync bytes, length or field layout."""


class ChecksumError(ProtocolError):
    """The frame's checksum does not match its contents."""
