"""The NMEA field rules of :mod:`protocols.nmea`: what a field may hold, what is refused (a parse error), what is
read as absent (docs/icd.md, "NMEA sentences: parsed, used, counted")."""

from __future__ import annotations

import datetime as dt

import pytest

from protocols.crc import nmea_checksum
from protocols.nmea import NMEA_RX_MAX_LEN, Gga, NmeaFormat, Zda
from protocols.stream import StreamDecoder


def s(body: str) -> bytes:
    return f"${body}*{nmea_checksum(body.encode()):02X}\r\n".encode()


def decode(frame: bytes) -> tuple[list[object], StreamDecoder]:
    dec = StreamDecoder([NmeaFormat(NMEA_RX_MAX_LEN)])
    return dec.feed(frame), dec


def gga_time(t: str) -> bytes:
    return s(f"GPGGA,{t},4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,")


@pytest.mark.parametrize(("field", "want"), [
    ("123519", dt.time(12, 35, 19)), ("123519.00", dt.time(12, 35, 19)), ("000000.5", dt.time(0, 0, 0, 500000)),
    ("235959.999", dt.time(23, 59, 59, 999000)), ("081401.1234567", dt.time(8, 14, 1, 123456)),
    ("123519.", dt.time(12, 35, 19)),
    ("235960", dt.time(23, 59, 59, 999999)), ("235960.50", dt.time(23, 59, 59, 999999)),  # leap second, held
])
def test_time_field_accepted(field: str, want: dt.time) -> None:
    out, dec = decode(gga_time(field))
    assert len(out) == 1 and isinstance(out[0], Gga) and out[0].time_utc == want
    assert dec.stats.parse_errors == 0


@pytest.mark.parametrize("field", [
    "240000", "126019", "123561", "1235inf", "1235nan", "12351e300", "1235" + "9" * 40, "9" * 40, "-12351",
    "+12351", "1235 9", "12351", "123519.5e3", "123519.-5", "123519..5", "0x1234", "1_2351",
])
def test_time_field_refused(field: str) -> None:
    out, dec = decode(gga_time(field))
    assert out == [] and dec.stats.parse_errors == 1 and dec.stats.format_faults == 0


@pytest.mark.parametrize(("fields", "want"), [
    ("04,07,2002,00,00", (dt.date(2002, 7, 4), 0, 0)), ("29,02,2024,-05,30", (dt.date(2024, 2, 29), -5, 30)),
    ("31,12,1999,,", (dt.date(1999, 12, 31), None, None)), (",,,,", (None, None, None)),
    ("04,07,2002", (dt.date(2002, 7, 4), None, None)),  # the zone fields omitted
])
def test_zda_accepted(fields: str, want: tuple[object, ...]) -> None:
    out, dec = decode(s(f"GPZDA,201530.00,{fields}"))
    assert len(out) == 1 and isinstance(out[0], Zda), dec.stats
    assert (out[0].date, out[0].zone_hours, out[0].zone_minutes) == want


@pytest.mark.parametrize("fields", [
    "04,07," + "9" * 40 + ",00,00", "04,07,2147483648,00,00", "9" * 40 + ",07,2002,00,00", "04,13,2002,00,00",
    "00,07,2002,00,00", "30,02,2024,00,00", "04,07,0000,00,00", "04,07,02,00,00", "04,07,20021,00,00",
    "04,07,2002,14,00", "04,07,2002,00,60", "04,07,2002,99999,00", "04,,2002,00,00", "4e1,07,2002,00,00",
    "04,07,+200,00,00",
])
def test_zda_refused(fields: str) -> None:
    out, dec = decode(s(f"GPZDA,201530.00,{fields}"))
    assert out == [] and dec.stats.parse_errors == 1 and dec.stats.format_faults == 0


@pytest.mark.parametrize("date", ["32d394", "230394x", "2303", "-10394", "310294"])
def test_rmc_date_refused(date: str) -> None:
    out, dec = decode(s(f"GPRMC,123519.00,A,4807.038,N,01131.000,E,022.4,084.4,{date},003.1,W,A"))
    assert out == [] and dec.stats.parse_errors == 1


@pytest.mark.parametrize(("body", "talker", "kind"), [
    ("PGRME,15.0,M,45.0,M,25.0,M", "PGRM", "E"),  # five characters, still proprietary (not talker PG)
    ("PUBX,00,081350.00", "PUBX", ""), ("PSRFTXTVersion GSW3.2.2 ", "PSRF", "TXTVersion GSW3.2.2 "),
    ("LOG108,4,-1", "", "LOG108"), ("GPTXT,01,01,02,ANTSTATUS=OK", "GP", "TXT"),
])
def test_addresses(body: str, talker: str, kind: str) -> None:
    from protocols.nmea import NmeaSentence

    out, dec = decode(s(body))
    assert len(out) == 1 and isinstance(out[0], NmeaSentence), dec.stats
    assert (out[0].talker, out[0].kind) == (talker, kind)


