"""The DSP out (``dsp.external``): the example C firmware (examples/c_firmware) in the virtual DSP's place over
ptys, and an outside DSP that sends garbage or nothing.

The C firmware (psns_nav, built as the pty program psns_nav_pty) is a free-inertial strapdown with no bias
estimate that compensates the Earth's rotation, so on a static box its attitude after ``t - t0`` s is, in closed
form, ``C_b^n(t) = exp(-[w_ie^n x] (t - t0)) C_b^n(t0) exp([w x] (t - t0))`` with ``w = C_n^b w_ie^n + b`` the
gyro's reading: the Earth's rotation seen in the body plus the turn-on bias the world drew (the other gyro errors
are set to zero in the scenario, so the reading is exactly that, up to the 2^-14 deg/s quantum; the transport rate
of its small velocity error is below 1e-7 rad/s). The attitude error is then the bias alone, rotated. The expected
error is computed here from truth (scipy's Rotation, the WGS-84 Earth rate) and the drawn bias, never from the C
program's own output.
"""

from __future__ import annotations

import csv
import json
import math
import os
import shutil
import subprocess
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from scipy.spatial.transform import Rotation

from emulator.assembly.session import Emulator, run_emulator
from emulator.recording.summary_model import load_summary
from emulator.scenario import load_scenario
from protocols.host import MSG_NAV_SOLUTION, NAV_SOLUTION_LEN, build_host_frame
from protocols.monitor import MONITOR_CHANNELS, MonitorFormat
from protocols.stream import StreamDecoder

ROOT = Path(__file__).resolve().parents[3]
OMEGA_IE = 7.2921151467e-5  # WGS-84 Earth rotation rate, rad/s
ORIGIN = {"lat_deg": 39.979, "lon_deg": 116.339, "height_m": 50.0}
ATTITUDE = {"heading_deg": 30.0, "pitch_deg": 2.0, "roll_deg": -1.5}
DURATION_S = 10.0
#: every gyro error but the turn-on bias set to zero: the reading is the Earth rate plus the bias
GYRO_BIAS_ONLY = {"arw_deg_rt_h": 0.0, "bias_repeatability_deg_h": 300.0, "bias_instability_deg_h": 0.0,
                  "rate_random_walk_deg_h_rt_h": 0.0, "scale_factor_ppm": 0.0, "scale_asymmetry_ppm": 0.0,
                  "misalignment_mrad": 0.0, "nonlinearity_ppm_fs": 0.0, "bias_temp_coeff_deg_h_per_c": 0.0,
                  "bias_temp_gradient_deg_h": 0.0, "g_sensitivity_deg_h_per_g": 0.0}


def _scenario(path: Path, uarts: dict[str, str], duration_s: float = DURATION_S, silence_s: float = 2.0,
              monitor: bool = False) -> Path:
    data: dict = {
        "name": "dsp_out", "seed": 7, "epoch": "2019-09-18T02:30:00Z", "duration_s": duration_s,
        "mode": "realtime", "origin": ORIGIN, "attitude": ATTITUDE,
        "motion": [{"static": {"duration_s": duration_s}}],
        "sensors": {"imu": {"gyro": GYRO_BIAS_ONLY}},
        "dsp": {"external": {"uarts": uarts, "silence_s": silence_s}},
    }
    if monitor:
        data["links"] = {"monitor": {"url": "mem://monitor"}}
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


@pytest.fixture(scope="module")
def psns_nav_pty(tmp_path_factory) -> Path:
    """The example firmware's pty program, built by its Makefile into a temporary directory."""
    if shutil.which(os.environ.get("CC", "gcc")) is None:
        pytest.skip("no C compiler (gcc) on this machine: the example C firmware cannot be built")
    build = tmp_path_factory.mktemp("c_firmware")
    subprocess.run(["make", "-s", "-C", str(ROOT / "examples" / "c_firmware"), f"BUILD={build}"], check=True,
                   timeout=120)
    return build / "psns_nav_pty"


def _expected_angles(c_bn0: Rotation, w_b: np.ndarray, w_n: np.ndarray, dt: np.ndarray) -> np.ndarray:
    """(roll, pitch, heading) deg of ``exp(-[w_n x] dt) C_b^n(t0) exp([w_b x] dt)`` per ``dt``: the intrinsic ZXY
    Euler angles (C_b^n = R_z(yaw) R_x(pitch) R_y(roll), heading = -yaw)."""
    r = Rotation.from_rotvec(-np.outer(dt, w_n)) * c_bn0 * Rotation.from_rotvec(np.outer(dt, w_b))
    yaw, pitch, roll = r.as_euler("ZXY").T
    return np.column_stack([np.degrees(roll), np.degrees(pitch), np.degrees(-yaw) % 360.0])


