"""Firmware-level tests: synthetic IMU/GNSS/PSNS byte frames into Firmware.receive/service.

No emulator and no sensor models: a static truth is encoded with the protocols encoders
(``tests/firmware_model/synth.py``) and fed in reception order, as the virtual DSP does.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from firmware_model import Firmware, FirmwareConfig, FirmwareError, earth
from firmware_model.attitude import heading_from_yaw, m2att, q2mat, qconj, qmul
from firmware_model.config import FILTER_VARIANTS
from firmware_model.filters.base import BaseFilter
from firmware_model.filters.interface import register_filter
from firmware_model.tasks.state import FirmwareState
from protocols.constants import DEG
from protocols.host import HostFormat, NavMode, NavSolution
from protocols.stream import StreamDecoder

from .synth import SensorErrors, StaticTruth, StreamConfig, static_stream

#: Paper-grade sensors (the sensor figures of docs/architecture.md, one draw), the gyro z bias set to zero so that
#: "heading stays at its initial misalignment" without PSNS is not blurred by a z-gyro drift.
PAPER_ERRORS = SensorErrors(gyro_bias_dph=(9.0, -7.0, 0.0), gyro_arw_deg_rt_h=0.15, accel_bias_mg=(1.5, -1.0, 2.0),
                            accel_noise_ug_rt_hz=100.0, gnss_pos_sigma_m=3.0, gnss_vel_sigma_mps=0.03,
                            psns_sigma_deg=0.03)


def _wrap180(a: float) -> float:
    return (a + 180.0) % 360.0 - 180.0


def run_static(cfg: FirmwareConfig, truth: StaticTruth, err: SensorErrors, stream: StreamConfig, duration_s: float,
               seed: int = 1, keep_outputs: bool = False):
    """Feed the stream; sample the navigation state once per second. Returns (fw, samples, events, outputs)."""
    fw = Firmware(cfg)
    rm, rn = earth.radii(truth.lat_deg * DEG)
    samples = []
    events = []
    outputs = []
    next_sample = 1.0
    for t_rx, uart, data in static_stream(truth, err, stream, duration_s, seed=seed):
        fw.receive(uart, data, t_rx)
        if uart != 1:
            continue
        for r in fw.service():
            events.extend(r.events)
            if keep_outputs:
                outputs.extend(o[1] for o in r.outputs)
            if fw.nav is not None and r.t_fpga_s >= next_sample - 1e-9:
                next_sample += 1.0
                p, ro, y = m2att(q2mat(fw.nav.q.astype(np.float64)))
                dn = (fw.nav.pos[0] - truth.lat_deg * DEG) * (rm + truth.height_m)
                de = (fw.nav.pos[1] - truth.lon_deg * DEG) * (rn + truth.height_m) * math.cos(truth.lat_deg * DEG)
                samples.append((r.t_fpga_s, _wrap180(heading_from_yaw(y) / DEG - truth.heading_deg),
                                p / DEG - truth.pitch_deg, ro / DEG - truth.roll_deg, math.hypot(dn, de),
                                fw.nav.pos.copy(), fw.nav.q.astype(np.float64).copy()))
    return fw, samples, events, outputs


def _heading_errors(samples, after_s):
    return np.array([s[1] for s in samples if s[0] >= after_s])


# -- Done-when: static 10 min, heading with and without PSNS --------------------------------------------
@pytest.mark.parametrize("duration_s", [
    pytest.param(180.0, id="3min"),
    pytest.param(600.0, id="10min", marks=pytest.mark.slow),
])
def test_static_gnss_psns_heading_converges_and_without_psns_it_stays(duration_s):
    truth = StaticTruth(heading_deg=30.0, pitch_deg=2.0, roll_deg=-3.0)
    # PSNS on: heading from gravity + Sun (TRIAD), then the KF with +-S updates
    cfg = FirmwareConfig(initial_heading_deg=31.0)  # the configured heading is NOT used: alignment takes the Sun
    fw, samples, events, _ = run_static(cfg, truth, PAPER_ERRORS, StreamConfig(psns="solar_vector"), duration_s)
    align = [e for e in events if e["event"] == "alignment_done"]
    assert len(align) == 1 and align[0]["heading_source"] == "psns"
    assert abs(_wrap180(align[0]["heading_deg"] - truth.heading_deg)) < 0.5  # coarse TRIAD
    he = _heading_errors(samples, after_s=60.0)
    rms = float(np.sqrt(np.mean(he**2)))
    assert rms < 0.2, rms
    assert fw.counters["psns_updates"] > 4 * duration_s * 0.9 and fw.counters["psns_rejected"] == 0
    assert fw.state == FirmwareState.NAVIGATE

    # PSNS off: the configured heading (1 deg off truth) is all the firmware has; heading is unobservable
    # (earth rate 11.5 deg/h at 40 N is far below the gyro bias uncertainty) and the error stays at 1 deg.
    cfg_off = FirmwareConfig(initial_heading_deg=31.0, psns_enabled=False)
    fw_off, s_off, ev_off, _ = run_static(cfg_off, truth, PAPER_ERRORS, StreamConfig(psns=None), duration_s)
    assert [e["heading_source"] for e in ev_off if e["event"] == "alignment_done"] == ["config"]
    he_off = _heading_errors(s_off, after_s=60.0)
    # not corrected: it stays near 1 deg (a slow wander of a few tenths comes from the weakly observable
    # vertical gyro bias over 10 min); with PSNS the error is an order of magnitude smaller
    assert np.all(np.abs(he_off - 1.0) < 0.4), (he_off.min(), he_off.max())
    assert float(np.sqrt(np.mean(he_off**2))) > 5 * rms
    assert fw_off.counters["psns_updates"] == 0
    # and the filter knows it: its heading sigma stays near the configured 1 deg
    assert math.sqrt(float(fw_off.P[2, 2])) / DEG > 0.8


def test_polarization_obs_frames_are_solved_in_the_firmware():
    """POLARIZATION_OBS (points on the wire, ~200 per frame at 115200 baud and 5 Hz): firmware solve + KF."""
    truth = StaticTruth(heading_deg=250.0, pitch_deg=-4.0, roll_deg=6.0)
    err = SensorErrors(gyro_bias_dph=(5.0, 4.0, 0.0), gyro_arw_deg_rt_h=0.15, accel_bias_mg=(0.5, 0.5, 1.0),
                       accel_noise_ug_rt_hz=100.0, gnss_pos_sigma_m=3.0, gnss_vel_sigma_mps=0.03, psns_sigma_deg=1.0)
    fw, samples, events, _ = run_static(FirmwareConfig(), truth, err, StreamConfig(psns="polarization_obs"), 60.0)
    assert [e["heading_source"] for e in events if e["event"] == "alignment_done"] == ["psns"]
    assert fw.counters["psns_solutions"] >= 250 and fw.counters["psns_invalid"] == 0
    he = _heading_errors(samples, after_s=20.0)
    assert float(np.sqrt(np.mean(he**2))) < 0.2
    # the solve's cycles are metered in their own task
    assert fw.meter.tasks["psns_update"].kernels["psns_solve"] > 0


def test_psns_exposure_time_tag_uses_latency_and_line_time():
    truth = StaticTruth()
    stream = StreamConfig(psns="solar_vector", psns_latency_us=123456, psns_baud=57600)
    cfg = FirmwareConfig(psns_baud=57600)
    fw = Firmware(cfg)
    got = []
    orig = fw.psns.observation

    def spy(t_rx, f):
        obs = orig(t_rx, f)
        if obs is not None:
            got.append(obs.t_exposure_s)
        return obs

    fw.psns.observation = spy  # type: ignore[method-assign]
    for t_rx, uart, data in static_stream(truth, SensorErrors(), stream, 5.0):
        fw.receive(uart, data, t_rx)
        if uart == 1:
            fw.service()
    # synth exposes at k / 5 Hz exactly
    assert len(got) >= 20
    assert np.allclose(np.array(got) * 5.0, np.round(np.array(got) * 5.0), atol=1e-9 * 5)


def test_nav_solution_frames_carry_mode_bits_and_sigmas():
    truth = StaticTruth()
    _fw, _, _, outputs = run_static(FirmwareConfig(fine_align_time_s=5.0), truth, PAPER_ERRORS,
                                   StreamConfig(psns="solar_vector"), 12.0, keep_outputs=True)
    dec = StreamDecoder([HostFormat()])
    navs = [f for f in dec.feed(b"".join(outputs)) if isinstance(f, NavSolution)]
    assert len(navs) == 12 * 100 and dec.stats.as_dict()["crc_errors"] == 0
    last = navs[-1]
    assert last.mode & NavMode.NAVIGATING and last.mode & NavMode.GNSS_AIDED and last.mode & NavMode.PSNS_AIDED
    assert not last.mode & NavMode.ALIGNING  # fine alignment (5 s) is over
    assert (last.mode >> 8) & 0xF == BaseFilter.variant_id
    assert last.psns_status == 1
    assert 0 < last.sigma[2] < 0.5  # heading sigma, deg
    assert abs(_wrap180(last.heading_deg - truth.heading_deg)) < 0.3
    assert navs[0].mode & NavMode.ALIGNING and not navs[0].mode & NavMode.NAVIGATING


# -- Done-when: float32 vs float64, same code path ----------------------------------------------------------
def _compare_precisions(duration_s: float):
    truth = StaticTruth()
    stream = StreamConfig(psns="solar_vector")
    out = {}
    for prec in ("float32", "float64"):
        out[prec] = run_static(FirmwareConfig(precision=prec), truth, PAPER_ERRORS, stream, duration_s, seed=4)[1]
    s32, s64 = out["float32"], out["float64"]
    assert len(s32) == len(s64) and len(s32) > 0.9 * duration_s
    att, pos = [], []
    for a, b in zip(s32, s64):
        qa, qb = a[6] / np.linalg.norm(a[6]), b[6] / np.linalg.norm(b[6])
        dq = qmul(qconj(qa), qb)  # rotation between the two attitudes; angle = 2 asin |vector part|
        att.append(math.degrees(2.0 * math.asin(min(1.0, float(np.linalg.norm(dq[1:]))))))
        rm, rn = earth.radii(float(b[5][0]))
        pos.append(math.hypot((a[5][0] - b[5][0]) * rm, (a[5][1] - b[5][1]) * rn * math.cos(float(b[5][0]))))
    return max(att), max(pos)


def test_float32_matches_float64_over_5_min():
    att, pos = _compare_precisions(300.0)
    assert att < 0.01 and pos < 0.5, (att, pos)


@pytest.mark.slow
def test_float32_matches_float64_over_1_h():
    att, pos = _compare_precisions(3600.0)
    assert att < 0.01 and pos < 0.5, (att, pos)


# -- Done-when: cycle budget ------------------------------------------------------------------------------
def test_worst_tick_below_20_percent_of_the_budget_in_the_base_configuration():
    """300 MHz, 200 Hz: 1.5 M cycles per tick; base filter with GNSS and a full POLARIZATION_OBS frame."""
    fw, _, _, _ = run_static(FirmwareConfig(), StaticTruth(), PAPER_ERRORS, StreamConfig(psns="polarization_obs"), 30.0)
    tick = fw.meter.tasks["imu_tick"]
    assert fw.meter.tick_budget == 1_500_000
    assert tick.calls == 6000
    assert tick.cycles_max < 0.20 * fw.meter.tick_budget, tick.cycles_max
    rows = {r["task"]: r for r in fw.meter.table()}
    for task in ("imu_tick", "imu", "kf_predict", "gnss_update", "psns_update", "output"):
        assert rows[task]["calls"] > 0 and rows[task]["budget_cycles"] == 1_500_000
        assert rows[task]["cycles_min"] <= rows[task]["cycles_avg"] <= rows[task]["cycles_max"]
    assert rows["gnss_update"]["calls"] >= 28 and rows["kf_predict"]["calls"] >= 270
    assert "strapdown" in rows["imu"]["kernels"] and "psns_solve" in rows["psns_update"]["kernels"]
    assert "imu_tick" in fw.meter.format_table()


def test_double_precision_build_pays_the_dp_price():
    stream = StreamConfig(psns="polarization_obs")
    c = {}
    for prec in ("float32", "float64"):
        fw, _, _, _ = run_static(FirmwareConfig(precision=prec), StaticTruth(), PAPER_ERRORS, stream, 6.0)
        c[prec] = {t: fw.meter.tasks[t].cycles_max for t in ("imu", "kf_predict", "psns_update")}
    assert c["float64"]["kf_predict"] > 2.5 * c["float32"]["kf_predict"]  # MPYDP: 4 cycles per .M issue
    assert c["float64"]["psns_update"] > 2 * c["float32"]["psns_update"]
    assert c["float64"]["imu"] > c["float32"]["imu"]


# -- two-sample coning/sculling with angle increments ---------------------------------------------------------
def test_angle_increment_gyro_runs_two_sample_mechanization():
    truth = StaticTruth()
    cfg = FirmwareConfig(gyro_output="angle")
    assert cfg.subsamples == 2
    fw, samples, events, _ = run_static(cfg, truth, PAPER_ERRORS,
                                        StreamConfig(psns="solar_vector", gyro_output="angle"), 60.0)
    align_ticks = next(e["samples"] for e in events if e["event"] == "alignment_done")
    n_strap = fw.meter.tasks["imu"].kernels["strapdown"] / fw._cyc["strapdown"]
    assert n_strap == pytest.approx((fw.meter.tasks["imu"].calls - align_ticks) / 2, abs=1)  # 100 Hz steps
    he = _heading_errors(samples, after_s=20.0)
    assert float(np.sqrt(np.mean(he**2))) < 0.2
    assert max(s[4] for s in samples if s[0] > 10) < 10.0


# -- robustness and the interface ------------------------------------------------------------------------------
def test_garbage_on_every_uart_is_counted_not_raised():
    fw = Firmware(FirmwareConfig())
    rng = np.random.default_rng(0)
    for uart in (0, 1, 2, 3):
        fw.receive(uart, rng.integers(0, 256, 4000, dtype=np.uint8).tobytes(), 0.1)
    fw.service()
    stats = fw.decoder_stats()
    assert set(stats) >= {"uart1", "uart2", "uart3"}
    assert stats["uart2"]["garbage_bytes"] > 0


def test_unknown_filter_variant_is_a_firmware_error():
    with pytest.raises(FirmwareError, match="available: base, dual_vector, federated, kmeans_3d, sun_elevation"):
        FirmwareConfig(filter="no_such_variant")


def test_a_registered_variant_plugs_into_the_same_loop():
    calls = {"predict": 0, "gnss": 0, "solar": 0}

    @register_filter("test_counting")
    class CountingFilter(BaseFilter):
        variant_id = 15

        def predict(self, nav, f_n, Tk):
            calls["predict"] += 1
            super().predict(nav, f_n, Tk)

        def update_gnss(self, nav, meas, p_ins, v_ins):
            calls["gnss"] += 1
            return super().update_gnss(nav, meas, p_ins, v_ins)

        def update_solar(self, nav, obs, s_n, cbn_exp):
            calls["solar"] += 1
            return super().update_solar(nav, obs, s_n, cbn_exp)

    try:
        fw, _, _, _ = run_static(FirmwareConfig(filter="test_counting"), StaticTruth(), PAPER_ERRORS,
                                 StreamConfig(psns="solar_vector"), 10.0)
        assert isinstance(fw.filter, CountingFilter)
        assert calls["predict"] >= 70 and calls["gnss"] >= 7 and calls["solar"] >= 35
    finally:
        FILTER_VARIANTS.pop("test_counting", None)


def test_psns_alignment_source_waits_and_falls_back():
    truth = StaticTruth()
    cfg = FirmwareConfig(alignment_heading="psns", psns_align_timeout_s=3.0, initial_heading_deg=31.0)
    _fw, _, events, _ = run_static(cfg, truth, PAPER_ERRORS, StreamConfig(psns=None), 10.0)
    ev = [e for e in events if e["event"] == "alignment_done"]
    assert ev and ev[0]["heading_source"] == "config" and ev[0]["t_fpga_s"] >= 2.0 + 3.0 - 0.01


def test_compass_frames_reach_the_variant_with_their_exposure_time():
    from protocols.psns import CompassUnit, PsnsHeader, PsnsStatus, encode_compass

    seen = []

    @register_filter("test_compass")
    class CompassRecorder(BaseFilter):
        def update_compass(self, nav, frame, t_exposure_s):
            seen.append((len(frame.units), t_exposure_s))
            return None

    try:
        cfg = FirmwareConfig(filter="test_compass", psns_baud=115200)
        fw = Firmware(cfg)
        frame = encode_compass(PsnsHeader(1, 1000, 20000, int(PsnsStatus.VALID), 9),
                               [CompassUnit(u, 100 * u, 30000) for u in range(9)])
        sent = False
        for t_rx, uart, data in static_stream(StaticTruth(), SensorErrors(), StreamConfig(psns=None), 6.0):
            fw.receive(uart, data, t_rx)
            if uart == 1:
                fw.service()
                if not sent and fw.state != FirmwareState.COARSE_ALIGN:
                    fw.receive(2, frame, t_rx)
                    t_sent = t_rx
                    sent = True
        assert fw.counters["compass_frames"] == 1
        assert len(seen) == 1 and seen[0][0] == 9
        assert seen[0][1] == pytest.approx(t_sent - len(frame) * 10 / 115200 - 0.020)
    finally:
        FILTER_VARIANTS.pop("test_compass", None)


def test_sun_below_horizon_no_psns_updates_no_event_spam():
    import datetime as dt

    night = StaticTruth(epoch=dt.datetime(2019, 9, 18, 20, 0, 0, tzinfo=dt.UTC))  # 04:00 local, Beijing
    assert night.sun_n(0.0)[2] < 0
    fw, _, events, _ = run_static(FirmwareConfig(initial_heading_deg=30.0), night, PAPER_ERRORS,
                                  StreamConfig(psns="solar_vector"), 20.0)
    assert [e["heading_source"] for e in events if e["event"] == "alignment_done"] == ["config"]
    assert fw.counters["psns_updates"] == 0 and fw.counters["psns_sun_low"] > 80
    assert not [e for e in events if e["event"] == "psns_rejected"]


def test_gnss_outage_sets_degraded_and_psns_keeps_heading():
    truth = StaticTruth()
    stream = StreamConfig(psns="solar_vector", gnss_outage_s=(20.0, 40.0))
    fw, samples, _, outputs = run_static(FirmwareConfig(fine_align_time_s=5.0), truth, PAPER_ERRORS, stream, 50.0,
                                         keep_outputs=True)
    navs = [f for f in StreamDecoder([HostFormat()]).feed(b"".join(outputs)) if isinstance(f, NavSolution)]
    by_t = {round(n.time_s, 3): n for n in navs}
    during, after = by_t[35.0], by_t[49.0]
    assert during.mode & NavMode.DEGRADED and not during.mode & NavMode.GNSS_AIDED and during.mode & NavMode.PSNS_AIDED
    assert after.mode & NavMode.GNSS_AIDED and not after.mode & NavMode.DEGRADED
    assert fw.counters["gnss_updates"] < 50 - 19
    he = _heading_errors(samples, after_s=20.0)
    assert float(np.max(np.abs(he))) < 0.2  # the Sun keeps the heading through the outage


# -- UBX NAV-PVT on UART3 (full 3-D velocity) ---------------------------------------------------------------
def test_ubx_nav_pvt_gives_the_vertical_velocity_update():
    truth = StaticTruth()
    # the synthetic receiver's position errors are white: the filter models them so (no GNSS-error states), or its
    # consistent chi-square gate refuses the 4-sigma draws a white-noise receiver makes look like a correlated one's
    white = FirmwareConfig(gnss_error_states=False)
    fw, samples, events, _ = run_static(white, truth, PAPER_ERRORS,
                                        StreamConfig(psns="solar_vector", gnss_output="ubx"), 30.0)
    assert fw.counters["gnss_pvt"] == 30 and fw.counters["gnss_updates"] >= 27
    assert [e["heading_source"] for e in events if e["event"] == "alignment_done"] == ["psns"]  # UTC from NAV-PVT
    gnss = [e for e in events if e["event"] == "gnss_update"]
    assert all(e["n_meas"] == 6 for e in gnss)  # 3 position + 3 velocity rows (velD)
    # NMEA has no vertical velocity: 5 rows
    _, _, ev_nmea, _ = run_static(white, truth, PAPER_ERRORS, StreamConfig(psns="solar_vector"), 10.0)
    assert {e["n_meas"] for e in ev_nmea if e["event"] == "gnss_update"} == {5}
    assert samples[-1][4] < 10.0


def test_ubx_vertical_velocity_is_used():
    """A 0.5 m/s error on velD pulls the INS vertical velocity; without velD (NMEA) it does not."""
    truth = StaticTruth()
    fw, _, _, _ = run_static(FirmwareConfig(), truth, SensorErrors(),
                             StreamConfig(psns=None, gnss_output="ubx", gnss_vel_up_error_mps=0.5), 20.0)
    assert float(fw.nav.v[2]) > 0.2


# -- host commands on UART0 ---------------------------------------------------------------------------------
def _drive_with_commands(commands_at: dict[float, bytes], duration_s: float, cfg: FirmwareConfig | None = None):
    fw = Firmware(cfg or FirmwareConfig())
    out = []
    pending = sorted(commands_at.items())
    for t_rx, uart, data in static_stream(StaticTruth(), SensorErrors(), StreamConfig(psns="solar_vector"),
                                          duration_s):
        while pending and pending[0][0] <= t_rx:
            fw.receive(0, pending.pop(0)[1], t_rx)
        fw.receive(uart, data, t_rx)
        if uart == 1:
            for r in fw.service():
                out.extend((r.t_fpga_s, o[1]) for o in r.outputs)
    dec = StreamDecoder([HostFormat()])
    frames = [(t, f) for t, b in out for f in dec.feed(b)]
    return fw, frames


def test_host_commands_are_acknowledged_and_applied(monkeypatch):
    from protocols.host import (
        Ack,
        AckResult,
        FilterVariant,
        HostStatus,
        RequestStatus,
        ResetFilter,
        SelectVariant,
        SetOutputRate,
        build_host_frame,
        encode_command,
    )

    monkeypatch.delitem(FILTER_VARIANTS, "federated")  # a known variant left out of this build

    cmds = {
        4.0: encode_command(SetOutputRate(token=1, rate_hz=10.0)),
        4.5: encode_command(SetOutputRate(token=2, rate_hz=30.0)),  # not 200 Hz / k
        5.0: encode_command(RequestStatus(token=3)),
        5.5: encode_command(SelectVariant(token=4, variant=int(FilterVariant.FEDERATED))),  # not in this build
        6.0: encode_command(SelectVariant(token=5, variant=99)),
        6.5: encode_command(SelectVariant(token=6, variant=int(FilterVariant.BASE))),
        7.0: encode_command(ResetFilter(token=7, scope=1)),
        7.5: build_host_frame(0x8F, b"\x08"),  # unknown command id
        8.0: encode_command(ResetFilter(token=9, scope=0)),  # back to coarse alignment
    }
    fw, frames = _drive_with_commands(cmds, 14.0)
    acks = {f.token: f.result for _, f in frames if isinstance(f, Ack)}
    assert acks == {1: AckResult.ACCEPTED, 2: AckResult.BAD_ARGUMENT, 3: AckResult.ACCEPTED,
                    4: AckResult.NOT_ALLOWED, 5: AckResult.BAD_ARGUMENT, 6: AckResult.ACCEPTED,
                    7: AckResult.ACCEPTED, 8: AckResult.UNKNOWN_COMMAND, 9: AckResult.ACCEPTED}
    navs = [t for t, f in frames if isinstance(f, NavSolution)]
    # 100 Hz before the command, 10 Hz after it
    assert sum(1 for t in navs if 3.0 <= t < 4.0) == 100 and sum(1 for t in navs if 5.0 <= t < 6.0) == 10
    status = [(t, f) for t, f in frames if isinstance(f, HostStatus)]
    assert len(status) >= 14  # 1 Hz plus the requested one
    st = next(f for t, f in status if 5.0 <= t < 5.1)
    assert st.output_rate_hz == pytest.approx(10.0) and st.filter_variant == int(FilterVariant.BASE)
    assert st.commands_accepted == 2 and st.commands_rejected == 1 and st.uart1_frames > 900
    assert 0 < st.cpu_load_pct <= st.cpu_load_max_pct
    # the reset at 8 s restarted the alignment, which completed again 2 s later
    assert fw.counters["commands_accepted"] == 5 and fw.counters["commands_rejected"] == 4
    assert fw.state == FirmwareState.FINE_ALIGN


def test_mag_frames_on_uart1_are_decoded_beside_imu_frames():
    from protocols.imu_frame import MagFrame, encode_mag_frame

    fw = Firmware(FirmwareConfig())
    for t_rx, uart, data in static_stream(StaticTruth(), SensorErrors(), StreamConfig(psns=None), 3.0):
        if uart == 1:
            data = data + encode_mag_frame(MagFrame(seq=1, t_sample_us=int(t_rx * 1e6), field=(200000, 300000, -400000),
                                                    status=0))
        fw.receive(uart, data, t_rx)
        if uart == 1:
            fw.service()
    assert fw.counters["mag_frames"] == 600 and fw.counters["imu_frames"] == 600
    assert fw.last_mag.field == (200000, 300000, -400000)
    assert fw.decoder_stats()["uart1"]["crc_errors"] == 0


def test_a_psns_alignment_that_timed_out_takes_its_heading_from_the_first_solar_vector():
    """D-5.50: the sun comes only after the alignment gave up; until then the heading is a placeholder (sigma of a
    uniform circle, not the configured 1 deg), and the first solar vector sets it."""
    from firmware_model.attitude import q2mat_fast

    truth = StaticTruth(heading_deg=75.0)
    cfg = FirmwareConfig(alignment_heading="psns", psns_align_timeout_s=1.0, initial_heading_deg=0.0)
    fw = Firmware(cfg)
    events: list[dict] = []
    sigma_at_align = None
    for t_rx, uart, data in static_stream(truth, PAPER_ERRORS, StreamConfig(psns="solar_vector"), 14.0):
        if uart == 2 and t_rx < 8.0:
            continue  # no solar vector until 8 s (a cloud)
        fw.receive(uart, data, t_rx)
        if uart == 1:
            for r in fw.service():
                events.extend(r.events)
                if sigma_at_align is None and fw.nav is not None:
                    sigma_at_align = math.sqrt(float(fw.filter.P[2, 2])) / DEG
    al = [e for e in events if e["event"] == "alignment_done"]
    late = [e for e in events if e["event"] == "late_solar_heading"]
    assert al and al[0]["heading_source"] == "config"
    assert sigma_at_align == pytest.approx(180.0 / math.sqrt(3.0), rel=1e-3)
    assert len(late) == 1 and late[0]["t_fpga_s"] >= 8.0
    assert abs(_wrap180(late[0]["heading_change_deg"] - 75.0)) < 2.0
    _, _, y = m2att(q2mat_fast(fw.nav.q.astype(np.float64)))
    assert abs(_wrap180(heading_from_yaw(y) / DEG - 75.0)) < 1.0
    assert math.sqrt(float(fw.filter.P[2, 2])) / DEG < 1.0
