"""Every derived ``struct`` codec agrees with its ``construct`` declaration, field by field, both ways.

For every :class:`~protocols.codec.StructCodec` in :data:`protocols.codec.CODECS` (each message that has a
derived codec, and every fixed part of a variable one) and every dataclass binding generated from it:

* on the bytes of every golden vector, at every offset, and on random bytes: the fast decode and
  ``construct``'s parse both refuse the bytes, or give the same value for every field; the generated
  dataclass decoders give every field the (converted) value ``construct`` parsed;
* encoding the decoded values with the derived ``struct`` and with ``construct`` gives the same bytes (the
  original bytes, NaN payloads apart), and the generated dataclass encoders give those bytes too;
* a value out of its field's range is refused by both.
"""

from __future__ import annotations

import math
from dataclasses import fields
from pathlib import Path
from typing import Any

import pytest
from construct import ConstructError
from hypothesis import given, settings
from hypothesis import strategies as st

import protocols.host
import protocols.imu_frame
import protocols.monitor
import protocols.psns
import protocols.stim
import protocols.ubx  # noqa: F401 - importing the modules registers their codecs
from protocols.codec import CODECS, Binding, StructCodec

VECTORS = Path(__file__).resolve().parents[1] / "vectors"
CODEC_IDS = [c.name for c in CODECS]


def _vector_bytes() -> bytes:
    out = bytearray()
    for p in sorted(VECTORS.rglob("*.hex")):
        for line in p.read_text().splitlines():
            line = line.split("#", 1)[0].strip()
            if line:
                out += bytes.fromhex(line)
    return bytes(out)


GOLDEN = _vector_bytes()
#: Codecs with constants whose layout the golden vectors hold (the constants must match somewhere).
IN_GOLDEN_VECTORS = {"IMU_FRAME", "IMU_FRAME_BODY", "MAG_FRAME", "MAG_FRAME_BODY", "STIM210_e", "STIM210_m",
                     "STIM210_p", "STIM210_s", "STIM300_90", "STIM300_93", "STIM300_A7", "STIM300_AF", "STIM300_F7"}


