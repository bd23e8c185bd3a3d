"""The 1 Hz GNSS output set: NMEA and UBX views of one fix agree, with each other and with the peers."""

import datetime as dt

import pytest
from pyubx2 import UBXReader

from protocols.gnss import GnssFix, GnssOutputSet, build_epoch, gps_time_of_week_ms, nav_pvt_from_fix
from protocols.nmea import Gga, Gsa, NmeaFormat, Rmc, Vtg, Zda
from protocols.stream import StreamDecoder
from protocols.ubx import NavPvt, NavStatus, UbxFormat

UTC = dt.datetime(2019, 9, 18, 8, 14, 0, tzinfo=dt.UTC)
FIX = GnssFix(utc=UTC, lat_deg=39.979, lon_deg=116.339, height_m=50.0, geoid_sep_m=-8.5, vel_enu_mps=(3.0, -4.0, 0.5))


def test_gps_time_of_week():
    # 2019-09-18 is a Wednesday: 3 days + 08:14:00 + 18 leap seconds into the GPS week
    assert gps_time_of_week_ms(UTC) == (3 * 86400 + 8 * 3600 + 14 * 60 + 18) * 1000
    assert gps_time_of_week_ms(dt.datetime(1980, 1, 6, tzinfo=dt.UTC)) == 0  # GPS = UTC at the GPS epoch (no leap yet)


def test_default_set_is_rmc_vtg_gga_gsa_zda_and_consistent():
    out = StreamDecoder([NmeaFormat()]).feed(build_epoch(FIX))
    assert [type(o) for o in out] == [Rmc, Vtg, Gga, Gsa, Zda]
    rmc, vtg, gga, gsa, zda = out
    assert rmc.lat_deg == pytest.approx(39.979, abs=1e-7) and gga.lon_deg == pytest.approx(116.339, abs=1e-7)
    assert gga.altitude_msl_m == 58.5 and gga.geoid_sep_m == -8.5
    assert rmc.speed_mps == pytest.approx(5.0, abs=3e-4) and vtg.speed_mps == rmc.speed_mps
    assert rmc.course_deg == pytest.approx(143.13, abs=0.01) == vtg.course_true_deg  # atan2(3, -4)
    assert gsa.fix_type == 3 and gsa.sat_ids == FIX.sat_ids and gga.num_sats == 12
    assert zda.date == rmc.date == UTC.date() and zda.time_utc == gga.time_utc == dt.time(8, 14)


def test_ubx_set_agrees_with_nmea_and_pyubx2():
    raw = build_epoch(FIX, GnssOutputSet(nmea=("GGA",), ubx=("NAV-PVT", "NAV-STATUS")))
    gga, pvt, st = StreamDecoder([NmeaFormat(), UbxFormat()]).feed(raw)
    assert isinstance(pvt, NavPvt) and isinstance(st, NavStatus)
    assert pvt.lat * 1e-7 == pytest.approx(gga.lat_deg, abs=2e-7) and pvt.hMSL == 58500 and pvt.height == 50000
    assert (pvt.velN, pvt.velE, pvt.velD, pvt.gSpeed) == (-4000, 3000, -500, 5000)
    assert pvt.iTOW == st.iTOW and st.gpsFix == pvt.fixType == 3
    m = UBXReader.parse(raw[len(raw) - 124 : len(raw) - 24])
    assert m.identity == "NAV-PVT" and m.headMot == pytest.approx(143.13010, abs=1e-5)


def test_no_fix_epoch():
    out = StreamDecoder([NmeaFormat()]).feed(build_epoch(GnssFix(utc=UTC, lat_deg=0, lon_deg=0, height_m=0,
                                                                 fix_type=0)))
    rmc, vtg, gga, gsa, _zda = out
    assert not rmc.valid and gga.quality == 0 and gga.lat_deg is None and vtg.mode == "N" and gsa.fix_type == 1
    assert nav_pvt_from_fix(GnssFix(utc=UTC, lat_deg=0, lon_deg=0, height_m=0, fix_type=0)).flags & 1 == 0


def test_epoch_byte_budget_at_9600_baud():
    # docs/reference/wire-formats.md section 2.3: GGA+RMC+VTG+GSA+ZDA is ~330-350 bytes, ~0.35 s of each second
    # at 9600 8N1
    n = len(build_epoch(FIX))
    assert 280 <= n <= 350
    assert n * 10 / 9600 < 0.4


def test_output_set_validation():
    with pytest.raises(ValueError, match="GLL"):
        GnssOutputSet(nmea=("GLL",))
    with pytest.raises(ValueError, match=r"4\.1"):
        GnssOutputSet(version="4.1")
    with pytest.raises(ValueError):
        GnssOutputSet(rate_hz=0)


def test_gst_carries_the_receivers_estimate_and_agrees_with_pynmea2():
    """GST in an epoch: the fix's own estimate when given, else its accuracies (h_acc per axis, v_acc); the range RMS
    is the horizontal sigma over the HDOP; empty without a fix. Read back by pynmea2 (an independent parser)."""
    import pynmea2

    from protocols.nmea import Gst

    utc = dt.datetime(2024, 3, 1, 12, 0, 1, tzinfo=dt.UTC)
    out = GnssOutputSet(nmea=("GGA", "GST"))
    fix = GnssFix(utc=utc, lat_deg=40.0, lon_deg=116.0, height_m=50.0, hdop=2.0, gst_std_m=(9.0, 12.0, 20.0))
    lines = build_epoch(fix, out).decode().split("\r\n")
    msg = pynmea2.parse(lines[1])
    assert (float(msg.std_dev_latitude), float(msg.std_dev_longitude), float(msg.std_dev_altitude)) == (9.0, 12.0, 20.0)
    assert float(msg.rms) == pytest.approx(15.0 / 2.0, abs=0.05)
    assert (float(msg.std_dev_major), float(msg.std_dev_minor), float(msg.orientation)) == (12.0, 9.0, 90.0)
    plain = GnssFix(utc=utc, lat_deg=40.0, lon_deg=116.0, height_m=50.0, h_acc_m=5.0, v_acc_m=7.5)
    parsed = StreamDecoder([NmeaFormat()]).feed(build_epoch(plain, out))
    gst = [m for m in parsed if isinstance(m, Gst)]
    assert len(gst) == 1 and gst[0].lat_m == pytest.approx(3.5) and gst[0].alt_m == 7.5
    none = GnssFix(utc=utc, lat_deg=0.0, lon_deg=0.0, height_m=0.0, fix_type=0, quality=0)
    assert build_epoch(none, GnssOutputSet(nmea=("GST",))).startswith(b"$GPGST,120001.00,,,,,,,*")
