"""Receiver model details (issue 17): PPS 1 Hz at any rate, msss/ttff from start-up, GPS-UTC from the leap-second
table, no-fix accuracies; values checked in our decoder and in pyubx2."""

from __future__ import annotations

import asyncio
import datetime as dt
import io

import numpy as np
import pytest

from emulator.clock import EmulatorLoop
from emulator.devices.gnss import NO_FIX_ACC_M, GnssConfig, GnssOutage, GnssReceiver
from emulator.links import LineConfig, MemHub
from emulator.world.trajectory import StaticTrajectory
from protocols.gnss import GPS_EPOCH, gps_time_of_week_ms, gps_utc_offset_s
from protocols.nmea import Gga, NmeaFormat
from protocols.stream import StreamDecoder
from protocols.ubx import NavPvt, NavStatus, UbxFormat

EPOCH = dt.datetime(2019, 9, 18, 8, 14, tzinfo=dt.UTC)


def _run(cfg: GnssConfig, seconds: float, epoch: dt.datetime = EPOCH) -> tuple[GnssReceiver, list, list[float]]:
    loop = EmulatorLoop("fast")
    a, b = MemHub().pair("gnss", LineConfig(baud=460800), loop)
    pps: list[float] = []
    rx = GnssReceiver(a, StaticTrajectory(39.979, 116.339, 50.0), epoch, np.random.default_rng(1), cfg,
                      pps=pps.append)
    dec = StreamDecoder([NmeaFormat(), UbxFormat()])
    got: list = []
    b.on_receive = lambda d: got.extend((loop.time(), s) for s in dec.feed(d))

    async def main() -> None:
        rx.start()
        await asyncio.sleep(seconds)

    loop.run_until_complete(main())
    loop.close()
    assert dec.stats.crc_errors == 0
    return rx, got, pps


def test_pps_is_1_hz_at_a_10_hz_navigation_rate() -> None:
    cfg = GnssConfig(rate_hz=10.0, latency_s=0.02, ubx=("NAV-PVT",), sentences=("GGA",))
    rx, got, pps = _run(cfg, 5.05)
    ggas = [s for _, s in got if isinstance(s, Gga)]
    assert len(ggas) == 51  # 10 Hz epochs
    assert len(pps) == 6 == rx.pps_pulses  # t = 0..5: one pulse per whole second
    assert np.all(np.abs(np.array(pps) - np.arange(6)) < 1e-6)
    # the epochs sit on the 100 ms grid (no accumulated rounding)
    micros = {s.time_utc.microsecond for s in ggas}
    assert micros == {k * 100_000 for k in range(10)}


def test_msss_counts_from_start_up_and_ttff_is_the_first_fix() -> None:
    cfg = GnssConfig(ubx=("NAV-STATUS",), sentences=(), outages=(GnssOutage(0.0, 3.0),), reacquisition_s=0.5)
    _rx, got, _ = _run(cfg, 6.5)
    st = [s for _, s in got if isinstance(s, NavStatus)]
    assert [s.msss for s in st] == [k * 1000 for k in range(7)]
    # no fix in [0, 3.5): the first fix epoch is t = 4 s
    assert [s.ttff for s in st] == [0, 0, 0, 0, 4000, 4000, 4000]
    assert [s.gpsFix for s in st] == [0, 0, 0, 0, 3, 3, 3]


def test_no_fix_accuracies_are_reported_unknown() -> None:
    cfg = GnssConfig(ubx=("NAV-PVT",), sentences=(), outages=(GnssOutage(0.0, 2.0),), reacquisition_s=0.1)
    _rx, got, _ = _run(cfg, 3.5)
    pvt = [s for _, s in got if isinstance(s, NavPvt)]
    nofix, fix = pvt[0], pvt[-1]
    assert nofix.fixType == 0 and nofix.hAcc == nofix.vAcc == round(NO_FIX_ACC_M * 1e3) == 0xFFFFFFFF
    assert nofix.pDOP == 9999 and nofix.numSV == 0 and nofix.flags & 0x01 == 0
    assert fix.fixType == 3 and fix.hAcc < 20_000 and fix.pDOP < 500
    from pyubx2 import UBXReader

    from protocols.ubx import encode_nav_pvt

    peer = UBXReader.parse(encode_nav_pvt(nofix))
    assert peer.hAcc == 0xFFFFFFFF and peer.pDOP == pytest.approx(99.99)


