"""Golden vectors (tests/vectors/) asserted both ways, and damaged captures with their expected counts."""

import json

import pytest

from protocols.can_nav import decode_can_frame, decode_can_frames, encode_can_frames
from protocols.stim import (
    GYRO_RATE_LSB_DPS,
    INCL_LSB_G,
    STIM300_ACCEL_LSB_G,
    TEMP_LSB_DEGC,
    utility_mode_crc,
)
from protocols.stream import StreamDecoder, parse_one
from tests.protocols.vectorlib import DAMAGED, VECTORS, from_json, load_vector, make_format, read_hex, vector_names

FRAME_VECTORS = [n for n in vector_names() if json.loads((VECTORS / f"{n}.json").read_text())["format"] in
                 ("stim210", "stim300", "imu", "fpga", "nmea", "host-text", "ubx", "psns", "monitor", "host")]
DAMAGED_VECTORS = vector_names(DAMAGED)


def test_every_frame_family_has_vectors():
    formats = {json.loads(p.read_text())["format"] for p in VECTORS.glob("*.json")}
    assert formats >= {"stim210", "stim300", "stim-utility", "imu", "fpga", "nmea", "host-text", "ubx", "psns",
                       "monitor", "host", "can"}
    kinds = {f["__type__"] for n in FRAME_VECTORS for f in json.loads((VECTORS / f"{n}.json").read_text())["frames"]}
    assert kinds >= {"StimDatagram", "Stim300Datagram", "ImuFrame", "MagFrame", "Gga", "Rmc", "Vtg", "Gsa", "Zda",
                     "NavText", "NavPvt", "NavStatus", "PolarizationObs", "CompassFrame", "SolarVectorFrame",
                     "MonitorRecord", "NavSolution", "HostStatus", "Ack", "ResetFilter", "SelectVariant",
                     "SetOutputRate", "RequestStatus"}
    assert len(DAMAGED_VECTORS) >= 15


@pytest.mark.parametrize("name", FRAME_VECTORS)
def test_vector_decodes_to_its_values_and_reencodes_to_its_bytes(name):
    meta, data = load_vector(VECTORS / f"{name}.json")
    assert (VECTORS / f"{name}.hex").read_text().startswith("#"), "hex file needs its provenance header"
    assert meta["provenance"]
    expected = [from_json(f) for f in meta["frames"]]
    fmt = make_format(meta["format"], meta["config"])
    # decode(b) == v, through the streaming decoder, whole and byte by byte
    dec = StreamDecoder([fmt])
    assert dec.feed(data) == expected
    assert dec.pending() == 0 and dec.stats.garbage_bytes == 0
    dec = StreamDecoder([make_format(meta["format"], meta["config"])])
    assert [f for i in range(len(data)) for f in dec.feed(data[i : i + 1])] == expected
    # encode(decode(b)) == b
    assert b"".join(fmt.encode(v) for v in expected) == data
    # decode(encode(v)) == v, one frame at a time with the strict parser
    for v in expected:
        assert parse_one(fmt, fmt.encode(v)) == v


@pytest.mark.parametrize("name", DAMAGED_VECTORS)
@pytest.mark.parametrize("chunk", [1, 7, 4096])
def test_damaged_capture_gives_expected_counts(name, chunk):
    meta, data = load_vector(DAMAGED / f"{name}.json")
    assert name.split("_", 1)[1] in ("bad_crc", "bad_checksum", "truncated", "bad_length", "noise_between_frames",
                                     "joined_midstream")
    dec = StreamDecoder([make_format(meta["format"], meta["config"])])
    out = [f for i in range(0, len(data), chunk) for f in dec.feed(data[i : i + chunk])]
    assert out == [from_json(f) for f in meta["frames"]]
    assert {k: getattr(dec.stats, k) for k in meta["expected_stats"]} == meta["expected_stats"]
    assert dec.stats.bytes_in == len(data)


def test_hand_vectors_carry_the_datasheet_scale_factors():
    meta, data = load_vector(VECTORS / "stim300_af_real_unit.json")
    d = from_json(meta["frames"][0])
    phys = meta["physical"]
    assert [w * GYRO_RATE_LSB_DPS for w in d.gyro] == phys["gyro_dps"]
    assert [w * STIM300_ACCEL_LSB_G[10] for w in d.accel] == phys["accel_g_10g_range"]
    assert [w * INCL_LSB_G for w in d.incl] == phys["incl_g"]
    assert [w * TEMP_LSB_DEGC for w in d.gyro_temp] == phys["gyro_temp_degc"]
    assert int.from_bytes(data[59:63], "big") == phys["crc32"] == 3326689990
    meta, _ = load_vector(VECTORS / "stim300_93_hand.json")
    d = from_json(meta["frames"][0])
    assert [w * GYRO_RATE_LSB_DPS for w in d.gyro] == meta["physical"]["gyro_dps"]
    assert [w * INCL_LSB_G for w in d.incl] == meta["physical"]["incl_g"]
    meta, _ = load_vector(VECTORS / "stim210_m_hand.json")
    d = from_json(meta["frames"][0])
    assert [w * GYRO_RATE_LSB_DPS for w in d.gyro] == meta["physical"]["gyro_dps"]


def test_stim_utility_mode_crc_examples():
    meta = json.loads((VECTORS / "stim300_utility_crc.json").read_text())
    data = read_hex(VECTORS / "stim300_utility_crc.hex")
    texts = [ln["text"].encode() for ln in meta["lines"]]
    assert data == b"".join(texts)
    for ln in meta["lines"]:
        assert utility_mode_crc(ln["text"]) == ln["crc8"]


def test_can_vector_both_ways():
    meta, data = load_vector(VECTORS / "can_nav_epoch.json")
    frames = [(int.from_bytes(data[i : i + 4], "big"), data[i + 4 : i + 12]) for i in range(0, len(data), 12)]
    nav = from_json(meta["nav_solution"])
    assert encode_can_frames(nav) == frames
    for (fid, payload), want in zip(frames, meta["frames"]):
        name, sig = decode_can_frame(fid, payload)
        assert (fid, name, sig) == (want["id"], want["message"], want["signals"])
    back = decode_can_frames(frames)
    assert encode_can_frames(back) == frames
