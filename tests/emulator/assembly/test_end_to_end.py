"""The quickstart slice end to end: sensors -> FPGA -> DSP firmware -> host, against truth."""

import itertools
import json

import pytest

from emulator.assembly.session import run_scenario
from emulator.recording.capture import read_capture
from emulator.scenario import load_scenario
from protocols.imu_frame import ImuFrameFormat
from protocols.nmea import Gga, NmeaFormat
from protocols.stim import Stim210Format
from protocols.stream import StreamDecoder


@pytest.fixture(scope="module")
def short_run(tmp_path_factory):
    from tests.conftest import SCENARIOS

    scn = load_scenario(SCENARIOS / "quickstart.yaml")
    scn.duration_s = 30.0
    out = tmp_path_factory.mktemp("qs")
    summary = run_scenario(scn, out / "run")
    return scn, summary, out / "run"


def test_dsp_decoded_exactly_the_frames_the_devices_sent(short_run):
    _scn, s, run_dir = short_run
    _header, records = read_capture(run_dir / "capture.psnscap")
    gyro_in = b"".join(r.data for r in records if r.link == "gyro" and r.direction == "in")
    uart1_in = b"".join(r.data for r in records if r.link == "uart1" and r.direction == "in")
    datagrams = StreamDecoder([Stim210Format("m")]).feed(gyro_in)
    imu_frames = StreamDecoder([ImuFrameFormat()]).feed(uart1_in)
    # every datagram the STIM model transmitted arrived, in order, unaltered, inside an IMU frame
    assert len(datagrams) == s["devices"]["gyro_datagrams"]
    assert len(imu_frames) in (len(datagrams), len(datagrams) - 1)  # the last may still be in flight
    assert [f.gyro for f in imu_frames] == [d.gyro for d in datagrams[: len(imu_frames)]]
    assert [f.gyro_counter for f in imu_frames] == [d.counter for d in datagrams[: len(imu_frames)]]
    assert all((b.gyro_counter - a.gyro_counter) % 256 == 10 for a, b in itertools.pairwise(imu_frames))
    # the firmware decoded each of them once and nothing else
    fw = s["firmware"]
    assert fw["counters"]["imu_frames"] == len(imu_frames)
    assert fw["decoders"]["uart1"]["frames"] == len(imu_frames)
    assert fw["decoders"]["uart1"]["crc_errors"] == 0 and fw["decoders"]["uart1"]["garbage_bytes"] == 0
    assert fw["counters"]["gyro_counter_jumps"] == 0
    # GNSS: every sentence pair the receiver sent reached the firmware through the FPGA
    gnss_in = b"".join(r.data for r in records if r.link == "gnss" and r.direction == "in")
    sentences = StreamDecoder([NmeaFormat()]).feed(gnss_in)
    ggas = [x for x in sentences if isinstance(x, Gga)]
    assert len(ggas) == s["devices"]["gnss_epochs"]
    assert fw["counters"]["gnss_fixes"] == len(ggas)
    assert fw["decoders"]["uart3"]["frames"] == len(sentences)
    # the host saw the navigation frames the DSP sent (100 Hz)
    assert s["links"]["uart0"]["frames"] >= 100 * 30 - 2
    assert s["links"]["host"]["crc_errors"] == 0


def test_navigation_error_is_bounded_against_truth(short_run):
    _, s, _ = short_run
    e = s["nav_error"]
    assert e["position_m"]["rms"] < 20.0
    assert e["velocity_mps"]["rms"] < 0.5
    assert e["attitude_deg"]["max"] < 2.0
    assert s["dsp"]["deadline_misses"] == 0
    assert 0 < s["dsp"]["tick_utilization_max_pct"] < 20.0


