"""The capture writer: its records are the documented bytes, in order, after every flush and at close."""

from __future__ import annotations

import random
import struct

from emulator.recording.capture import CAPTURE_MAGIC, FLAG_PITCH, CaptureWriter, read_capture


def _records(seed: int, n: int) -> list[tuple[int, bool, float, bytes, float | None]]:
    rng = random.Random(seed)
    out = []
    for _ in range(n):
        size = rng.choice((0, 1, 16, 30, 90, 700, 5000))
        out.append((rng.randrange(8), rng.random() < 0.5, rng.uniform(0, 600), rng.randbytes(size),
                    rng.uniform(1e-6, 1e-4) if rng.random() < 0.3 else None))
    return out


def _expected(records: list[tuple[int, bool, float, bytes, float | None]]) -> bytes:
    """The records as docs/capture-format.md lays them out (``<d t> <H link> <B dir> <B flags> <I n> [<d pitch>]``)."""
    out = b""
    for index, inbound, t, data, pitch in records:
        out += struct.pack("<dHBBI", t, index, int(inbound), 0 if pitch is None else FLAG_PITCH, len(data))
        out += b"" if pitch is None else struct.pack("<d", pitch)
        out += data
    return out


def test_records_are_the_documented_bytes_after_every_flush_and_at_close(tmp_path):
    path = tmp_path / "c.psnscap"
    w = CaptureWriter(path, {"scenario": "x"}, ["gyro", "uart1"])
    head = path.read_bytes()
    assert head.startswith(CAPTURE_MAGIC) and head.endswith(b"\n")
    records = _records(3, 400)
    rng = random.Random(1)
    for k, r in enumerate(records):
        w.write(*r)
        if rng.random() < 0.05:
            w.flush()  # what a reader sees after a flush: every record written so far
            assert path.read_bytes() == head + _expected(records[:k + 1])
    w.close()
    assert path.read_bytes() == head + _expected(records)
    w.close()  # twice: nothing more
    header, back = read_capture(path)
    assert header["links"] == ["gyro", "uart1"] and header["version"] == 2 and header["scenario"] == "x"
    assert [(r.link, r.direction, r.t_s, r.data, r.pitch_s) for r in back] == [
        (("gyro", "uart1")[i] if i < 2 else f"link{i}", "in" if inbound else "out", t, data, pitch)
        for i, inbound, t, data, pitch in records]
