"""Equivalence cases of the fast paths of ``protocols`` and their references.

Every fast path sits next to its reference under one naming scheme (``<name>_fast`` beside ``<name>``, same
module): the derived ``struct`` codecs beside ``construct`` (:meth:`StructCodec.decode_fast` /
:meth:`StructCodec.decode`, :meth:`StructCodec.encode_fast` / :meth:`StructCodec.encode`, and every generated
dataclass decoder or encoder, :attr:`Binding.call_fast` / :meth:`Binding.call`), the StreamDecoder's one-format
scanner and one-frame shortcut beside its reference scanner (``StreamDecoder._scan_fast`` / ``_scan``, switched
by ``fast_paths``), ``crc32_mpeg2_fast`` / ``crc32_mpeg2``, ``crc8_stim_fast`` / ``crc8_stim`` (remembered) and
``sentence_ok_fast`` / ``sentence_ok``.

:data:`CASES` is a list of ``pytest.param(reference, fast, inputs, id=...)``: ``reference(*args) == fast(*args)``
must hold for every argument tuple in ``inputs``.
"""

from __future__ import annotations

import datetime as dt
import math
import random
from collections.abc import Callable, Sequence
from dataclasses import fields
from typing import Any

import pytest

from protocols.codec import CODECS, Binding, StructCodec
from protocols.crc import CRC8_MEMO_GENERATION, crc8_stim, crc8_stim_fast, crc16_ccitt, crc32_mpeg2, crc32_mpeg2_fast
from protocols.gnss import GnssFix, GnssOutputSet, build_epoch
from protocols.host import HostFormat, NavSolution, encode_nav_solution
from protocols.imu_frame import FpgaFrameFormat, ImuFrame, ImuFrameFormat, MagFrame, encode_mag_frame
from protocols.monitor import MonitorFormat, MonitorRecord, encode_monitor
from protocols.nmea import NmeaFormat, sentence_ok, sentence_ok_fast
from protocols.stim import Stim210Format, Stim300Datagram, Stim300Format, StimDatagram
from protocols.stream import BAD_LENGTH, NEED_MORE, FrameFormat, StreamDecoder
from protocols.ubx import UbxFormat

__all__ = ["CASES"]

_RNG = random.Random(20261201)


# -- StreamDecoder -------------------------------------------------------------------------------------------
def _run_stream(fast_paths: bool) -> Callable[[Callable[[], Sequence[FrameFormat]], list[bytes]], tuple[Any, ...]]:
    def run(formats: Callable[[], Sequence[FrameFormat]], chunks: list[bytes]) -> tuple[Any, ...]:
        dec = StreamDecoder(formats(), fast_paths=fast_paths)
        out = [f for c in chunks for f in dec.feed(c)]
        return out, dec.stats.as_dict(), dec.pending()

    run.__name__ = "decode_stream_fast" if fast_paths else "decode_stream"
    return run


class _Tlv:
    """A small format for the cases: 0xC3 0x3C, length byte, payload, CRC-16; payload 'bad' fails to parse."""

    name = "tlv"
    sync = b"\xc3\x3c"

    def frame_length(self, buf: bytes | bytearray, start: int) -> int:
        if len(buf) - start < 3:
            return NEED_MORE
        n = buf[start + 2]
        return 5 + n if n <= 32 else BAD_LENGTH

    def check(self, frame: bytes) -> bool:
        return crc16_ccitt(frame[:-2]) == int.from_bytes(frame[-2:], "little")

    def parse(self, frame: bytes) -> bytes:
        p = bytes(frame[3:-2])
        if p == b"bad":
            raise ValueError("bad payload")
        return p


def _tlv(payload: bytes) -> bytes:
    body = b"\xc3\x3c" + bytes((len(payload),)) + payload
    return body + crc16_ccitt(body).to_bytes(2, "little")


def _damaged(frames: list[bytes], rng: random.Random) -> list[bytes]:
    """The frames as chunks: some with a flipped bit, some split in two, some joined, some with garbage."""
    chunks: list[bytes] = []
    for f in frames:
        r = rng.random()
        if r < 0.05:
            i = rng.randrange(len(f))
            f = f[:i] + bytes((f[i] ^ (1 << rng.randrange(8)),)) + f[i + 1 :]
        elif r < 0.1:
            i = rng.randrange(1, len(f))
            chunks.append(f[:i])
            f = f[i:]
        elif r < 0.13 and chunks:
            f = chunks.pop() + f
        elif r < 0.15:
            f = bytes(rng.randrange(256) for _ in range(rng.randrange(1, 9))) + f
        chunks.append(f)
    return chunks


