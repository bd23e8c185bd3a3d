"""CAN navigation output: protocols/psns_nav.dbc through cantools, our struct codec, python-can's virtual bus."""

from pathlib import Path

import can
import cantools
import pytest

import protocols
from protocols.can_nav import (
    CAN_BITRATE,
    CAN_MESSAGES,
    can_frame_bits,
    can_signals_to_nav,
    dbc_text,
    decode_can_frame,
    decode_can_frames,
    encode_can_frames,
    nav_to_can_signals,
)
from protocols.host import NavSolution

DBC = Path(protocols.__file__).with_name("psns_nav.dbc")
NAV = NavSolution(seq=70000, time_s=3601.235, lat_deg=-39.97912345, lon_deg=116.33998765, height_m=-12.345,
                  vel_enu_mps=(-0.5, 12.25, -0.13), roll_deg=-1.5, pitch_deg=2.55, heading_deg=359.999,
                  sigma=(0.05, 0.05, 0.5, 0.03, 0.03, 0.06, 2.5, 2.5, 4.0), mode=6 | (1 << 8), gnss_status=1,
                  psns_status=2, cpu_load_pct=12.34, deadline_misses=5)


@pytest.fixture(scope="module")
def db():
    return cantools.database.load_file(DBC)


def test_committed_dbc_is_the_generated_one():
    assert DBC.read_text() == dbc_text()


def test_dbc_content(db):
    assert [m.name for m in db.messages] == [m.name for m in CAN_MESSAGES]
    for m, ours in zip(db.messages, CAN_MESSAGES):
        assert m.frame_id == ours.frame_id and m.is_extended_frame and m.length == 8
        assert m.cycle_time == ours.cycle_ms
        for s, o in zip(m.signals, ours.signals):
            assert (s.name, s.start, s.length, s.is_signed, s.byte_order) == (o.name, o.start, o.length, o.signed,
                                                                            "little_endian")
            assert s.scale == o.scale and s.unit == (o.unit or None)
    fast = [m for m in CAN_MESSAGES if m.cycle_ms == 10]
    assert {m.name for m in fast} == {"PSNS_NAV_TIME", "PSNS_NAV_POSITION", "PSNS_NAV_HEIGHT_MODE",
                                      "PSNS_NAV_VELOCITY", "PSNS_NAV_ATTITUDE"}  # 100 Hz


def test_cantools_and_our_codec_give_the_same_bytes(db):
    sig = nav_to_can_signals(NAV)
    frames = encode_can_frames(NAV)
    assert len(frames) == len(CAN_MESSAGES)
    for fid, data in frames:
        m = db.get_message_by_frame_id(fid)
        assert m.encode(sig[m.name]) == data
        raw = m.decode(data, scaling=False, decode_choices=False)
        ours = decode_can_frame(fid, data)[1]
        for s in m.signals:
            assert raw[s.name] * s.scale == pytest.approx(ours[s.name], abs=1e-12)
        assert m.decode(data, decode_choices=False) == pytest.approx(ours)


def test_round_trip_within_half_an_lsb():
    back = decode_can_frames(encode_can_frames(NAV))
    assert back.seq == NAV.seq and back.mode == NAV.mode and back.deadline_misses == 5
    assert back.lat_deg == pytest.approx(NAV.lat_deg, abs=0.5e-7)
    assert back.lon_deg == pytest.approx(NAV.lon_deg, abs=0.5e-7)
    assert back.height_m == pytest.approx(NAV.height_m, abs=0.5e-3)
    assert back.vel_enu_mps == pytest.approx(NAV.vel_enu_mps, abs=0.005)
    assert back.heading_deg == 0.0  # 359.999 deg rounds to 360.00 = 0.00 (modulo 360)
    assert back.pitch_deg == pytest.approx(2.55, abs=0.005)
    assert back.sigma == pytest.approx(NAV.sigma, abs=0.005)
    assert encode_can_frames(back) == encode_can_frames(NAV)  # decode(encode(v)) is a fixed point


def test_saturation_and_wrapping():
    import dataclasses

    wild = dataclasses.replace(NAV, seq=2**32 + 3, lat_deg=91.0, vel_enu_mps=(400.0, -400.0, float("nan")),
                               roll_deg=-181.0, sigma=(1e6,) * 9)
    back = decode_can_frames(encode_can_frames(wild))
    assert back.seq == 3 and back.lat_deg == 90.0 and back.vel_enu_mps == (327.67, -327.68, 0.0)
    assert back.roll_deg == -180.0 and back.sigma[0] == 65.535 and back.sigma[8] == 655.35


def test_incomplete_epoch_refused():
    with pytest.raises(ValueError, match="PSNS_NAV_DSP"):
        decode_can_frames(encode_can_frames(NAV, names=["PSNS_NAV_TIME", "PSNS_NAV_POSITION"]))
    with pytest.raises(ValueError):
        can_signals_to_nav({})
    with pytest.raises(ValueError):
        decode_can_frame(0x123, bytes(8))


def test_bus_load_budget():
    per_s = sum(1000 // m.cycle_ms for m in CAN_MESSAGES)
    bits = per_s * can_frame_bits()
    assert can_frame_bits(8, True, False) == 131  # extended frame, 8 data bytes, no stuffing, with IFS
    assert bits / CAN_BITRATE < 0.25


def test_frames_over_python_can_virtual_bus(db):
    with can.Bus(interface="virtual", channel="psns-nav-test", receive_own_messages=False) as tx, \
            can.Bus(interface="virtual", channel="psns-nav-test") as rx:
        for fid, data in encode_can_frames(NAV):
            tx.send(can.Message(arbitration_id=fid, data=data, is_extended_id=True))
        got = [rx.recv(timeout=1.0) for _ in CAN_MESSAGES]
    assert all(m is not None and m.is_extended_id for m in got)
    want = decode_can_frames(encode_can_frames(NAV))
    assert decode_can_frames((m.arbitration_id, bytes(m.data)) for m in got) == want
    assert db.decode_message(got[1].arbitration_id, got[1].data)["lat_deg"] == pytest.approx(NAV.lat_deg, abs=1e-7)
