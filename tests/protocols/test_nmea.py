"""NMEA GGA/RMC against pynmea2 (an independent peer), both directions."""

import datetime as dt
import io

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


# -- VTG, GSA, ZDA, proprietary ------------------------------------------------------------------
from protocols.nmea import Gsa, NmeaSentence, Vtg, Zda, build_gsa, build_vtg, build_zda, encode_nmea  # noqa: E402

D = dt.date(2019, 9, 18)


def test_vtg_gsa_zda_parse_in_pynmea2_to_same_values():
    vtg = pynmea2.parse(build_vtg(271.5, 5.0, "A", 275.25).decode().strip(), check=True)
    assert vtg.true_track == 271.5 and vtg.mag_track == 275.25 and vtg.faa_mode == "A"
    assert float(vtg.spd_over_grnd_kts) * 1852 / 3600 == pytest.approx(5.0, abs=3e-4)
    assert vtg.spd_over_grnd_kmph == pytest.approx(float(vtg.spd_over_grnd_kts) * 1.852, abs=5e-4)
    gsa = pynmea2.parse(build_gsa(3, [4, 5, None, 9, 12], 2.5, 1.3, 2.1).decode().strip(), check=True)
    assert (gsa.mode, gsa.mode_fix_type) == ("A", "3")
    assert [gsa.sv_id01, gsa.sv_id02, gsa.sv_id03, gsa.sv_id04, gsa.sv_id05, gsa.sv_id06] == ["04", "05", "", "09",
                                                                                            "12", ""]
    assert (float(gsa.pdop), float(gsa.hdop), float(gsa.vdop)) == (2.5, 1.3, 2.1)
    zda = pynmea2.parse(build_zda(T, D, -5, 30).decode().strip(), check=True)
    assert (zda.day, zda.month, zda.year, zda.local_zone, zda.local_zone_minutes) == (18, 9, 2019, -5, 30)
    assert zda.timestamp.replace(tzinfo=None) == T


def test_pynmea2_built_vtg_gsa_zda_decode_in_ours():
    vtg = pynmea2.VTG("GN", "VTG", ("77.52", "T", "", "M", "0.004", "N", "0.008", "K", "A"))
    gsa = pynmea2.GSA("GN", "GSA", ("A", "3", "10", "32", "", "", "", "", "", "", "", "", "", "", "1.94", "1.18",
                                    "1.54"))
    zda = pynmea2.ZDA("GP", "ZDA", ("201530.00", "04", "07", "2002", "00", "00"))
    out = StreamDecoder([NmeaFormat()]).feed("".join(m.render(newline=True) for m in (vtg, gsa, zda)).encode())
    assert out[0] == Vtg("GN", 77.52, None, pytest.approx(0.004 * 1852 / 3600), "A")
    assert out[1] == Gsa("GN", "A", 3, (10, 32) + (None,) * 10, 1.94, 1.18, 1.54)
    assert out[2] == Zda("GP", dt.time(20, 15, 30), dt.date(2002, 7, 4), 0, 0)


def test_pynmeagps_is_a_second_peer():
    # pyubx2's reader hands NMEA to pynmeagps, written independently of pynmea2
    # (docs/reference/wire-formats.md section 2.4)
    from pynmeagps import NMEAReader

    for raw in (build_gga(T, 39.979123456, -116.339987654, 41.25, -8.5), build_rmc(T, D, -33.5, 70.25, 5.0, 271.5),
                build_vtg(271.5, 5.0), build_zda(T, D, 0, 0), build_gsa(3, [4, 5, 9], 2.5, 1.3, 2.1)):
        m = NMEAReader.parse(raw)
        ours = parse_one(NmeaFormat(), raw)
        if m.msgID in ("GGA", "RMC"):
            assert m.lat == pytest.approx(ours.lat_deg, abs=1e-9) and m.lon == pytest.approx(ours.lon_deg, abs=1e-9)
        if m.msgID == "VTG":
            assert m.cogt == ours.course_true_deg
        if m.msgID == "ZDA":
            assert (m.day, m.month, m.year) == (18, 9, 2019)
        if m.msgID == "GSA":
            assert (m.PDOP, m.HDOP, m.VDOP) == (2.5, 1.3, 2.1)


@pytest.mark.parametrize("raw", [
    build_vtg(0.004, 0.0021), build_vtg(None, None, "N"), build_gsa(1, [], None, None, None),
    build_zda(T, D, None, None), build_rmc(T, D, 0, 0, 0, 0, valid=False), build_gga(T, 0, 0, 0, 0, quality=0),
])
def test_typed_sentences_reencode_byte_for_byte(raw):
    assert encode_nmea(parse_one(NmeaFormat(), raw)) == raw


