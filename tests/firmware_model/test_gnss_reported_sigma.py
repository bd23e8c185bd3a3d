"""The receiver's own error estimate (NMEA GST) widens a fix's sigmas beside its HDOP (D-5.51, issue 36 item 3):
``k = max(1, HDOP / hdop_ref, GST / sheet)``; a GST no wider than the sheet changes nothing; GST's latitude and
longitude errors reach the update through the one NMEA parser; hostile values are refused and counted."""

from __future__ import annotations

import datetime as dt
import math

import numpy as np
import pytest

from firmware_model import Firmware, FirmwareConfig, c674x, input_guard
from firmware_model.filters.gnss import GnssMeasurement, gnss_fix_scale, gnss_measurement_rows
from protocols.nmea import Gst
from protocols.nmea_build import build_gga, build_gst, build_rmc

from .synth import StaticTruth, StreamConfig, gnss_updates_seen

DEG = math.pi / 180.0


def _meas(hdop: float | None = None, gst: float | None = None) -> GnssMeasurement:
    return GnssMeasurement(t_fpga_s=1.0, pos=(0.7, 2.0, 50.0), vel=np.zeros(3), hdop=hdop, reported_sigma_h_m=gst)


def test_the_scale_is_the_larger_of_the_geometrys_and_the_receivers_estimate():
    cfg = FirmwareConfig(gnss_hdop_ref=1.0, gnss_pos_sigma_h_m=4.0)
    assert gnss_fix_scale(cfg, _meas(2.0, 12.0)) == pytest.approx(3.0)  # GST 12 m over the sheet's 4 m
    assert gnss_fix_scale(cfg, _meas(4.0, 12.0)) == pytest.approx(4.0)  # the HDOP is the larger
    assert gnss_fix_scale(cfg, _meas(0.8, 3.0)) == 1.0  # a receiver better than the sheet never narrows it
    for bad in (None, math.nan, math.inf, 0.0, -2.0):
        assert gnss_fix_scale(cfg, _meas(0.8, bad)) == 1.0
    # without an HDOP reference the receiver's estimate still widens the sheet
    assert gnss_fix_scale(FirmwareConfig(gnss_pos_sigma_h_m=4.0), _meas(None, 8.0)) == pytest.approx(2.0)


def test_every_row_variance_scales_by_the_reported_ratio_squared_and_the_division_is_charged():
    cfg = FirmwareConfig(gnss_pos_sigma_h_m=4.0)
    meter = c674x.CycleMeter(cfg.clock_hz, cfg.imu_rate_hz)
    p = np.array([0.7, 2.0, 50.0])
    meter.begin("gnss")
    r0 = gnss_measurement_rows(cfg, meter, _meas(), p, np.zeros(3))
    c0 = meter.elapsed
    r2 = gnss_measurement_rows(cfg, meter, _meas(None, 10.0), p, np.zeros(3))
    assert meter.elapsed - c0 > c0
    meter.end()
    for a, b in zip(r0, r2, strict=True):
        assert a[:3] == b[:3] and b[3] == pytest.approx(6.25 * a[3])


def test_the_input_guard_refuses_out_of_range_estimates():
    t = dt.time(12, 0, 0)
    assert input_guard.check_gst(Gst("GP", t, 5.0, 4.0, 3.0, 0.0, 4.0, 3.0, 7.0)) is None
    assert input_guard.check_gst(Gst("GP", t, 5.0, 4.0, 3.0, 0.0, 0.0, 0.0, 7.0)) is None  # zero: no estimate
    assert input_guard.check_gst(Gst("GP", t, 5.0, 4.0, 3.0, 0.0, 1e300, 3.0, 7.0)) == "gst_range"
    assert input_guard.check_gst(Gst("GP", t, 5.0, 4.0, 3.0, 0.0, math.nan, 3.0, 7.0)) == "not_finite"


def _run(gst_lat_lon: tuple[float, float] | None, with_sats: bool = False) -> tuple[Firmware, list]:
    """A static box fed GGA + RMC (+ GST) at 1 Hz through UART3 bytes; the GST values (or, ``with_sats``, the
    satellite counts) each update saw."""
    truth = StaticTruth()
    fw = Firmware(FirmwareConfig(gnss_baud=115200, gnss_latency_s=0.05, align_time_s=2.0, gnss_hdop_ref=1.0))
    chunks = []
    for k in range(1, 8):
        utc = truth.epoch + dt.timedelta(seconds=k)
        data = build_gga(utc.time(), truth.lat_deg, truth.lon_deg, truth.height_m, 0.0, 1, 9, 1.0, "GP")
        data += build_rmc(utc.time(), utc.date(), truth.lat_deg, truth.lon_deg, 0.0, 0.0, valid=True, mode="A")
        if gst_lat_lon is not None:
            data += build_gst(utc.time(), 6.0, max(gst_lat_lon), min(gst_lat_lon), 0.0, *gst_lat_lon, 20.0)
        chunks.append((k + 0.05 + len(data) * 10 / 115200, 3, data))
    pick = (lambda m: m.num_sats) if with_sats else (lambda m: m.reported_sigma_h_m)
    return fw, gnss_updates_seen(fw, pick, chunks)


