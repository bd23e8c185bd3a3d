"""UBX NAV-PVT / NAV-STATUS against pyubx2 (an independent peer), both directions."""

import io

import pytest
from pyubx2 import GET, UBX_PROTOCOL, UBXMessage, UBXReader

from protocols.stream import StreamDecoder, parse_one
from protocols.ubx import (
    NAV_PVT_SPEC,
    NAV_STATUS_SPEC,
    NavPvt,
    NavStatus,
    UbxFormat,
    UbxFrame,
    build_ubx_frame,
    encode_nav_pvt,
    encode_nav_status,
)

PVT = NavPvt(iTOW=288243500, year=2019, month=9, day=18, hour=8, min=14, sec=3, valid=0x37, tAcc=25, nano=-12345,
             fixType=3, flags=0x01, flags2=0xE0, numSV=12, lon=-1163399877, lat=-399791235, height=32750, hMSL=41250,
             hAcc=2500, vAcc=4000, velN=2000, velE=-1000, velD=-100, gSpeed=2236, headMot=33343000, sAcc=100,
             headAcc=1500000, pDOP=144, flags3=0x0001, reserved0=0x01020304, headVeh=-17999999, magDec=-650, magAcc=100)
STATUS = NavStatus(iTOW=288243500, gpsFix=3, flags=0x0D, fixStat=0x01, flags2=0x08, ttff=28000, msss=61500)

# pyubx2 attribute -> (our field, scale that pyubx2 applies)
SCALED = {"lon": 1e-7, "lat": 1e-7, "headMot": 1e-5, "headAcc": 1e-5, "pDOP": 0.01, "headVeh": 1e-5, "magDec": 1e-2,
          "magAcc": 1e-2}


def test_our_nav_pvt_parses_in_pyubx2_to_the_same_values():
    raw = encode_nav_pvt(PVT)
    m = UBXReader.parse(raw, parsebitfield=0)
    assert m.identity == "NAV-PVT" and len(raw) == 100
    for name in NavPvt.__dataclass_fields__:
        ours = getattr(PVT, name)
        peer = getattr(m, "second" if name == "sec" else name)
        if isinstance(peer, bytes):  # bitfields when parsebitfield=0
            peer = int.from_bytes(peer, "little")
        if name in SCALED:
            assert round(peer / SCALED[name]) == ours, name
        else:
            assert peer == ours, name


def test_our_nav_status_parses_in_pyubx2():
    m = UBXReader.parse(encode_nav_status(STATUS), parsebitfield=0)
    assert (m.iTOW, m.gpsFix, m.ttff, m.msss) == (STATUS.iTOW, 3, 28000, 61500)
    assert int.from_bytes(m.flags, "little") == 0x0D and int.from_bytes(m.flags2, "little") == 0x08


def test_pyubx2_built_frames_decode_in_ours():
    # built with payload= (docs/reference/wire-formats.md section 2.4: scaled keyword values are truncated by pyubx2)
    pvt = UBXMessage("NAV", "NAV-PVT", GET, payload=encode_nav_pvt(PVT)[6:-2]).serialize()
    st = UBXMessage("NAV", "NAV-STATUS", GET, payload=encode_nav_status(STATUS)[6:-2]).serialize()
    poll = UBXMessage("CFG", "CFG-PRT", 2).serialize()  # a poll: empty payload, another class
    out = StreamDecoder([UbxFormat()]).feed(b"noise" + pvt + st + poll)
    assert out == [PVT, STATUS, UbxFrame(0x06, 0x00, b"")]
    assert pvt == encode_nav_pvt(PVT)  # byte for byte, header and checksum by pyubx2


