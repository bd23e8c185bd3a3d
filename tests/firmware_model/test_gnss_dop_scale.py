"""The GNSS sigmas follow the receiver's reported geometry (D-5.42, issue 36 item 3): ``k = max(1, HDOP / hdop_ref)``
on every GNSS sigma (white rows, velocity rows, the correlated error states), the sheet's figures a floor; a fix
whose geometry is no worse than the sheet's leaves the filter exactly as before; GGA's HDOP reaches the update."""

from __future__ import annotations

import datetime as dt
import math

import numpy as np
import pytest
import yaml

from firmware_model import Firmware, FirmwareConfig, c674x
from firmware_model.attitude import a2mat, mat2q, yaw_from_heading
from firmware_model.filters.base import BaseFilter
from firmware_model.filters.gnss import GnssMeasurement, gnss_corr_sigmas, gnss_dop_scale, gnss_measurement_rows
from firmware_model.kf import D_H, D_LAT, D_LON, DV_E
from firmware_model.nav_state import NavState
from firmware_model.spec_sheet import SensorSpecSheet
from protocols.nmea_build import build_gga, build_rmc

from .synth import StaticTruth, gnss_updates_seen
from .test_spec_sheet import SHEETS

DEG = math.pi / 180.0


def test_the_scale_is_hdop_over_the_reference_never_below_one():
    cfg = FirmwareConfig(gnss_hdop_ref=1.0)
    assert gnss_dop_scale(cfg, 2.5) == 2.5
    assert gnss_dop_scale(cfg, 0.8) == 1.0  # a better geometry never narrows the sheet's figures
    for bad in (None, math.nan, math.inf, 0.0, -1.0):
        assert gnss_dop_scale(cfg, bad) == 1.0
    assert gnss_dop_scale(FirmwareConfig(), 4.0) == 1.0  # no reference: the HDOP is not used


def test_the_field_sheet_states_its_reference_and_the_default_sheet_none():
    field = SensorSpecSheet.from_dict(yaml.safe_load((SHEETS / "field.yaml").read_text()), "field")
    default = SensorSpecSheet.from_dict(yaml.safe_load((SHEETS / "default.yaml").read_text()), "default")
    assert field.config_fields()["gnss_hdop_ref"] == 1.0 and "gnss.hdop_ref" in field.sources
    assert default.config_fields()["gnss_hdop_ref"] == 0.0


def test_every_row_variance_scales_by_k_squared():
    cfg = FirmwareConfig(gnss_hdop_ref=1.0)
    meter = c674x.CycleMeter(cfg.clock_hz, cfg.imu_rate_hz)
    p = np.array([40 * DEG, 116 * DEG, 50.0])
    v = np.zeros(3)
    base = GnssMeasurement(t_fpga_s=1.0, pos=(float(p[0]), float(p[1]), 60.0), vel=np.ones(3), vel_up=True)
    worse = GnssMeasurement(t_fpga_s=1.0, pos=base.pos, vel=base.vel, vel_up=True, hdop=3.0)
    meter.begin("gnss")
    r0 = gnss_measurement_rows(cfg, meter, base, p, v)
    c1 = meter.elapsed
    r3 = gnss_measurement_rows(cfg, meter, worse, p, v)
    assert meter.elapsed - c1 > c1  # the division is charged
    meter.end()
    assert [r[0] for r in r3] == [D_LAT, D_LON, D_H, DV_E, DV_E + 1, DV_E + 2]
    for a, b in zip(r0, r3, strict=True):
        assert a[:3] == b[:3] and b[3] == pytest.approx(9.0 * a[3])


def _filter(**kw):
    cfg = FirmwareConfig(precision="float64", gnss_relock_gap_s=5.0, **kw)
    flt = BaseFilter(cfg, c674x.CycleMeter(cfg.clock_hz, cfg.imu_rate_hz), np.float64)
    cbn = a2mat(0.0, 0.0, yaw_from_heading(30 * DEG))
    nav = NavState(q=mat2q(cbn), v=np.zeros(3), pos=np.array([39.979 * DEG, 116.339 * DEG, 50.0]))
    flt.initialise(nav, 1.0 * DEG)
    return flt, nav


