"""Fault injection: every fault kind acts, shows in the events with its evidence, and a fault that never
took effect invalidates the run; runs with faults are deterministic."""

from __future__ import annotations

import asyncio
import itertools
import json
import math
import subprocess
import sys
from typing import ClassVar

import numpy as np
import pytest

from emulator.assembly.session import run_scenario
from emulator.scenario.presets import preset
from emulator.testing import load_test_scenario
from protocols.constants import DEG
from tests.conftest import ROOT, SCENARIOS

G = 9.80665
QS = SCENARIOS / "quickstart.yaml"
CAM = SCENARIOS / "static_psns_camera.yaml"


def _scn(base, duration, faults, **ov):
    data = {"duration_s": duration, "motion": [{"static": {"duration_s": duration}}], "expectations": [],
            "faults": faults, "firmware.alignment.fine_time_s": 3}
    data.update(ov)
    return load_test_scenario(base, data)


def _events(run_dir):
    return [json.loads(ln) for ln in (run_dir / "events.jsonl").read_text().splitlines() if ln.strip()]


def _by_index(summary):
    return {f["index"]: f for f in summary["faults"]}


# ------------------------------------------------------------------------------------------ IMU + GNSS + FPGA + DSP
@pytest.fixture(scope="module")
def imu_gnss_run(tmp_path_factory):
    faults = [
        {"gnss_glitch": {"start_s": 3, "duration_s": 3, "offset_enu_m": [40, 0, 0]}},
        {"gnss_degraded": {"start_s": 7, "duration_s": 3, "num_sats": 3}},
        {"gnss_degraded": {"start_s": 11, "duration_s": 3, "noise_scale": 10, "num_sats": 5, "fix_quality": 2}},
        {"imu_bias_step": {"start_s": 2, "duration_s": 4, "gyro_deg_h": [0, 0, 3600]}},
        {"imu_stuck_axis": {"start_s": 8, "duration_s": 2, "sensor": "accel", "axes": ["x", "y"]}},
        {"imu_saturation": {"start_s": 12, "duration_s": 1, "accel_range_g": 0.5}},
        {"imu_dropped_datagrams": {"start_s": 14, "duration_s": 2, "probability": 0.5}},
        {"fpga_channel_stall": {"start_s": 16, "duration_s": 2, "channel": "gnss"}},
        {"dsp_extra_load": {"start_s": 18, "load_pct": 50}},
        {"gnss_outage": {"start_s": 18.5, "duration_s": 1}},
    ]
    # the IMU + GNSS box (the quickstart without the camera it now carries)
    scn = _scn(QS, 20, faults, **{"links.psns": None, "sensors.camera": None,
                                  "firmware.alignment.heading_source": "config"})
    d = tmp_path_factory.mktemp("faults") / "run"
    return run_scenario(scn, d), d


def test_every_fault_fired_with_evidence_and_the_run_is_valid(imu_gnss_run):
    s, _ = imu_gnss_run
    assert s["valid"] is True and s["passed"] is True
    for f in s["faults"]:
        assert f["fired"] is True, f
        assert any(f["evidence"][k] > 0 for k in f["effect"]), f
    f = _by_index(s)
    assert f[0]["evidence"] == {"glitched_fixes": 3}
    assert f[1]["evidence"]["epochs_without_fix"] == 3  # fewer than four satellites: no fix
    assert f[2]["evidence"]["degraded_fixes"] == 3
    # the instants at both ends of a window may or may not see the fault (callbacks at the same time)
    assert 800 <= f[3]["evidence"]["samples_biased"] <= 801  # 4 s at 200 Hz
    assert 400 <= f[4]["evidence"]["samples_stuck"] <= 401
    assert 200 <= f[5]["evidence"]["samples_clipped"] <= 201  # gravity (1 g) on z above the 0.5 g range
    assert 150 < f[6]["evidence"]["datagrams_dropped"] < 250  # 400 datagrams at p = 0.5
    assert f[7]["evidence"]["held_back"] > 100  # GNSS bytes the FPGA did not forward
    assert 399 <= f[8]["evidence"]["ticks_loaded"] <= 401  # 18 s to the end
    assert f[9]["evidence"]["epochs_without_fix"] == 1