@pytest.mark.parametrize(("utc", "leap"), [
    (dt.datetime(1980, 1, 6, tzinfo=dt.UTC), 0),
    (dt.datetime(1999, 6, 1, tzinfo=dt.UTC), 13),  # 13 s from 1999 to 2005
    (dt.datetime(2016, 3, 1, 12, tzinfo=dt.UTC), 17),  # before the 2016-12-31 leap second
    (dt.datetime(2016, 12, 31, 23, 59, 59, tzinfo=dt.UTC), 17),
    (dt.datetime(2017, 1, 1, tzinfo=dt.UTC), 18),
    (dt.datetime(2026, 1, 1, tzinfo=dt.UTC), 18),
])
def test_gps_utc_from_the_leap_second_table(utc: dt.datetime, leap: int) -> None:
    assert gps_utc_offset_s(utc) == leap
    # GPS time of week from first principles: seconds since the GPS epoch + leap, modulo one week
    want = (round((utc - GPS_EPOCH).total_seconds() * 1000) + leap * 1000) % (7 * 86_400_000)
    assert gps_time_of_week_ms(utc) == want


def test_a_2016_epoch_gives_the_itow_of_17_leap_seconds() -> None:
    epoch = dt.datetime(2016, 3, 1, 12, 0, 0, tzinfo=dt.UTC)
    _rx, got, _ = _run(GnssConfig(ubx=("NAV-PVT",), sentences=()), 0.5, epoch)
    pvt = next(s for _, s in got if isinstance(s, NavPvt))
    # 2016-03-01 is a Tuesday: 2 days + 12 h into the GPS week, plus 17 s
    assert pvt.iTOW == (2 * 86400 + 12 * 3600 + 17) * 1000
    from pyubx2 import UBXReader

    peer = next(m for _, m in UBXReader(io.BytesIO(bytes(__import__("protocols.ubx", fromlist=["x"]).encode_nav_pvt(
        pvt))), protfilter=2))
    assert peer.iTOW == pvt.iTOW


@pytest.mark.parametrize(("talker", "lo", "hi"), [("GL", 65, 96), ("GA", 1, 36), ("GB", 1, 63), ("GP", 1, 32)])
def test_satellite_numbers_follow_nmea_4_10_per_constellation(talker: str, lo: int, hi: int) -> None:
    from protocols.nmea import Gsa, Gsv

    cfg = GnssConfig(talker=talker, sentences=("GGA", "GSA", "GSV"), num_sats=10)
    _rx, got, _ = _run(cfg, 0.5)
    gsa = next(s for _, s in got if isinstance(s, Gsa))
    gsv = [s for _, s in got if isinstance(s, Gsv)]
    ids = [i for i in gsa.sat_ids if i is not None]
    assert len(ids) == 10 and all(lo <= i <= hi for i in ids)
    assert gsv and gsv[0].num_sv == 10 and sorted(s[0] for g in gsv for s in g.sats) == sorted(ids)
    assert all(g.talker == talker for g in gsv)


def test_multi_gnss_nmea_4_10_sends_gsa_and_gsv_per_system_and_pynmeagps_reads_them() -> None:
    from pynmeagps import NMEAReader

    from protocols.nmea import Gsa, Gsv, Rmc

    cfg = GnssConfig(talker="GN", nmea_version="4.10", sentences=("RMC", "GGA", "GSA", "GSV"), num_sats=12)
    loop = EmulatorLoop("fast")
    a, b = MemHub().pair("gnss", LineConfig(baud=460800), loop)
    rx = GnssReceiver(a, StaticTrajectory(39.979, 116.339, 50.0), EPOCH, np.random.default_rng(1), cfg)
    raw = bytearray()
    b.on_receive = raw.extend

    async def main() -> None:
        rx.start()
        await asyncio.sleep(0.5)

    loop.run_until_complete(main())
    loop.close()
    objs = StreamDecoder([NmeaFormat()]).feed(bytes(raw))
    gsa = [o for o in objs if isinstance(o, Gsa)]
    assert [g.system_id for g in gsa] == [1, 2]  # GPS, GLONASS
    assert all(i <= 32 for i in gsa[0].sat_ids if i) and all(65 <= i <= 96 for i in gsa[1].sat_ids if i)
    gsv = [o for o in objs if isinstance(o, Gsv)]
    assert {g.talker for g in gsv} == {"GP", "GL"} and all(g.signal_id == 1 for g in gsv)
    rmc = next(o for o in objs if isinstance(o, Rmc))
    assert rmc.nav_status == "V"
    peer = [m for _, m in NMEAReader(io.BytesIO(bytes(raw)))]
    assert [m.msgID for m in peer].count("GSV") == len(gsv) and peer[0].navStatus == "V"