def test_pyubx2_keyword_built_nav_pvt_agrees_within_one_lsb():
    m = UBXMessage("NAV", "NAV-PVT", GET, iTOW=1000, year=2024, month=6, day=21, hour=12, lat=39.8825,
                   lon=116.3986, headMot=333.43, numSV=12, fixType=3)
    d = parse_one(UbxFormat(), m.serialize())
    assert abs(d.lat - 398825000) <= 1 and abs(d.lon - 1163986000) <= 1
    assert abs(d.headMot - 33343000) <= 1  # pyubx2 truncates: 33342999


def test_stream_with_nmea_on_the_same_port_and_pyubx2_reader():
    import datetime as dt

    from protocols.nmea import NmeaFormat, build_gga

    gga = build_gga(dt.time(8, 14, 3), 39.979, 116.339, 41.0, -8.5)
    stream = gga + encode_nav_pvt(PVT) + gga + encode_nav_status(STATUS)
    out = StreamDecoder([NmeaFormat(), UbxFormat()]).feed(stream)
    assert [type(o).__name__ for o in out] == ["Gga", "NavPvt", "Gga", "NavStatus"]
    peer = [p.identity for _, p in UBXReader(io.BytesIO(stream), protfilter=UBX_PROTOCOL | 1)]
    assert peer == ["GPGGA", "NAV-PVT", "GPGGA", "NAV-STATUS"]


def test_header_checks_refuse_noise_quickly():
    fmt = UbxFormat()
    assert fmt.frame_length(bytearray(b"\xb5\x62\x77\x07\x5c\x00"), 0) < 0  # unknown class
    assert fmt.frame_length(bytearray(b"\xb5\x62\x01\x07\x55\x00"), 0) < 0  # NAV-PVT: 84 or >= 92 bytes
    assert fmt.frame_length(bytearray(b"\xb5\x62\x01\x07\x5b\x00"), 0) < 0
    assert fmt.frame_length(bytearray(b"\xb5\x62\x01\x07\x54\x00"), 0) == 84 + 8  # protocol 14 (u-blox 7)
    assert fmt.frame_length(bytearray(b"\xb5\x62\x01\x07\x64\x00"), 0) == 100 + 8  # a later, longer payload
    assert fmt.frame_length(bytearray(b"\xb5\x62\x01\x07\x5c\x00"), 0) == 100


def test_nav_pvt_of_every_protocol_version_is_parsed_by_its_prefix():
    """u-blox 7 (protocol 14: 84 bytes, the 92-byte layout up to pDOP then 6 reserved bytes), M8/F9 (92 bytes) and
    a later, longer payload (100 bytes) all give the same typed fields; the fields protocol 14 lacks are zero."""
    import dataclasses

    from protocols.ubx import NAV_PVT_PREFIX_V14

    fmt = UbxFormat()
    payload = encode_nav_pvt(PVT)[6:-2]
    assert NAV_PVT_PREFIX_V14 == 78  # iTOW .. pDOP (u-blox 7 receiver description, UBX-NAV-PVT)
    v14 = parse_one(fmt, build_ubx_frame(0x01, 0x07, payload[:78] + b"\xaa" * 6))  # reserved bytes need not be 0
    assert v14 == dataclasses.replace(PVT, flags3=0, reserved0=0, headVeh=0, magDec=0, magAcc=0)
    assert parse_one(fmt, build_ubx_frame(0x01, 0x07, payload)) == PVT
    assert parse_one(fmt, build_ubx_frame(0x01, 0x07, payload + bytes(range(8)))) == PVT


def test_specs_agree_with_struct_codec():
    raw = encode_nav_pvt(PVT)
    c = NAV_PVT_SPEC.parse(raw[6:-2])
    assert NAV_PVT_SPEC.sizeof() == 92 and NAV_STATUS_SPEC.sizeof() == 16
    assert all(c[k] == getattr(PVT, k) for k in NavPvt.__dataclass_fields__)


def test_out_of_range_field_is_a_value_error():
    import dataclasses

    with pytest.raises(ValueError):
        encode_nav_pvt(dataclasses.replace(PVT, numSV=256))