def test_a_fix_no_worse_than_the_sheet_leaves_the_filter_as_without_the_reference():
    """The field world's receiver reports HDOP 0.8: with the reference 1.0 the filter is bit-identical to the
    filter that ignores the HDOP (the price on the typical world is nil by construction)."""
    a, nav = _filter(gnss_hdop_ref=1.0)
    b, _ = _filter()
    for k in range(1, 4):
        fix = GnssMeasurement(t_fpga_s=float(k), pos=(float(nav.pos[0]), float(nav.pos[1]), 52.0),
                              vel=np.array([0.02, -0.01, 0.0]), hdop=0.8)
        a.update_gnss(nav, fix, nav.pos, np.zeros(3))
        b.update_gnss(nav, fix, nav.pos, np.zeros(3))
    np.testing.assert_array_equal(a.P, b.P)
    np.testing.assert_array_equal(a.x, b.x)
    assert "gnss_level_changes" not in a.counters and a.gnss_states is not None and a.gnss_states.level == 1.0


def test_a_worse_geometry_widens_the_error_states_and_the_first_fixs_position_prior():
    flt, nav = _filter(gnss_hdop_ref=1.0)
    gs = flt.gnss_states
    assert gs is not None
    i = gs.i
    sc_h, sc_v = gnss_corr_sigmas(flt.cfg)
    var = np.array([sc_h**2, sc_h**2, sc_v**2])
    P0 = flt.P.copy()
    q0 = flt.q[i:i + 3].copy()
    # the first fix since the prior, HDOP 3: level 9; the prior rises as if it had been set at that level
    assert gs.set_level(flt.P, 9.0, prior=(6.4e6, 4.9e6)) is True
    np.testing.assert_allclose(np.diag(flt.P)[i:i + 3] - np.diag(P0)[i:i + 3], 8.0 * var)
    sh, sv = flt.cfg.gnss_pos_sigma_h_m, flt.cfg.gnss_pos_sigma_v_m
    assert flt.P[D_H, D_H] - P0[D_H, D_H] == pytest.approx(8.0 * sv**2)
    assert flt.P[D_LAT, D_LAT] - P0[D_LAT, D_LAT] == pytest.approx(8.0 * sh**2 / 6.4e6**2)
    assert flt.P[D_H, i + 2] - P0[D_H, i + 2] == pytest.approx(8.0 * var[2])
    np.testing.assert_array_equal(flt.P - P0, (flt.P - P0).T)  # the addition is symmetric
    np.linalg.cholesky(flt.P)
    # a falling level keeps the variance (the states decay towards it) and lowers the process noise
    before = flt.P.copy()
    assert gs.set_level(flt.P, 4.0) is True
    np.testing.assert_array_equal(flt.P, before)
    np.testing.assert_allclose(gs.psd, 4.0 * q0)
    assert gs.position_row(np.zeros(flt.n), D_H) == pytest.approx(4.0 * flt.cfg.gnss_pos_white_sigma_v_m**2)
    # through the update: the process noise the predict uses follows the level, the counter counts
    fix = GnssMeasurement(t_fpga_s=1.0, pos=(float(nav.pos[0]), float(nav.pos[1]), 52.0), hdop=2.0)
    flt2, _ = _filter(gnss_hdop_ref=1.0)
    flt2.update_gnss(nav, fix, nav.pos, np.zeros(3))
    assert flt2.counters["gnss_level_changes"] == 1
    np.testing.assert_allclose(flt2.q[i:i + 3], 4.0 * q0)
    # a loss of lock re-draws the states at the current level
    flt2._gnss_relock(20.0)
    np.testing.assert_allclose(np.diag(flt2.P)[i:i + 3], 4.0 * var)
    # a re-initialisation returns to the sheet's level
    flt2.initialise(nav, 1.0 * DEG)
    assert flt2.gnss_states is not None and flt2.gnss_states.level == 1.0
    np.testing.assert_allclose(flt2.q[i:i + 3], q0)


def test_ggas_hdop_reaches_the_gnss_update():
    truth = StaticTruth()
    fw = Firmware(FirmwareConfig(gnss_baud=115200, gnss_latency_s=0.05, align_time_s=2.0, gnss_hdop_ref=1.0))
    chunks = []
    for k in range(1, 8):
        utc = truth.epoch + dt.timedelta(seconds=k)
        gga = build_gga(utc.time(), truth.lat_deg, truth.lon_deg, truth.height_m, 0.0, 1, 6, 2.7, "GP")
        rmc = build_rmc(utc.time(), utc.date(), truth.lat_deg, truth.lon_deg, 0.0, 0.0, valid=True, mode="A")
        chunks.append((k + 0.05 + len(gga + rmc) * 10 / 115200, 3, gga + rmc))
    seen = gnss_updates_seen(fw, lambda m: m.hdop, chunks)
    assert seen and all(h == pytest.approx(2.7) for h in seen)
    assert fw.filter.gnss_states is not None and fw.filter.gnss_states.level == pytest.approx(2.7**2)