def test_run_directory_contents(short_run):
    _, _s, run_dir = short_run
    summary = json.loads((run_dir / "summary.json").read_text())
    for key in ("scenario", "seed", "mode", "sim_duration_s", "wall_s", "realtime_factor", "nav_error", "links", "dsp"):
        assert key in summary
    for m in ("attitude_deg", "heading_deg", "position_m", "velocity_mps"):
        assert set(summary["nav_error"][m]) == {"rms", "max"}
    for name in ("gyro", "gnss", "host", "uart0", "uart1", "uart3"):
        assert set(summary["links"][name]) >= {"bytes", "frames", "crc_errors", "dropped"}
    assert set(summary["dsp"]) >= {"clock_hz", "cpu_load_pct_max", "deadline_misses"}
    nav_head = (run_dir / "nav.csv").read_text().splitlines()[0].split(",")
    truth_head = (run_dir / "truth.csv").read_text().splitlines()[0].split(",")
    assert "lat_deg" in nav_head and "vel_e_mps" in nav_head and "err_pos_m" in nav_head
    assert truth_head[:4] == ["time_s", "lat_deg", "lon_deg", "height_m"]


def test_same_seed_gives_identical_bytes(tmp_path):
    from tests.conftest import SCENARIOS

    scn = load_scenario(SCENARIOS / "quickstart.yaml")
    scn.duration_s = 5.0
    run_scenario(scn, tmp_path / "a")
    run_scenario(scn, tmp_path / "b")
    # byte-identical files, the capture's header and record times included
    for name in ("capture.psnscap", "nav.csv", "truth.csv", "events.jsonl"):
        assert (tmp_path / "a" / name).read_bytes() == (tmp_path / "b" / name).read_bytes(), name
    assert (tmp_path / "a" / "capture.psnscap").stat().st_size > 100_000
    # and a different seed really changes the sensor bytes
    run_scenario(scn, tmp_path / "c", seed=2)
    assert (tmp_path / "c" / "capture.psnscap").read_bytes() != (tmp_path / "a" / "capture.psnscap").read_bytes()


def test_replay_reproduces_the_navigation_output_bit_for_bit(short_run, tmp_path):
    from emulator.postrun.replay import run_replay, same_file

    _scn, s, run_dir = short_run
    r = run_replay(run_dir / "capture.psnscap", tmp_path / "replay")
    assert r["replay"]["records"] > 6000
    assert same_file(run_dir / "nav.csv", tmp_path / "replay" / "nav.csv")
    assert same_file(run_dir / "truth.csv", tmp_path / "replay" / "truth.csv")
    _h, orig = read_capture(run_dir / "capture.psnscap")
    _h, rep = read_capture(tmp_path / "replay" / "capture.psnscap")
    for link in ("uart0", "host"):
        a = [(x.t_s, x.data) for x in orig if x.link == link and x.direction == "out"]
        b = [(x.t_s, x.data) for x in rep if x.link == link and x.direction == "out"]
        assert a == b and len(a) > 2900, link
    assert r["dsp"]["ticks"] == s["dsp"]["ticks"]
    assert r["firmware"]["counters"] == s["firmware"]["counters"]


def test_crossbar_is_cut_through(short_run):
    """HOST gets each nav frame one byte time after UART0 delivered its last byte (same baud)."""
    _scn, _s, run_dir = short_run
    _h, recs = read_capture(run_dir / "capture.psnscap")
    u0 = [r.t_s for r in recs if r.link == "uart0" and r.direction == "out"]
    host = [r.t_s for r in recs if r.link == "host" and r.direction == "out"]
    bt = 10 / 460800
    assert len(host) >= len(u0) - 1 > 2900
    assert all(abs((h - u) - bt) < 1e-9 for u, h in zip(u0, host))
    # GNSS bytes reach the DSP over EMIFA as they arrive: one 0.1 us bus read after the port
    gnss = [r.t_s for r in recs if r.link == "gnss" and r.direction == "in"]
    u3 = [r.t_s for r in recs if r.link == "uart3" and r.direction == "in"]
    assert len(gnss) == len(u3) > 20
    assert all(abs((b - a) - 1e-7) < 1e-9 for a, b in zip(gnss, u3))