def _same(a: Any, b: Any) -> bool:
    """Equality with NaN equal to NaN (a float field may hold any bit pattern)."""
    if isinstance(a, tuple) and isinstance(b, tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return type(a) is type(b) and a == b


def _has_nan(values: dict[str, Any]) -> bool:
    flat = [x for v in values.values() for x in (v if isinstance(v, tuple) else (v,))]
    return any(isinstance(x, float) and math.isnan(x) for x in flat)


def _reference(codec: StructCodec, buf: bytes, off: int) -> dict[str, Any] | None:
    try:
        return codec.decode(buf, off)
    except ConstructError:
        return None


def _fast(codec: StructCodec, buf: bytes, off: int) -> dict[str, Any] | None:
    try:
        return codec.decode_fast(buf, off)
    except ValueError:
        return None


def _init_fields(b: Binding) -> list[str]:
    return [f.name for f in fields(b.cls) if f.init]


def _decode_binding(codec: StructCodec, b: Binding, buf: bytes, off: int) -> Any:
    """Call a generated dataclass decoder, with placeholders for the fields the spec does not carry."""
    if b.direction == "decode_all":
        rec = bytes(buf[off : off + codec.size])
        one, again = b.call_fast(rec + rec)
        assert one == again
        return one
    return b.call_fast(buf, off, *([None] * len(b.params)))


def _object_for(codec: StructCodec, b: Binding, wire: dict[str, Any]) -> dict[str, Any]:
    """Attribute values that the encoder binding ``b`` turns into the wire values ``wire``."""
    decoders = [d for d in codec.bindings if d.direction == "decode" and d.cls is b.cls]
    attrs: dict[str, Any] = {}
    for cname, (sname, conv) in b.fields.items():
        candidates = [wire[sname]] + [d.fields[cname][1](wire[sname]) for d in decoders  # type: ignore[misc]
                                      if cname in d.fields and d.fields[cname][1] is not None]
        attrs[cname] = next(x for x in candidates if conv is None or conv(x) == wire[sname])
    return attrs


def _check_bytes(codec: StructCodec, buf: bytes, off: int) -> bool:
    """One comparison at ``buf[off:]``; True when the bytes decode (both ways)."""
    ref = _reference(codec, buf, off)
    fast = _fast(codec, buf, off)
    assert (ref is None) == (fast is None), (codec, buf[off : off + codec.size].hex())
    if ref is None or fast is None:
        return False
    assert list(fast) == list(codec.names)
    for name in codec.names:
        assert _same(fast[name], ref[name]), (codec, name, fast[name], ref[name])
    raw = codec.encode(ref)
    assert codec.encode_fast(fast) == raw
    if not _has_nan(ref):
        assert raw == buf[off : off + codec.size]
    for b in codec.bindings:
        if b.direction.startswith("decode"):
            obj = _decode_binding(codec, b, buf, off)
            for cname, (sname, conv) in b.fields.items():
                want = ref[sname] if conv is None else conv(ref[sname])
                assert _same(getattr(obj, cname), want), (codec, b.cls.__name__, cname)
        elif not _has_nan(ref):
            attrs = _object_for(codec, b, ref)
            want = codec.encode({**ref, **b.fixed})
            if b.direction == "encode":
                obj = type("Obj", (), attrs)()
                assert b.call_fast(obj) == want, (codec, b.cls.__name__)
            elif b.direction == "encode_all":
                obj = type("Obj", (), attrs)()
                assert b.call_fast([obj, obj]) == want + want, (codec, b.cls.__name__)
                assert b.call_fast([]) == b""
            else:
                assert b.call_fast(*(attrs[p] for p in b.params)) == want, (codec, b.cls.__name__)
    return True


def test_every_codec_is_registered_and_bound():
    names = set(CODEC_IDS)
    assert {"NAV_SOLUTION", "STATUS", "ACK", "UBX_NAV_PVT", "UBX_NAV_STATUS", "IMU_FRAME", "MAG_FRAME",
            "PSNS_POINT", "PSNS_UNIT", "PSNS_SOLAR_VECTOR", "MONITOR_HEADER"} <= names
    assert len(names) == len(CODEC_IDS), "codec names must be unique"
    bound = {b.cls.__name__ for c in CODECS for b in c.bindings}
    assert {"NavSolution", "HostStatus", "Ack", "ResetFilter", "SelectVariant", "SetOutputRate", "RequestStatus",
            "NavPvt", "NavStatus", "ImuFrame", "MagFrame", "PsnsHeader", "PolarizationPoint", "CompassUnit",
            "SolarVectorFrame", "MonitorRecord"} <= bound


@pytest.mark.parametrize("codec", CODECS, ids=CODEC_IDS)
def test_codec_agrees_with_construct_on_the_golden_vectors(codec):
    # Every offset where the constants can match; without constants any bytes decode, so every 5th offset
    # (all alignments, a fifth of the time) is enough.
    offsets = range(0, len(GOLDEN) - codec.size + 1, 1 if codec.constants else 5)
    decoded = sum(_check_bytes(codec, GOLDEN, off) for off in offsets)
    if not codec.constants:
        assert decoded == len(offsets)
    elif codec.name in IN_GOLDEN_VECTORS:
        assert decoded >= 1, f"{codec.name}: no golden vector holds this layout"


@pytest.mark.parametrize("codec", CODECS, ids=CODEC_IDS)
@settings(max_examples=60, derandomize=True, deadline=None)
@given(data=st.data())
def test_codec_agrees_with_construct_on_random_bytes(codec, data):
    raw = bytearray(data.draw(st.binary(min_size=codec.size, max_size=codec.size)))
    for off, const in codec.constants:  # put the constants in place, so the rest is exercised
        raw[off : off + len(const)] = const
    assert _check_bytes(codec, bytes(raw), 0)
    # a random corruption either still decodes or is refused by both
    k = data.draw(st.integers(0, codec.size - 1))
    raw[k] ^= 0xFF
    _check_bytes(codec, bytes(raw), 0)


def _outcome(encode: Any, values: dict[str, Any], refusal: type[Exception]) -> bytes | None:
    try:
        out: bytes = encode(values)
    except refusal:
        return None
    return out


@pytest.mark.parametrize("codec", [c for c in CODECS if c.names], ids=[c.name for c in CODECS if c.names])
def test_out_of_range_values_are_refused_both_ways(codec):
    values = codec.decode_fast(codec.encode({n: _zero(codec, n) for n in codec.names}))
    for name, v in values.items():
        if isinstance(v, bytes):
            bad: list[Any] = [v + b"x", v[:-1]]
        elif isinstance(v, tuple):
            el = 1e300 if isinstance(v[0], float) else 1 << 70
            bad = [v + v[:1], v[:-1], (el, *v[1:]), (-el, *v[1:])]
        elif isinstance(v, float):
            bad = [1e300, -1e300, float("inf")]
        else:
            bad = [1 << 70, -(1 << 70), 1 << 24, -(1 << 23) - 1, 1 << 16, -1, 1.5, None]
        for x in bad:
            ref = _outcome(codec.encode, {**values, name: x}, ConstructError)
            fast = _outcome(codec.encode_fast, {**values, name: x}, ValueError)
            assert ref == fast, (codec, name, x)


def _zero(codec: StructCodec, name: str) -> Any:
    it = next(i for i in codec._items if i.name == name)
    if it.kind == "bytes":
        return bytes(it.count)
    return (0,) * it.count if it.kind.startswith("array") else 0