def _stream_inputs() -> list[tuple[Any, ...]]:
    rng = _RNG
    imu = ImuFrameFormat()
    imu_frames = [imu.build(ImuFrame(k, 5000 * k, 0, 0, (rng.randrange(-2**23, 2**23), -k, k), 0, k & 255, 500,
                                     (k, 2 * k, -3 * k), 0x10)) for k in range(300)]
    mag_frames = [encode_mag_frame(MagFrame(k, 5000 * k, (k, -k, 100 * k), 0)) for k in range(60)]
    fpga_frames = imu_frames[:150] + mag_frames + imu_frames[150:]
    good = _tlv(b"hello")
    tlv_chunks = [good, good, good[:-1] + bytes((good[-1] ^ 0xFF,)), good, _tlv(b"bad"), b"\x00\x01garbage", good,
                  good[:4], good[4:], good + good, _tlv(b""), _tlv(b"x" * 32), good]
    host_frames = [encode_nav_solution(NavSolution(k, 0.01 * k, 39.9, 116.3, 50.0, (1.0, 2.0, 0.5), 1.0, 2.0, 30.0,
                                                   (0.5,) * 9, 6, 1, 0, 10.0, 0, variant_mode=(k % 3) or None))
                   for k in range(200)]
    stim210 = Stim210Format("m")
    stim_frames = [stim210.build(StimDatagram(0xA5, (k, -k, 3 * k), 0, (10 * k) & 0xFF, 516)) for k in range(300)]
    stim300 = Stim300Format(0x93)
    s300 = [stim300.build(Stim300Datagram(0x93, (k, -k, 3 * k), 0, (10 * k) & 0xFF, 516, (1, 2, k), 0, (3, 4, -k), 0))
            for k in range(200)]
    t0 = dt.datetime(2019, 9, 18, 8, 14, 0, tzinfo=dt.UTC)
    epochs = [build_epoch(GnssFix(utc=t0 + dt.timedelta(seconds=k), lat_deg=39.9 + 1e-5 * k, lon_deg=116.3,
                                  height_m=50.0), GnssOutputSet(ubx=("NAV-PVT", "NAV-STATUS"))) for k in range(30)]
    records = [encode_monitor(MonitorRecord(k % 9, k & 1, 1000 * k, f)) for k, f in enumerate(imu_frames[:100])]
    return [
        (lambda: [ImuFrameFormat()], imu_frames),  # one frame per chunk: the one-frame shortcut
        (lambda: [ImuFrameFormat()], _damaged(imu_frames, rng)),
        (lambda: [FpgaFrameFormat()], _damaged(fpga_frames, rng)),
        (lambda: [_Tlv()], tlv_chunks),
        (lambda: [HostFormat()], host_frames),
        (lambda: [HostFormat()], _damaged(host_frames, rng)),
        (lambda: [Stim210Format("m")], _damaged(stim_frames, rng)),
        (lambda: [Stim300Format(0x93)], _damaged(s300, rng)),
        (lambda: [NmeaFormat(), UbxFormat()], _damaged(epochs, rng)),  # two formats: the reference either way
        (lambda: [UbxFormat()], [b"".join(epochs)[i : i + 256] for i in range(0, len(b"".join(epochs)), 256)]),
        (lambda: [MonitorFormat()], _damaged(records, rng)),
    ]


# -- codecs and their dataclass bindings ------------------------------------------------------------------
def _values(codec: StructCodec, rng: random.Random) -> dict[str, Any]:
    """Random in-range values of every field (NaN-free, so == compares)."""
    raw = bytearray(rng.randrange(256) for _ in range(codec.size))
    for off, const in codec.constants:
        raw[off : off + len(const)] = const
    v = codec.decode(bytes(raw))
    return {k: tuple(_no_nan(y) for y in x) if isinstance(x, tuple) else _no_nan(x) for k, x in v.items()}


def _no_nan(x: Any) -> Any:
    return 0.5 if isinstance(x, float) and math.isnan(x) else x


def _object(b: Binding, wire: dict[str, Any]) -> Any:
    """An instance of the binding's dataclass whose encoding is ``wire`` (see test_derived_codecs)."""
    decoders = [d for d in b.codec.bindings if d.direction == "decode" and d.cls is b.cls]
    attrs: dict[str, Any] = {f.name: None for f in fields(b.cls) if f.init}
    for cname, (sname, conv) in b.fields.items():
        candidates = [wire[sname]] + [d.fields[cname][1](wire[sname]) for d in decoders  # type: ignore[misc]
                                      if cname in d.fields and d.fields[cname][1] is not None]
        attrs[cname] = next(x for x in candidates if conv is None or conv(x) == wire[sname])
    return b.cls(**attrs)


