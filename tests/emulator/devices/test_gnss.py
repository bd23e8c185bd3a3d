"""GNSS receiver: error statistics, PPS, fix types, outages with re-acquisition, glitches."""

from __future__ import annotations

import asyncio
import datetime as dt
import math

import numpy as np
import pytest

from emulator.clock import EmulatorLoop
from emulator.devices.gnss import GnssConfig, GnssErrorModel, GnssErrors, GnssGlitch, GnssOutage, GnssReceiver
from emulator.links import LineConfig, MemHub
from emulator.world.trajectory import StaticTrajectory
from firmware_model import earth
from protocols.constants import DEG
from protocols.nmea import Gga, NmeaFormat, Rmc
from protocols.stream import StreamDecoder

EPOCH = dt.datetime(2019, 9, 18, 8, 14, tzinfo=dt.UTC)


def test_error_statistics_match_the_configured_sigma_within_10_percent():
    e = GnssErrors()
    m = GnssErrorModel(e, np.random.default_rng(2), batch=2000)
    pos, vel = [], []
    for _ in range(150):  # 2000 receivers x 150 epochs (each receiver spans half a correlation time)
        p, v = m.step(1.0)
        pos.append(p)
        vel.append(v)
    pos, vel = np.array(pos), np.array(vel)
    sd_p = pos.reshape(-1, 3).std(axis=0)
    sd_v = vel.reshape(-1, 3).std(axis=0)
    want_p = np.array([e.pos_sigma_h_m, e.pos_sigma_h_m, e.pos_sigma_v_m])
    want_v = np.array([e.vel_sigma_h_mps, e.vel_sigma_h_mps, e.vel_sigma_v_mps])
    assert np.all(np.abs(sd_p / want_p - 1) < 0.1)
    assert np.all(np.abs(sd_v / want_v - 1) < 0.1)
    # the paper's 95 % figures: 10 m horizontal radial, 15 m vertical
    radial = np.hypot(pos[..., 0], pos[..., 1]).ravel()
    assert abs(np.quantile(radial, 0.95) / 10.0 - 1) < 0.1
    assert abs(np.quantile(np.abs(pos[..., 2]).ravel(), 0.95) / 15.0 - 1) < 0.1
    # first-order Gauss-Markov: lag-1 correlation of the GM part exp(-1/300), white part decorrelates
    wf = e.pos_white_fraction
    r1 = np.mean(pos[1:, :, 0] * pos[:-1, :, 0]) / np.mean(pos[:, :, 0] ** 2)
    assert r1 == pytest.approx((1 - wf**2) * math.exp(-1 / e.pos_corr_time_s), abs=0.02)


def run_receiver(cfg, seconds, traj=None):
    loop = EmulatorLoop("fast")
    a, b = MemHub().pair("gnss", LineConfig(baud=9600), loop)
    traj = traj or StaticTrajectory(39.979, 116.339, 50.0)
    pps = []
    rx = GnssReceiver(a, traj, EPOCH, np.random.default_rng(1), cfg, pps=pps.append)
    dec = StreamDecoder([NmeaFormat()])
    got = []
    b.on_receive = lambda d: got.extend((loop.time(), s) for s in dec.feed(d))

    async def main():
        rx.start()
        await asyncio.sleep(seconds)

    loop.run_until_complete(main())
    loop.close()
    return rx, got, pps


def test_epochs_pps_and_fix_quality():
    cfg = GnssConfig(fix_quality=2, errors=GnssErrors(pps_jitter_ns=25.0))
    _rx, got, pps = run_receiver(cfg, 10.5)
    ggas = [s for _, s in got if isinstance(s, Gga)]
    rmcs = [s for _, s in got if isinstance(s, Rmc)]
    assert len(ggas) == len(rmcs) == 11 and len(pps) == 11
    assert all(g.quality == 2 for g in ggas) and all(r.mode == "D" for r in rmcs)
    jit = np.array(pps) - np.arange(11)
    assert np.all(np.abs(jit) < 200e-9) and np.any(jit != 0)