@pytest.mark.realtime
@pytest.mark.pty
def test_c_firmware_navigates_in_the_loop_over_ptys(psns_nav_pty, tmp_path):
    scn = load_scenario(_scenario(tmp_path / "dsp_out.yaml", {"uart0": "pty://dsp_uart0", "uart1": "pty://dsp_uart1"},
                                  monitor=True))
    run_dir = tmp_path / "run"
    procs: list[subprocess.Popen[bytes]] = []
    monitor = bytearray()

    class _Monitor:
        def on_link_bytes(self, link, direction, t, data):
            if direction == "out":
                monitor.extend(data)
    att = f"{ATTITUDE['heading_deg']},{ATTITUDE['pitch_deg']},{ATTITUDE['roll_deg']}"
    pos = f"{ORIGIN['lat_deg']},{ORIGIN['lon_deg']},{ORIGIN['height_m']}"

    def on_started(emu: Emulator) -> None:  # the ports exist: the foreign firmware attaches to them
        emu.links["monitor"].listeners.append(_Monitor())
        ports = run_dir / "ports"
        procs.append(subprocess.Popen([str(psns_nav_pty), "--imu", str(ports / "dsp_uart1"), "--host",
                                       str(ports / "dsp_uart0"), "--attitude", att, "--position", pos],
                                      stderr=subprocess.PIPE))

    emu = Emulator(scn, run_dir)
    summary = run_emulator(emu, 1.0, on_started)
    (proc,) = procs
    try:
        _out, err = proc.communicate(timeout=10)  # it ends when the emulator closes its UART1
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 0, err.decode()
    assert b"crc_errors=0" in err, err.decode()

    # the recorder decoded the C firmware's frames at the host port, and the external_dsp section agrees
    ext = summary["external_dsp"]
    rows = list(csv.DictReader((run_dir / "nav.csv").read_text().splitlines()))
    assert summary["nav_frames"] == len(rows) >= 0.7 * 200 * DURATION_S  # one per IMU frame, after attaching
    assert ext["nav_frames"] >= len(rows) and ext["crc_errors"] == 0 and ext["garbage_bytes"] == 0
    assert ext["silences"] == 0 and not ext["silent"]
    assert summary["links"]["host"]["crc_errors"] == 0
    assert summary["dsp"]["external"] is True
    # the FPGA's MONITOR port still mirrors the cut UARTs: UART1 towards the DSP, UART0 from it, byte for byte
    recs = StreamDecoder([MonitorFormat()]).feed(bytes(monitor))
    by = {(c, d): sum(len(r.data) for r in recs if (r.channel, r.direction) == (c, d)) for c in (4, 5) for d in (0, 1)}
    assert by[(MONITOR_CHANNELS["uart1"], 0)] == ext["uarts"]["uart1"]["bytes_to_dsp"] > 0
    # from the DSP: byte for byte but for the tail the run's end cut off. The FPGA mirrors a UART0 chunk after the
    # emulator has read it from the board's pty, so a frame read in the run's last instant can miss its MONITOR
    # record (one 109-byte frame in one CI run of 2026-12-03: 217019 mirrored of 217128)
    from_dsp = ext["uarts"]["uart0"]["bytes_from_dsp"]
    nav_frame_bytes = len(build_host_frame(MSG_NAV_SOLUTION, bytes(NAV_SOLUTION_LEN)))
    assert from_dsp > 0 and 0 <= from_dsp - by[(MONITOR_CHANNELS["uart0"], 1)] <= nav_frame_bytes
    typed = load_summary(run_dir)  # summary.json reads through the typed model
    assert typed.external_dsp is not None and typed.external_dsp.nav_frames == ext["nav_frames"]
    assert typed.dsp is not None and typed.dsp.deadline_misses is None  # the board's own: not observed

    # the closed form: the attitude drift of a free-inertial strapdown (Earth rate compensated, bias not)
    assert emu.sensors is not None
    bias = np.asarray(emu.sensors.gyro.turn_on_bias, dtype=float)
    assert np.linalg.norm(bias) > 50 * math.pi / 180 / 3600  # the drift is mostly the drawn bias
    lat = math.radians(ORIGIN["lat_deg"])
    w_ie_n = OMEGA_IE * np.array([0.0, math.cos(lat), math.sin(lat)])  # ENU
    c_bn0 = Rotation.from_euler("ZXY", [-math.radians(ATTITUDE["heading_deg"]), math.radians(ATTITUDE["pitch_deg"]),
                                        math.radians(ATTITUDE["roll_deg"])])
    w_b = c_bn0.inv().apply(w_ie_n) + bias
    t = np.array([float(r["time_s"]) for r in rows])
    got_err = np.array([[float(r["err_roll_deg"]), float(r["err_pitch_deg"]), float(r["err_heading_deg"])]
                        for r in rows])
    truth = np.array([ATTITUDE["roll_deg"], ATTITUDE["pitch_deg"], ATTITUDE["heading_deg"]])
    want = _expected_angles(c_bn0, w_b, w_ie_n, t - t[0]) - truth
    want[:, 2] = (want[:, 2] + 180.0) % 360.0 - 180.0
    drift_deg = math.degrees(np.linalg.norm(bias)) * (t[-1] - t[0])
    assert drift_deg > 0.3  # the check below could not pass by a firmware that does not integrate
    # float32 angles on the wire (~1e-5 deg) and the gyro word's 2^-14 deg/s quantum over 10 s (~1e-3 deg);
    # measured 2.5e-4 deg
    print(f"drift {drift_deg:.4f} deg, final error {got_err[-1]}, max |got - want| "
          f"{abs(got_err - want).max():.2e} deg")
    np.testing.assert_allclose(got_err, want, atol=1e-3)
    assert abs(got_err[-1]).max() > 0.1