def test_fault_events_have_start_end_evidence_and_firmware_effects(imu_gnss_run):
    s, d = imu_gnss_run
    ev = [e for e in _events(d) if e["source"] == "fault"]
    starts = {e["index"]: e for e in ev if e["event"] == "fault_start"}
    ends = {e["index"]: e for e in ev if e["event"] == "fault_end"}
    assert set(starts) == set(ends) == set(range(10))
    assert starts[0]["t_s"] == 3.0 and ends[0]["t_s"] == 6.0 and starts[0]["fault"] == "gnss_glitch"
    assert ends[8]["t_s"] == pytest.approx(20.0)  # no duration: until the end of the run
    assert ends[0]["evidence"] == {"glitched_fixes": 3} and ends[0]["fired"] is True
    # what the faults did downstream: the missing datagrams and the unforwarded GNSS bytes
    assert ends[6]["firmware"]["fpga_gyro_missing"] == _by_index(s)[6]["evidence"]["datagrams_dropped"]
    assert ends[7]["firmware"].get("gnss_updates", 0) == 0 and ends[7]["firmware"].get("gnss_fixes", 0) == 0


def test_injected_faults_show_in_the_run_summary(imu_gnss_run):
    s, _ = imu_gnss_run
    assert s["fpga"]["gyro_missing"] == _by_index(s)[6]["evidence"]["datagrams_dropped"]
    assert s["dsp"]["extra_load_ticks"] == _by_index(s)[8]["evidence"]["ticks_loaded"]
    assert s["dsp"]["deadline_misses"] == 0  # 50 % fits in a tick
    assert s["devices"]["gnss_epochs"] == 20


# ------------------------------------------------------------------------------------------ device capabilities
def _gyro(errs="perfect"):
    from emulator.clock import EmulatorLoop
    from emulator.devices.imu import GyroErrors, ImuTruthTap, Stim210Gyro
    from emulator.links import LineConfig, MemHub
    from emulator.world.trajectory import StaticTrajectory
    from protocols.stim import Stim210Format
    from protocols.stream import StreamDecoder

    loop = EmulatorLoop("fast")
    a, b = MemHub().pair("gyro", LineConfig(baud=460800), loop)
    traj = StaticTrajectory(39.979, 116.339, 50.0, 30.0)
    gyro = Stim210Gyro(a, ImuTruthTap(traj), np.random.default_rng(1),
                       GyroErrors(**preset("imu", errs)["gyro"]))
    dec = StreamDecoder([Stim210Format("m")])
    got = []
    b.on_receive = lambda data: got.extend(dec.feed(data))
    return loop, gyro, got, traj


def _trigger(loop, gyro, k0, k1):
    async def main():
        for k in range(k0, k1):  # one trigger every 5 ms of the emulator's clock, as the FPGA does
            await asyncio.sleep(max(0.0, k * 0.005 - loop.time()))
            gyro.trigger(k * 0.005, (k - 1) * 0.005)
        await asyncio.sleep(0.05)

    loop.run_until_complete(main())


def test_gyro_bias_step_stuck_axis_and_range_limit_act_on_the_words():
    from protocols.stim import GYRO_RATE_LSB_DPS

    loop, gyro, got, traj = _gyro()
    w = traj.angular_rate(0.0) / DEG / GYRO_RATE_LSB_DPS
    _trigger(loop, gyro, 1, 3)
    gyro.set_bias_step("a", np.array([0.0, 0.0, 1.0]) * DEG)  # +1 deg/s on z
    gyro.set_bias_step("b", np.array([0.5, 0.0, 0.0]) * DEG)
    _trigger(loop, gyro, 3, 5)
    gyro.set_bias_step("a", None)
    gyro.set_bias_step("b", None)
    _trigger(loop, gyro, 5, 6)
    base = tuple(round(x) for x in w)
    step = tuple(round(x) for x in w + np.array([0.5, 0.0, 1.0]) / GYRO_RATE_LSB_DPS)
    assert [d.gyro for d in got] == [base, base, step, step, base]
    assert gyro.faults.biased == 2 and not gyro.faults.active
    # a stuck axis holds its last output while the others move on
    gyro.set_bias_step("c", np.array([1.0, 1.0, 1.0]) * DEG)
    _trigger(loop, gyro, 6, 7)
    gyro.set_stuck_axis(0, True)
    gyro.set_bias_step("c", np.array([2.0, 2.0, 2.0]) * DEG)
    _trigger(loop, gyro, 7, 9)
    assert got[-1].gyro[0] == got[-3].gyro[0] and got[-1].gyro[1] > got[-3].gyro[1]
    assert gyro.faults.stuck_samples == 2
    gyro.set_stuck_axis(0, False)
    gyro.set_bias_step("c", None)
    # a range of 0.001 deg/s clips the Earth rate's vertical component (~0.0027 deg/s at 40 N)
    gyro.set_range_limit(0.001 * DEG)
    _trigger(loop, gyro, 9, 11)
    lim = round(0.001 / GYRO_RATE_LSB_DPS)
    assert all(abs(x) <= lim for x in got[-1].gyro) and gyro.faults.clipped == 2
    loop.close()


