"""PSNS frames: round trips, declarative specs, and the RS232 point budget."""

from dataclasses import fields

import pytest

from protocols.psns import (
    COMPASS_SPEC,
    POLARIZATION_OBS_SPEC,
    SOLAR_VECTOR_SPEC,
    CompassUnit,
    PolarizationPoint,
    PsnsFormat,
    PsnsHeader,
    encode_compass,
    encode_polarization_obs,
    encode_polarization_obs_columns,
    encode_solar_vector,
    max_points,
)
from protocols.stream import StreamDecoder, parse_one

H = PsnsHeader(seq=7, exposure_us=1000, latency_us=45000, status=1, count=0)


def test_obs_round_trip_and_spec():
    pts = (PolarizationPoint(1, 2, -8999, 65535, 4095), PolarizationPoint(2448, 2048, 9000, 0, 0))
    raw = encode_polarization_obs(H, pts)
    obs = parse_one(PsnsFormat(), raw)
    assert obs.points == pts and obs.header.count == 2 and obs.header.latency_us == 45000
    c = POLARIZATION_OBS_SPEC.parse(raw[5:-2])
    assert c.points[0].aop_cdeg == -8999 and c.points[1].x_px == 2448


def test_compass_and_solar_vector():
    units = tuple(CompassUnit(i, 100 * i - 400, 1000 * i) for i in range(9))
    raw = encode_compass(H, units)
    assert parse_one(PsnsFormat(), raw).units == units
    assert COMPASS_SPEC.parse(raw[5:-2]).count == 9
    sv = parse_one(PsnsFormat(), encode_solar_vector(H, (0.5, -0.25, 0.75), 0.01))
    assert sv.s == (0.5, -0.25, 0.75) and sv.quality == pytest.approx(0.01)
    assert SOLAR_VECTOR_SPEC.sizeof() == 13 + 16


def test_stream_with_noise():
    raw = encode_polarization_obs(H, [PolarizationPoint(10, 10, 0, 30000, 2000)] * 50)
    dec = StreamDecoder([PsnsFormat()])
    out = dec.feed(b"\xeb\x90\x77" + raw[:100]) + dec.feed(raw[100:] + raw)
    assert len(out) == 2 and dec.stats.length_errors >= 1


def test_max_points_on_rs232_115200():
    # 11520 B/s; at 5 Hz 2304 B per frame -> (2304 - 7 - 13) // 10 = 228 points
    assert max_points(115200, 5.0) == 228
    assert max_points(115200, 10.0) == 113
    assert max_points(115200, 1.0) == 1150


def test_length_must_agree_with_count_so_corrupt_lengths_fail_fast():
    raw = bytearray(encode_polarization_obs(H, [PolarizationPoint(10, 10, 0, 30000, 2000)] * 3))
    fmt = PsnsFormat()
    assert fmt.frame_length(raw, 0) == len(raw)
    raw[4] = 0x0A  # length 43 -> 2603 = 13 + 10 * 259: plausible alone, but count says 3
    assert fmt.frame_length(bytearray(raw[:17]), 0) == -1  # needs the count at bytes 16-17
    assert fmt.frame_length(raw, 0) == -2
    raw[4] = 0x20  # length 8235: not 13 + a multiple of 10, refused from the header alone
    assert fmt.frame_length(bytearray(raw[:5]), 0) == -2
    sv = bytearray(encode_solar_vector(H, (0.0, 0.0, 1.0), 0.5))
    sv[3] += 1
    assert fmt.frame_length(sv, 0) < 0


def test_every_frame_type_reencodes():
    from protocols.psns import encode_psns

    for raw in (encode_polarization_obs(H, [PolarizationPoint(1, 2, 3, 4, 5)]),
                encode_compass(H, [CompassUnit(0, 1, 2)]), encode_solar_vector(H, (0.5, 0.25, -0.75), 0.125)):
        assert encode_psns(parse_one(PsnsFormat(), raw)) == raw


@pytest.mark.parametrize("rate_hz, expected", [(1, 1150), (2, 574), (5, 228), (10, 113), (20, 55), (25, 44), (50, 21)])
def test_max_points_table_of_the_icd(rate_hz, expected):
    from protocols.psns import frame_bytes_obs

    n = max_points(115200, rate_hz)
    assert n == expected
    assert frame_bytes_obs(n) * 10 * rate_hz <= 115200 < frame_bytes_obs(n + 1) * 10 * rate_hz