@pytest.mark.realtime
@pytest.mark.pty
def test_an_external_dsp_that_sends_garbage_is_counted_not_a_crash(tmp_path):
    scn = load_scenario(_scenario(tmp_path / "g.yaml", {"uart0": "pty://dsp_uart0", "uart1": "pty://dsp_uart1"},
                                  duration_s=3.0))
    run_dir = tmp_path / "run"
    junk = bytes(range(256)) * 4 + b"\xa5\x5a\x01\x66\x00" + bytes(102) + b"\x00\x00"  # bad CRC at the end
    fds: list[int] = []

    def on_started(emu: Emulator) -> None:
        fd = os.open(run_dir / "ports" / "dsp_uart0", os.O_RDWR | os.O_NOCTTY)
        fds.append(fd)
        emu.loop.call_later(0.5, os.write, fd, junk)  # type: ignore[union-attr]

    try:
        summary = run_emulator(Emulator(scn, run_dir), 1.0, on_started)
    finally:
        for fd in fds:
            os.close(fd)
    ext = summary["external_dsp"]
    assert ext["uarts"]["uart0"]["bytes_from_dsp"] == len(junk)
    assert ext["nav_frames"] == 0 and summary["nav_frames"] == 0
    assert ext["crc_errors"] == 1  # the one well-framed NAV_SOLUTION with a wrong CRC
    assert ext["garbage_bytes"] + ext["length_errors"] > 0
    # its bytes went through the FPGA to the host port, where the recorder counted them as well
    assert summary["links"]["host"]["crc_errors"] == 1
    saved = json.loads((run_dir / "summary.json").read_text())
    assert saved["external_dsp"]["crc_errors"] == 1


@pytest.mark.realtime
@pytest.mark.pty
def test_an_external_dsp_that_says_nothing_is_counted_silent(tmp_path):
    scn = load_scenario(_scenario(tmp_path / "s.yaml", {"uart0": "pty://dsp_uart0", "uart1": "pty://dsp_uart1"},
                                  duration_s=3.0, silence_s=1.0))
    run_dir = tmp_path / "run"
    fds: list[int] = []

    def on_started(emu: Emulator) -> None:  # a board that is connected (it reads its UART1) but never answers
        fds.append(os.open(run_dir / "ports" / "dsp_uart1", os.O_RDONLY | os.O_NOCTTY | os.O_NONBLOCK))

    t0 = time.monotonic()
    try:
        summary = run_emulator(Emulator(scn, run_dir), 1.0, on_started)
    finally:
        for fd in fds:
            os.close(fd)
    assert time.monotonic() - t0 < 30
    ext = summary["external_dsp"]
    assert ext["silent"] is True and ext["silences"] == 1
    assert ext["uarts"]["uart1"]["bytes_to_dsp"] > 0 and ext["uarts"]["uart0"]["bytes_from_dsp"] == 0
    assert 1.0 < ext["silent_s"] <= 3.0
    assert summary["nav_frames"] == 0
    events = [json.loads(line) for line in (run_dir / "events.jsonl").read_text().splitlines()]
    assert [e["source"] for e in events if e["event"] == "external_dsp_silent"] == ["external_dsp"]


@pytest.mark.parametrize("case", ["same_pty_as_a_port", "same_pty_twice", "mem"])
def test_external_dsp_ports_are_validated(tmp_path, case):
    from emulator.scenario.loader import ScenarioError

    uarts = {"uart0": "pty://dsp0", "uart1": "pty://dsp1"}
    if case == "same_pty_twice":
        uarts["uart3"] = "pty://dsp0"
    if case == "mem":
        uarts["uart1"] = "mem://dsp1"
    path = _scenario(tmp_path / "v.yaml", uarts)
    if case == "same_pty_as_a_port":
        data = yaml.safe_load(path.read_text())
        data["links"] = {"host": {"url": "pty://dsp1"}}
        path.write_text(yaml.safe_dump(data, sort_keys=False))
    want = {"same_pty_as_a_port": r"dsp.external.uarts.uart1 uses the same pty name 'dsp1' as links.host",
            "same_pty_twice": r"uart3 and uart0 are both bound to 'pty://dsp0'",
            "mem": r"an external DSP needs a byte port \(pty://, serial://, zenoh://\), not mem://"}[case]
    with pytest.raises(ScenarioError, match=want):
        load_scenario(path)


def test_the_example_dsp_out_scenario_validates():
    scn = load_scenario(ROOT / "examples" / "c_firmware" / "dsp_out.yaml")
    assert scn.dsp.external is not None and set(scn.dsp.external.uarts) == {"uart0", "uart1", "uart3"}