def test_outage_then_reacquisition_within_one_second():
    cfg = GnssConfig(outages=(GnssOutage(3.0, 4.0),), reacquisition_s=0.8)
    _rx, got, pps = run_receiver(cfg, 12.5)
    q = [(round(t - cfg.latency_s), s.quality) for t, s in got if isinstance(s, Gga)]
    lost = [t for t, qq in q if qq == 0]
    assert lost == [3, 4, 5, 6, 7]  # 7.0 is within the 0.8 s re-acquisition after the 7.0 end
    assert all(qq == 1 for t, qq in q if t >= 8)
    assert [round(p) for p in pps] == [0, 1, 2, 8, 9, 10, 11, 12]
    rmc_invalid = [s for _, s in got if isinstance(s, Rmc) and not s.valid]
    assert len(rmc_invalid) == 5


def test_glitch_jumps_the_position():
    cfg = GnssConfig(errors=GnssErrors(0.0, 0.0, 0.2, 300.0, 0.0, 0.0, 0.0),
                     glitches=(GnssGlitch(4.0, 2.0, (30.0, -20.0, 5.0)),))
    _rx, got, _ = run_receiver(cfg, 8.5)
    lat0, lon0 = 39.979 * DEG, 116.339 * DEG
    rm, rn = earth.radii(lat0)
    for t, s in got:
        if not isinstance(s, Gga):
            continue
        e = (s.lon_deg * DEG - lon0) * (rn + 50) * math.cos(lat0)
        n = (s.lat_deg * DEG - lat0) * (rm + 50)
        if 4 <= round(t) < 6:
            assert e == pytest.approx(30.0, abs=0.05) and n == pytest.approx(-20.0, abs=0.05)
            assert s.altitude_msl_m + s.geoid_sep_m == pytest.approx(55.0, abs=0.01)  # h = H + N (EGM96)
        else:
            assert abs(e) < 0.05 and abs(n) < 0.05


def test_full_nmea_set_and_ubx_nav_pvt_decode_in_ours_and_pyubx2():
    from pyubx2 import UBXReader

    from protocols.ubx import NavPvt, UbxFormat

    cfg = GnssConfig(sentences=("RMC", "VTG", "GGA", "GSA", "ZDA"), ubx=("NAV-PVT", "NAV-STATUS"),
                     errors=GnssErrors(pos_sigma_h_m=0.0, pos_sigma_v_m=0.0, vel_sigma_h_mps=0.0, vel_sigma_v_mps=0.0),
                     geoid_sep_m=-8.5)
    loop = EmulatorLoop("fast")
    a, b = MemHub().pair("gnss", LineConfig(baud=115200), loop)
    rx = GnssReceiver(a, StaticTrajectory(39.979, 116.339, 50.0), EPOCH, np.random.default_rng(1), cfg)
    raw = bytearray()
    b.on_receive = raw.extend

    async def main():
        rx.start()
        await asyncio.sleep(2.5)

    loop.run_until_complete(main())
    loop.close()
    dec = StreamDecoder([NmeaFormat(), UbxFormat()])
    frames = dec.feed(bytes(raw))
    pvts = [f for f in frames if isinstance(f, NavPvt)]
    assert len(pvts) == 3 and dec.stats.crc_errors == 0 and dec.stats.garbage_bytes == 0
    assert pvts[0].lat == round(39.979e7) and pvts[0].lon == round(116.339e7)
    assert pvts[0].height == 50000 and pvts[0].hMSL == 58500 and pvts[0].fixType == 3
    kinds = {type(f).__name__ for f in frames}
    assert {"Gga", "Rmc", "Vtg", "Gsa", "Zda", "NavPvt", "NavStatus"} <= kinds
    peer = [m for _, m in UBXReader(__import__("io").BytesIO(bytes(raw)), protfilter=2)]
    peer_pvt = [m for m in peer if m.identity == "NAV-PVT"]
    assert len(peer_pvt) == 3 and peer_pvt[0].lat == pytest.approx(39.979) and peer_pvt[0].hMSL == 58500