def test_gyro_datagram_drop_probability_and_counter_gap():
    loop, gyro, got, _ = _gyro()
    gyro.set_datagram_drop(0.25, np.random.default_rng(5))
    _trigger(loop, gyro, 1, 2001)
    loop.close()
    n = gyro.datagrams_dropped
    assert abs(n - 500) < 5 * math.sqrt(2000 * 0.25 * 0.75)  # binomial within 5 sigma
    assert len(got) == 2000 - n
    steps = {(b.counter - a.counter) % 256 for a, b in itertools.pairwise(got)}
    assert 10 in steps and 20 in steps  # the STIM counter keeps counting: a drop is a visible gap


def test_bit_errors_flip_bits_at_the_configured_rate():
    """The injector's bit-error count over many bytes follows Binomial(n bits, BER)."""
    from emulator.faults.link import LinkBitErrors
    from emulator.links import LineConfig, MemHub
    from emulator.scenario.faults_schema import LinkBitErrorsFault

    class Emu:
        links: ClassVar[dict] = {}

    loop = asyncio.new_event_loop()
    a, _b = MemHub().pair("gnss", LineConfig(baud=9600), loop)
    Emu.links = {"gnss": a}
    spec = LinkBitErrorsFault(link="gnss", ber=1e-3)
    inj = LinkBitErrors(Emu, "link_bit_errors", spec, 0, np.random.default_rng(3))
    data = bytes(range(256)) * 400  # 102 400 bytes, 1 024 000 bits on the wire
    out = b"".join(inj.apply(a, "in", 0.0, data[i:i + 100]) for i in range(0, len(data), 100))
    loop.close()
    ev = inj.evidence()
    flips = ev["bytes_corrupted"] + ev["framing_errors"] + ev["parity_errors"]
    expect = len(data) * 10 * 1e-3
    assert abs(flips - expect) < 5 * math.sqrt(expect)  # a byte with two flips counts once: negligible at 1e-3
    assert ev["framing_errors"] == pytest.approx(0.2 * flips, rel=0.25)  # 2 of 10 wire bits are start/stop
    assert len(out) == len(data) - ev["framing_errors"]  # a framing error loses its byte
    assert sum(x != y for x, y in zip(out, data)) > 0
    assert a.stats.corrupted_bytes == ev["bytes_corrupted"] and a.stats.framing_errors == ev["framing_errors"]


# ------------------------------------------------------------------------------------------ links
@pytest.fixture(scope="module")
def link_run(tmp_path_factory):
    faults = [
        {"link_bit_errors": {"link": "gnss", "ber": 1.0e-3, "start_s": 2, "duration_s": 3}},
        {"link_byte_drops": {"link": "uart1", "probability": 0.01, "start_s": 2, "duration_s": 2}},
        {"link_noise_burst": {"link": "gyro", "start_s": 5, "duration_s": 0.2}},
        {"link_disconnect": {"link": "host", "start_s": 6, "duration_s": 1}},
        {"link_stall": {"link": "host", "start_s": 8, "duration_s": 0.5}},
        {"link_baud_mismatch": {"link": "gnss", "baud_error_pct": -9, "start_s": 9, "duration_s": 3}},
    ]
    scn = _scn(QS, 13, faults)
    d = tmp_path_factory.mktemp("links") / "run"
    return run_scenario(scn, d), d


def test_link_faults_fire_and_show_in_the_link_counters(link_run):
    s, _ = link_run
    f = _by_index(s)
    assert s["valid"] is True and all(x["fired"] for x in s["faults"])
    assert s["links"]["gnss"]["crc_errors"] >= 1 and s["links"]["uart3"]["crc_errors"] >= 1
    assert f[1]["evidence"]["bytes_dropped"] == s["link_stats"]["uart1"]["dropped_in"] > 0
    assert s["links"]["uart1"]["crc_errors"] >= 1  # IMU frames with a missing byte fail their CRC
    assert f[2]["evidence"]["spurious_bytes"] > 0 and s["links"]["gyro"]["garbage_bytes"] > 0
    # the host cable out for 1 s: nothing crosses it, 100 navigation frames lost
    assert f[3]["evidence"]["bytes_lost"] >= 100 * 109
    assert f[4]["evidence"]["bytes_held"] > 0
    assert f[5]["evidence"]["framing_errors"] > 0
    assert s["link_stats"]["gnss"]["framing_errors"] >= f[5]["evidence"]["framing_errors"]
    # links without faults stay clean
    assert s["links"]["uart0"]["crc_errors"] == 0 and s["links"]["uart0"]["dropped"] == 0