def test_gsts_latitude_and_longitude_errors_reach_the_gnss_update():
    fw, seen = _run((12.0, 16.0))
    assert seen and all(s == pytest.approx(math.sqrt((12.0**2 + 16.0**2) / 2.0)) for s in seen)
    k = math.sqrt((144.0 + 256.0) / 2.0) / fw.cfg.gnss_pos_sigma_h_m
    assert fw.filter.gnss_states is not None and fw.filter.gnss_states.level == pytest.approx(k * k)
    fw0, seen0 = _run(None)
    assert seen0 and all(s is None for s in seen0) and len(seen0) == len(seen)
    assert fw0.filter.gnss_states is not None and fw0.filter.gnss_states.level == 1.0


def test_a_hostile_gst_is_refused_counted_and_the_fix_still_used():
    fw, seen = _run((1e5, 1e5))
    assert seen and all(s is None for s in seen)
    assert fw.counters["input_rejected_gst_range"] >= len(seen) > 0
    assert fw.counters["gnss_updates"] == len(seen)


def test_a_fix_without_redundancy_assumes_the_sheets_multipath_through_its_hdop():
    """4 satellites or fewer: no residual shows the multipath, so ``HDOP x m / sqrt(2)`` per axis is added in
    quadrature to the fix's figure (D-5.51); 5 or more: the GST is a measurement and nothing is added."""
    cfg = FirmwareConfig(gnss_hdop_ref=1.0, gnss_pos_sigma_h_m=4.0, gnss_unverified_multipath_m=4.85)
    m4 = GnssMeasurement(t_fpga_s=1.0, pos=(0.7, 2.0, 50.0), hdop=3.0, reported_sigma_h_m=10.0, num_sats=4)
    want = math.sqrt(3.0**2 + (3.0 * 4.85 / math.sqrt(2.0) / 4.0) ** 2)  # the HDOP 3 beats GST 10 / 4
    assert gnss_fix_scale(cfg, m4) == pytest.approx(want)
    m5 = GnssMeasurement(t_fpga_s=1.0, pos=(0.7, 2.0, 50.0), hdop=3.0, reported_sigma_h_m=10.0, num_sats=5)
    assert gnss_fix_scale(cfg, m5) == pytest.approx(3.0)  # the HDOP's 3 beats GST's 2.5
    no_gst = GnssMeasurement(t_fpga_s=1.0, pos=(0.7, 2.0, 50.0), hdop=2.0, num_sats=4)
    assert gnss_fix_scale(cfg, no_gst) == pytest.approx(math.hypot(2.0, 2.0 * 4.85 / math.sqrt(2.0) / 4.0))
    # without the sheet's figure, or without a usable HDOP, nothing is assumed
    assert gnss_fix_scale(FirmwareConfig(gnss_hdop_ref=1.0, gnss_pos_sigma_h_m=4.0), m4) == pytest.approx(3.0)
    assert gnss_fix_scale(cfg, GnssMeasurement(t_fpga_s=1.0, num_sats=4, hdop=math.nan)) == 1.0


def test_ggas_satellite_count_reaches_the_update():
    _, seen = _run((12.0, 16.0), with_sats=True)
    assert seen and all(n == 9 for n in seen)  # _run's GGA reports 9 satellites


def test_a_nav_pvt_fix_without_redundancy_goes_through_its_pdop():
    """NAV-PVT reports no HDOP: the 4-satellite rule takes its PDOP, an upper bound of the HDOP (D-5.52)."""
    cfg = FirmwareConfig(gnss_hdop_ref=1.0, gnss_pos_sigma_h_m=4.0, gnss_unverified_multipath_m=4.85)
    m4 = GnssMeasurement(t_fpga_s=1.0, pos=(0.7, 2.0, 50.0), num_sats=4, pdop=2.5)
    assert gnss_fix_scale(cfg, m4) == pytest.approx(math.hypot(1.0, 2.5 * 4.85 / math.sqrt(2.0) / 4.0))
    # an HDOP, when one came, is the geometry (the smaller, truer figure)
    both = GnssMeasurement(t_fpga_s=1.0, pos=(0.7, 2.0, 50.0), num_sats=4, pdop=2.5, hdop=1.2)
    assert gnss_fix_scale(cfg, both) == pytest.approx(math.hypot(1.2, 1.2 * 4.85 / math.sqrt(2.0) / 4.0))
    # 5 satellites: nothing assumed; pDOP 0 (unknown): nothing assumed
    assert gnss_fix_scale(cfg, GnssMeasurement(t_fpga_s=1.0, num_sats=5, pdop=2.5)) == 1.0
    assert gnss_fix_scale(cfg, GnssMeasurement(t_fpga_s=1.0, num_sats=4, pdop=0.0)) == 1.0


def test_nav_pvts_numsv_and_pdop_reach_the_update_and_hacc_does_not():
    fw = Firmware(FirmwareConfig(gnss_baud=115200, gnss_latency_s=0.05, align_time_s=2.0))
    seen = gnss_updates_seen(fw, lambda m: (m.num_sats, m.pdop, m.hdop, m.reported_sigma_h_m),
                             stream=StreamConfig(gnss_output="ubx", gnss_baud=115200, psns=None))
    # synth's NAV-PVT: numSV 12, pDOP 1.50, hAcc 3 m (not a sigma: no HDOP, no reported sigma)
    assert len(seen) >= 4 and all(s == (12, pytest.approx(1.5), None, None) for s in seen)