@pytest.mark.parametrize("body", ["gpgga,1", "GP,1,2,3", "GPGGAXXXXXXX,1", "P\u00e9X,1", "XY Z,1"])
def test_bad_addresses_refused(body: str) -> None:
    dec = StreamDecoder([NmeaFormat(NMEA_RX_MAX_LEN)])
    raw = body.encode("utf-8")
    assert dec.feed(b"$" + raw + f"*{nmea_checksum(raw):02X}\r\n".encode()) == []
    assert dec.stats.parse_errors == 1


def test_a_stray_dollar_does_not_hold_ubx_back() -> None:
    """Lines up to NMEA_RX_MAX_LEN are accepted only when printable beyond 128 bytes: a stray '$' before binary UBX
    (NAV-PVT frames without a 0x0A byte) is refused at 128 bytes, as with the old limit, not held for 1024."""
    from protocols.ubx import UbxFormat
    from tests.fuzz.fuzz_inputs import seed_frames

    pvt = next(d for d in seed_frames(2.0)[3] if d.startswith(b"\xb5b") and b"\n" not in d)
    data = b"$" + pvt * 10
    dec = StreamDecoder([NmeaFormat(NMEA_RX_MAX_LEN), UbxFormat()])
    first = next(i + 16 for i in range(0, len(data), 16) if dec.feed(data[i : i + 16]))
    assert first <= 128 + 16  # without the rule: no UBX frame out of these 10 (1 001 bytes)
    dec.feed(data[first:])
    assert dec.stats.length_errors == 1 and dec.stats.per_format["ubx"] == 10
    # a long printable line is still waited for and taken ($PUBX,03 of 424 characters: the receiver corpus)
    line = s("PUBX,03,23," + ",".join(["014,U,067,31,42,010"] * 23))
    assert len(line) > 400
    dec = StreamDecoder([NmeaFormat(NMEA_RX_MAX_LEN)])
    assert len([o for i in range(0, len(line), 16) for o in dec.feed(line[i : i + 16])]) == 1
    # a long line with a binary byte in it is a length error, whatever the chunking
    bad = s("PUBX,03,23," + ",".join(["014,U,067,31,42,010"] * 10) + "\x01" + ",".join(["014,U,067,31,42,010"] * 10))
    for chunk in (1, 16, len(bad)):
        dec = StreamDecoder([NmeaFormat(NMEA_RX_MAX_LEN)])
        assert [o for i in range(0, len(bad), chunk) for o in dec.feed(bad[i : i + chunk])] == []
        assert dec.stats.length_errors == 1 and dec.stats.crc_errors == 0


def test_gst_parses_to_its_statistics_and_round_trips() -> None:
    from protocols.nmea import Gst, encode_nmea
    from protocols.nmea_build import build_gst

    frame = build_gst(dt.time(12, 0, 1, 500000), 5.2, 4.1, 3.0, 372.5, 4.0, 3.5, 7.2, "GN")
    assert frame == s("GNGST,120001.50,5.2,4.1,3.0,372.5,4.0,3.5,7.2")
    out, dec = decode(frame)
    assert dec.stats.parse_errors == 0
    assert out == [Gst("GN", dt.time(12, 0, 1, 500000), 5.2, 4.1, 3.0, 12.5, 4.0, 3.5, 7.2)]  # orientation mod 360
    assert encode_nmea(out[0]) == build_gst(dt.time(12, 0, 1, 500000), 5.2, 4.1, 3.0, 12.5, 4.0, 3.5, 7.2, "GN")
    # a receiver without a fix sends the fields empty; trailing fields may be omitted
    assert decode(s("GPGST,120002.00,,,,,,,"))[0] == [Gst("GP", dt.time(12, 0, 2), *([None] * 7))]
    assert decode(s("GPGST,120002.00,1.5"))[0] == [Gst("GP", dt.time(12, 0, 2), 1.5, *([None] * 6))]


@pytest.mark.parametrize("stats", [
    "inf,1,1,0,1,1,1", "1,1,1,0,nan,1,1", "1,1,1,0,-1.0,1,1", "1,1,1,inf,1,1,1", "1,1,1,0,1,1,1e999", "1,x,1,0,1,1,1",
])
def test_gst_refused(stats: str) -> None:
    out, dec = decode(s(f"GPGST,120001.00,{stats}"))
    assert out == [] and dec.stats.parse_errors == 1 and dec.stats.format_faults == 0