def test_disconnect_leaves_a_gap_and_a_stalled_line_delivers_its_backlog_at_the_end(link_run):
    _s, d = link_run
    import csv

    with open(d / "nav.csv") as f:
        rows = list(csv.DictReader(f))
    arr = [float(r["arrival_s"]) for r in rows]
    gaps = [(b - a, a) for a, b in itertools.pairwise(arr)]
    big = [(g, a) for g, a in gaps if g > 0.2]
    assert any(0.99 < g < 1.02 and 5.99 < a < 6.01 for g, a in big), big  # the disconnect
    # the stalled half second: frames arrive in one burst at 8.5 s (the backlog), none before
    during = [t for t in arr if 8.0 + 0.003 < t < 8.5]
    assert not during
    burst = [t for t in arr if abs(t - 8.5) < 1e-9]
    assert len(burst) >= 30


def test_baud_mismatch_inside_the_uart_tolerance_never_fires_and_invalidates_the_run(tmp_path):
    scn = _scn(QS, 6, [{"link_baud_mismatch": {"link": "gnss", "baud_error_pct": 3, "start_s": 1}}])
    s = run_scenario(scn, tmp_path / "run")
    assert s["faults"][0]["fired"] is False and s["faults"][0]["evidence"]["framing_errors"] == 0
    assert s["valid"] is False and s["passed"] is False


