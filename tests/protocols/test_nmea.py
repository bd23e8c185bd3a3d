"""NMEA GGA/RMC against pynmea2 (an independent peer), both directions."""

import datetime as dt

import pynmea2
import pytest

from protocols.nmea import Gga, NmeaFormat, Rmc, build_gga, build_rmc, format_lat, format_lon
from protocols.stream import StreamDecoder, parse_one

T = dt.time(8, 14, 3, 500000)


def test_gga_parses_in_pynmea2_to_same_values():
    raw = build_gga(T, 39.979123456, 116.339987654, 41.25, -8.5, quality=1, num_sats=12, hdop=0.8)
    msg = pynmea2.parse(raw.decode().strip(), check=True)
    assert msg.sentence_type == "GGA"
    assert msg.latitude == pytest.approx(39.979123456, abs=1e-7)  # 1e-5 arc-min resolution
    assert msg.longitude == pytest.approx(116.339987654, abs=1e-7)
    assert float(msg.altitude) == 41.25 and float(msg.geo_sep) == -8.5
    assert msg.timestamp.replace(tzinfo=None) == dt.time(8, 14, 3, 500000)


def test_rmc_parses_in_pynmea2_to_same_values():
    raw = build_rmc(T, dt.date(2019, 9, 18), -33.5, -70.25, 5.0, 271.5)
    msg = pynmea2.parse(raw.decode().strip(), check=True)
    assert msg.latitude == pytest.approx(-33.5) and msg.longitude == pytest.approx(-70.25)
    assert float(msg.spd_over_grnd) * 1852 / 3600 == pytest.approx(5.0, abs=3e-4)
    assert float(msg.true_course) == 271.5
    assert msg.datestamp == dt.date(2019, 9, 18)


def test_pynmea2_built_sentences_decode_in_ours():
    gga = pynmea2.GGA("GN", "GGA", ("081403.50", "3958.7400", "N", "11620.3400", "E", "1", "09", "1.1",
                                      "45.6", "M", "-8.0", "M", "", ""))
    rmc = pynmea2.RMC("GN", "RMC", ("081403.50", "A", "3958.7400", "N", "11620.3400", "E", "0.5", "90.0",
                                      "180919", "", "", "A"))
    dec = StreamDecoder([NmeaFormat()])
    out = dec.feed((gga.render(newline=True) + rmc.render(newline=True)).encode())
    assert isinstance(out[0], Gga) and isinstance(out[1], Rmc)
    assert out[0].lat_deg == pytest.approx(gga.latitude) and out[0].lon_deg == pytest.approx(gga.longitude)
    assert out[0].altitude_msl_m == 45.6 and out[0].num_sats == 9
    assert out[1].speed_mps == pytest.approx(0.5 * 1852 / 3600)
    assert out[1].date == dt.date(2019, 9, 18)


def test_format_lat_lon_rounding_carries_minutes():
    assert format_lat(39.99999999999) == ("4000.00000", "N")
    assert format_lon(-0.5) == ("00030.00000", "W")


def test_bad_checksum_counted_not_raised():
    good = build_gga(T, 10.0, 20.0, 1.0, 0.0)
    bad = bytearray(good)
    bad[10] ^= 0x01
    dec = StreamDecoder([NmeaFormat()])
    out = dec.feed(bytes(bad) + b"garbage\r\n" + good)
    assert len(out) == 1 and out[0].lat_deg == pytest.approx(10.0)
    assert dec.stats.crc_errors == 1


def test_strict_parse_of_good_sentence():
    assert isinstance(parse_one(NmeaFormat(), build_rmc(T, dt.date(2020, 1, 2), 1, 2, 0, 0)), Rmc)