def _codec_cases() -> list[Any]:
    cases = []
    for codec in CODECS:
        rng = random.Random(codec.name)
        values = [_values(codec, rng) for _ in range(8)]
        raws = [codec.encode(v) for v in values]
        cases.append(pytest.param(codec.decode, codec.decode_fast, [(r, 0) for r in raws], id=f"{codec.name}-decode"))
        cases.append(pytest.param(codec.encode, codec.encode_fast, [(v,) for v in values], id=f"{codec.name}-encode"))
        for k, b in enumerate(codec.bindings):
            if b.direction == "decode":
                inputs = [(r, 0, *([None] * len(b.params))) for r in raws]
            elif b.direction == "decode_all":
                inputs = [(b"".join(raws[:n]), *([None] * len(b.params))) for n in range(len(raws))]
            else:
                objs = [_object(b, {**v, **b.fixed}) for v in values]
                if b.direction == "encode":
                    inputs = [(o,) for o in objs]
                elif b.direction == "encode_all":
                    inputs = [(objs[:n],) for n in range(len(objs))]
                else:
                    inputs = [tuple(getattr(o, p) for p in b.params) for o in objs]
            name = f"{codec.name}-{b.direction}-{b.cls.__name__}-{k}"
            cases.append(pytest.param(b.call, b.call_fast, inputs, id=name))
    return cases


# -- checksums -------------------------------------------------------------------------------------------------
def _crc_inputs() -> list[tuple[Any, ...]]:
    rng = random.Random(32)
    data = [bytes(rng.randrange(256) for _ in range(n)) for n in [*range(40), 63, 64, 255, 1000]]
    return [(d,) for d in data] + [(d, 0x12345678) for d in data[::5]]


def _crc8_inputs() -> list[tuple[Any, ...]]:
    """Datagram-sized byte strings as the gyro, the FPGA and the recorder check them: each new one, then again
    (a new object of the same bytes), the one before, one from more than a memo generation ago (the older
    generation or computed anew), the same bytes as ``bytearray`` and ``memoryview`` and with other ``init``
    values (both computed); the catalogue check and lengths 0-40 first."""
    rng = random.Random(8)
    out: list[tuple[Any, ...]] = [(b"123456789",), (b"123456789",), (b"123456789", 0x00)]
    out += [(bytes(rng.randrange(256) for _ in range(n)),) for n in range(41)]
    seen: list[bytes] = []
    for i in range(3 * CRC8_MEMO_GENERATION):
        d = bytes(rng.randrange(256) for _ in range(rng.choice((15, 16, 21))))
        seen.append(d)
        out += [(d,), (bytes(bytearray(d)),)]
        if i:
            out.append((seen[i - 1],))
        if i > 300:
            out.append((seen[i - 300],))
        if i % 50 == 0:
            out += [(bytearray(d),), (memoryview(d),), (d, 0x00), (d, 0xA5), (d[:-1] + bytes((d[-1] ^ 1,)),)]
    return out


def _sentence_inputs() -> list[tuple[bytes]]:
    fix = GnssFix(utc=dt.datetime(2019, 9, 18, 8, 14, 3, tzinfo=dt.UTC), lat_deg=39.979, lon_deg=116.339,
                  height_m=50.0)
    good = [s + b"\n" for s in build_epoch(fix).split(b"\n") if s]
    rng = random.Random(183)
    out = list(good)
    for s in good:
        for _ in range(5):
            i = rng.randrange(1, len(s))
            out.append(s[:i] + bytes((s[i] ^ (1 << rng.randrange(8)),)) + s[i + 1 :])
        out.append(s[:-6] + s[-6:].lower())
    out += [b"$GPGGA*00\r\n", b"$X*zz\r\n", b"$" + b"A" * 900 + b"*41\r\n"]
    return [(s,) for s in out]


CASES = [
    pytest.param(_run_stream(False), _run_stream(True), _stream_inputs(), id="StreamDecoder-scan"),
    pytest.param(crc32_mpeg2, crc32_mpeg2_fast, _crc_inputs(), id="crc32_mpeg2"),
    pytest.param(crc8_stim, crc8_stim_fast, _crc8_inputs(), id="crc8_stim"),
    pytest.param(sentence_ok, sentence_ok_fast, _sentence_inputs(), id="nmea-sentence_ok"),
    *_codec_cases(),
]