def test_a_fault_that_never_fires_invalidates_the_run_and_exits_1(tmp_path):
    """A gyro range of 100 deg/s is never reached by a box standing still: the test would prove nothing."""
    text = QS.read_text().replace("duration_s: 120", "duration_s: 4").replace("{duration_s: 120}", "{duration_s: 4}")
    text = text[: text.index("expectations:")]
    text += "faults:\n  - imu_saturation: {gyro_range_dps: 100, start_s: 1}\nexpectations:\n" \
            "  - link: {name: uart1, counter: crc_errors, max: 0}\n"
    p = tmp_path / "s.yaml"
    p.write_text(text)
    out = tmp_path / "run"
    r = subprocess.run([sys.executable, "-m", "emulator", "run", str(p), "--out", str(out), "--no-report"],
                       capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 1, r.stdout + r.stderr
    assert "run invalid" in r.stdout and "imu_saturation" in r.stdout and "samples_clipped 0" in r.stdout
    s = json.loads((out / "summary.json").read_text())
    assert s["valid"] is False and s["passed"] is False
    assert all(e["passed"] for e in s["expectations"])  # the expectations alone would have passed
    end = next(e for e in _events(out) if e["event"] == "fault_end")
    assert end["fired"] is False and end["evidence"] == {"samples_clipped": 0}


# ------------------------------------------------------------------------------------------ PSNS
@pytest.fixture(scope="module")
def camera_run(tmp_path_factory):
    faults = [
        {"psns_cloud_cover": {"start_s": 2, "duration_s": 2}},
        {"psns_sun_occluded": {"start_s": 4, "duration_s": 2, "radius_deg": 40}},
        {"psns_unit_blocked": {"start_s": 6, "duration_s": 1}},
        {"psns_installation_error": {"start_s": 8, "duration_s": 2, "rotation_deg": [0, 0, 3]}},
    ]
    scn = _scn(CAM, 10, faults, epoch="2019-09-18T04:00:00Z")
    d = tmp_path_factory.mktemp("cam") / "run"
    return run_scenario(scn, d), d


def test_psns_faults_on_the_camera(camera_run):
    s, _ = camera_run
    f = _by_index(s)
    assert s["valid"] is True
    assert f[0]["evidence"]["rays_in_cloud"] == 10 * 225  # 2 s at 5 frames/s, every point under the cloud
    assert f[1]["evidence"]["rays_near_sun_hidden"] > 0
    assert f[2]["evidence"]["frames_blocked"] == 5 and f[2]["target"] == "polarization camera"
    assert f[3]["evidence"]["frames_with_error"] == 10
    # the cloud and the blocked lens leave the firmware without valid PSNS frames for a while
    assert f[0]["firmware"]["psns_invalid"] >= 8
    assert f[2]["firmware"]["psns_invalid"] == 5


def test_psns_faults_on_the_compass(tmp_path):
    faults = [{"psns_unit_blocked": {"start_s": 1, "duration_s": 1, "units": [1, 2, 3]}},
              {"psns_installation_error": {"start_s": 2, "duration_s": 1, "rotation_deg": [2, 0, 0]}}]
    scn = _scn(CAM, 4, faults, **{"sensors": {"compass": {"preset": "paper"}}})
    s = run_scenario(scn, tmp_path / "run")
    f = _by_index(s)
    assert s["valid"] is True and s["devices"]["compass_frames"] > 0
    assert f[0]["evidence"]["unit_readings_blocked"] == 15  # 3 units x 5 frames
    assert f[0]["target"] == "compass units 1, 2, 3"
    assert f[1]["evidence"]["frames_with_error"] == 5


def test_cloud_fault_changes_the_camera_frames(tmp_path):
    """Under the injected cloud the observation points' DOP drops by the cloud's factor."""
    from emulator.recording.capture import read_capture
    from protocols.psns import PolarizationObs, PsnsFormat
    from protocols.stream import StreamDecoder

    scn = _scn(CAM, 3, [{"psns_cloud_cover": {"start_s": 1, "duration_s": 1, "dop_scale": 0.25,
                                              "aop_sigma_deg": 0}}])
    run_scenario(scn, tmp_path / "run")
    _, recs = read_capture(tmp_path / "run" / "capture.psnscap")
    dec = StreamDecoder([PsnsFormat()])
    frames = []
    for r in recs:
        if r.link == "psns" and r.direction == "in":
            frames += [(r.t_s, f) for f in dec.feed(r.data) if isinstance(f, PolarizationObs)]
    mean_dop = {round(t, 3): np.mean([p.dop for p in f.points]) / 65535 for t, f in frames if f.points}
    clear = [v for t, v in mean_dop.items() if t < 1.0 or t > 2.05]
    cloudy = [v for t, v in mean_dop.items() if 1.05 < t < 2.0]
    assert cloudy and clear
    assert np.mean(cloudy) == pytest.approx(0.25 * np.mean(clear), rel=0.1)


# ------------------------------------------------------------------------------------------ determinism
def test_runs_with_faults_are_deterministic(tmp_path):
    faults = [{"link_bit_errors": {"link": "gnss", "ber": 1.0e-3, "start_s": 1}},
              {"imu_dropped_datagrams": {"start_s": 1, "probability": 0.1}}]
    a = run_scenario(_scn(QS, 4, faults), tmp_path / "a")
    b = run_scenario(_scn(QS, 4, faults), tmp_path / "b")
    assert a["faults"] == b["faults"]
    assert (tmp_path / "a" / "capture.psnscap").read_bytes() == (tmp_path / "b" / "capture.psnscap").read_bytes()
    assert (tmp_path / "a" / "nav.csv").read_text() == (tmp_path / "b" / "nav.csv").read_text()
    c = run_scenario(_scn(QS, 4, faults, seed=2), tmp_path / "c")
    assert c["faults"][0]["evidence"] != a["faults"][0]["evidence"]


def test_a_fault_does_not_change_the_sensors_random_numbers(tmp_path):
    """Fault draws come from their own streams: before a fault starts, a run is byte-identical to one
    without it."""
    from emulator.recording.capture import read_capture

    a = tmp_path / "a"
    b = tmp_path / "b"
    run_scenario(_scn(QS, 4, []), a)
    run_scenario(_scn(QS, 4, [{"link_bit_errors": {"link": "gnss", "ber": 0.01, "start_s": 3}}]), b)
    ra = [r for r in read_capture(a / "capture.psnscap")[1] if r.t_s < 3.0]
    rb = [r for r in read_capture(b / "capture.psnscap")[1] if r.t_s < 3.0]
    assert [(r.t_s, r.link, r.data) for r in ra] == [(r.t_s, r.link, r.data) for r in rb]


def test_every_fault_kind_has_one_registered_injector():
    from emulator.faults.base import INJECTORS, Injector, injector_classes, injects
    from emulator.scenario.faults_schema import FAULT_KINDS

    assert injector_classes() is INJECTORS
    assert set(INJECTORS) == set(FAULT_KINDS)
    assert all(issubclass(c, Injector) for c in INJECTORS.values())
    with pytest.raises(ValueError, match="already has an injector"):
        injects("gnss_outage")(type("Other", (Injector,), {}))