def test_proprietary_and_unknown_sentences():
    raw = (b"$PUBX,00,081350.00,4717.113210,N,00833.915187,E,546.589,G3,2.1,2.0,0.007,77.52,0.007,,0.92,1.19,0.77,"
           b"9,0,0*5F\r\n")
    assert StreamDecoder([NmeaFormat()]).feed(raw) == []  # 111 characters: beyond the standard's 82
    s = parse_one(NmeaFormat(max_len=128), raw)
    assert (s.talker, s.kind) == ("PUBX", "") and isinstance(s, NmeaSentence) and s.fields[0] == "00"
    assert encode_nmea(s) == raw if len(raw) <= 82 else True
    from protocols.nmea import build_sentence

    gll = build_sentence("GP", "GLL", ["4717.11321", "N", "00833.91519", "E", "081350.00", "A", "A"])
    s = parse_one(NmeaFormat(), gll)
    assert (s.talker, s.kind, s.fields[:2]) == ("GP", "GLL", ("4717.11321", "N"))
    assert encode_nmea(s) == gll


def test_sentence_length_limit_is_enforced_both_ways():
    from protocols.nmea import build_sentence

    assert len(build_sentence("GP", "TXT", ["x" * 70])) == 82
    with pytest.raises(ValueError):
        build_sentence("GP", "TXT", ["x" * 71])
    dec = StreamDecoder([NmeaFormat()])
    assert dec.feed(b"$" + b"A" * 100 + b"\r\n" + build_zda(T, D)) != []
    assert dec.stats.length_errors == 1


def test_gsv_and_nmea_4_10_fields_round_trip_and_agree_with_pynmeagps():
    """GSV (4 satellites per sentence, GLONASS numbered 65-96) and the NMEA 4.10 fields (RMC navStatus, GSA systemId,
    GSV signalId) decode in ours and in pynmeagps, and re-encode byte for byte."""
    import datetime as dt

    from pynmeagps import NMEAReader

    from protocols.nmea import Gsa, Gsv, Rmc, build_gsa, build_gsv, build_rmc

    sats = [(65, 45, 120, 40), (66, 10, 300, None), (72, 80, 5, 33), (79, 20, 200, 30), (80, 5, 10, 21)]
    raw = build_gsv(sats, talker="GL", signal_id=1)
    raw += build_rmc(dt.time(8, 14, 0), dt.date(2019, 9, 18), 39.979, 116.339, 1.0, 30.0, talker="GN", nav_status="V")
    raw += build_gsa(3, [65, 66, 72, 79], 1.5, 0.9, 1.2, talker="GN", system_id=2)
    objs = StreamDecoder([NmeaFormat()]).feed(raw)
    assert [type(o) for o in objs] == [Gsv, Gsv, Rmc, Gsa]
    assert [s for o in objs[:2] for s in o.sats] == sats and objs[0].num_sv == 5 and objs[0].signal_id == 1
    assert objs[2].nav_status == "V" and objs[3].system_id == 2 and objs[3].sat_ids[:4] == (65, 66, 72, 79)
    assert b"".join(encode_nmea(o) for o in objs) == raw
    peer = [m for _, m in NMEAReader(io.BytesIO(raw))]
    assert [m.msgID for m in peer] == ["GSV", "GSV", "RMC", "GSA"]
    g = peer[0]
    assert (g.svid_01, g.elv_01, g.az_01, g.cno_01, int(g.signalID, 16)) == (65, 45, 120, 40, 1)
    assert peer[1].svid_01 == 80 and peer[2].navStatus == "V" and int(peer[3].systemId) == 2
    assert peer[3].svid_01 == 65


def test_lf_only_lines_are_accepted_and_counted_apart_from_crc_errors():
    """A sentence ended by LF alone (no CR) decodes like its CR LF twin and is counted in ``lf_only``; a corrupted
    one is still a CRC error; the reference scanner and the fast path count the same."""
    good = build_gga(T, 39.979, 116.339, 50.0, 0.0)
    lf = good[:-2] + b"\n"
    bad = lf[:10] + b"9" + lf[11:]
    for fast in (True, False):
        fmt = NmeaFormat()
        dec = StreamDecoder([fmt], fast_paths=fast)
        got = dec.feed(lf) + dec.feed(bad) + dec.feed(good) + dec.feed(lf + lf)
        assert got == [parse_one(NmeaFormat(), good)] * 4
        assert fmt.lf_only == 3 and dec.stats.crc_errors == 1