def test_obs_from_columns_is_the_obs_from_points():
    """``encode_polarization_obs_columns`` (the camera's path: no point objects) gives the bytes of
    ``encode_polarization_obs`` on the same points, full range of every field included, and refuses what the
    layout cannot hold or columns of different lengths."""
    import numpy as np

    rng = np.random.default_rng(5)
    n = 228
    cols = (rng.integers(1, 2449, n).tolist(), rng.integers(1, 2049, n).tolist(),
            rng.integers(-32768, 32768, n).tolist(), rng.integers(0, 65536, n).tolist(),
            rng.integers(0, 65536, n).tolist())
    for c in cols:
        c[:2] = [min(c), max(c)]
    pts = [PolarizationPoint(*p) for p in zip(*cols)]
    assert encode_polarization_obs_columns(H, *cols) == encode_polarization_obs(H, pts)
    assert parse_one(PsnsFormat(), encode_polarization_obs_columns(H, *cols)).points == tuple(pts)
    assert encode_polarization_obs_columns(H, [], [], [], [], []) == encode_polarization_obs(H, [])
    with pytest.raises(ValueError):
        encode_polarization_obs_columns(H, [1], [1], [40000], [0], [0])  # aop_cdeg is s16
    with pytest.raises(ValueError):
        encode_polarization_obs(H, [PolarizationPoint(1, 1, 40000, 0, 0)])  # the same refusal from objects
    with pytest.raises(ValueError, match="one length"):
        encode_polarization_obs_columns(H, [1, 2], [1], [0], [0], [0])


def test_columns_packer_is_refused_for_a_class_that_is_not_the_layout():
    from dataclasses import dataclass

    from protocols.codec import CODECS, StructCodec
    from protocols.psns import POINT_SPEC

    @dataclass(frozen=True)
    class Swapped:
        y_px: int
        x_px: int
        aop_cdeg: int
        dop: int
        intensity: int

    codec = StructCodec(POINT_SPEC, "PSNS_POINT_TEST")
    CODECS.remove(codec)  # a test's codec: not one of the registry's
    with pytest.raises(TypeError, match="not the spec's fields in order"):
        codec.columns_packer(Swapped)


def test_packed_points_are_the_points_of_the_objects_frame():
    """``PsnsFormat(packed_points=True)`` (the firmware's decoder, no point objects) decodes the same frames to
    ``PolarizationObsPacked``: its ``point_bytes`` are the frame's point records, ``.points`` the objects the
    plain decoder gives, ``point_bytes`` of the objects' frame the same bytes; the other messages and the
    refusals are unchanged, and ``encode_psns`` gives the frame back (performance.md 5.7, D-10.E9)."""
    import struct

    import numpy as np

    from protocols.psns import POINT_FIELDS, POINT_STRUCT_FORMAT, PolarizationObs, PolarizationObsPacked, encode_psns

    assert tuple(f.name for f in fields(PolarizationPoint)) == POINT_FIELDS
    rng = np.random.default_rng(11)
    for n in (0, 1, 3, 225, 228):
        cols = (rng.integers(1, 2449, n).tolist(), rng.integers(1, 2049, n).tolist(),
                rng.integers(-32768, 32768, n).tolist(), rng.integers(0, 65536, n).tolist(),
                rng.integers(0, 65536, n).tolist())
        raw = encode_polarization_obs_columns(H, *cols)
        objs = parse_one(PsnsFormat(), raw)
        packed = parse_one(PsnsFormat(packed_points=True), raw)
        assert type(objs) is PolarizationObs and type(packed) is PolarizationObsPacked
        assert packed.header == objs.header and packed.n_points == objs.n_points == n
        assert packed.point_bytes == raw[5 + 13:-2] == objs.point_bytes
        assert tuple(struct.iter_unpack(POINT_STRUCT_FORMAT, packed.point_bytes)) == tuple(zip(*cols))
        assert packed.points == objs.points
        assert encode_psns(packed) == encode_psns(objs) == raw
    for raw in (encode_compass(H, [CompassUnit(1, -3, 9)]), encode_solar_vector(H, (0.0, 0.6, 0.8), 1.5)):
        assert parse_one(PsnsFormat(packed_points=True), raw) == parse_one(PsnsFormat(), raw)
    bad = bytearray(encode_polarization_obs_columns(H, [1, 2], [1, 2], [0, 0], [0, 0], [0, 0]))
    bad[-3] ^= 0xFF  # a CRC error: refused by both
    for fmt in (PsnsFormat(), PsnsFormat(packed_points=True)):
        d = StreamDecoder([fmt])
        assert d.feed(bytes(bad)) == [] and d.stats.crc_errors == 1
