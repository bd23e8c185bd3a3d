"""Sensor streams bound out to real ports (``links.NAME.direction: out | tee``; docs/runtime.md "Sensor ports out").

The realtime tests read the pty with pyserial and compare, byte for byte, with what the FPGA end of the same link
carried (the recorder's capture): the same stream, faults and all, at the same line rate.
"""

from __future__ import annotations

import asyncio
import contextlib
import shutil
import subprocess
import time

import pytest

from emulator.errors import ScenarioError
from emulator.testing import load_test_scenario
from protocols.nmea import NmeaFormat
from protocols.stim import Stim210Format
from protocols.stream import StreamDecoder
from tests.conftest import SCENARIOS

QS = SCENARIOS / "quickstart.yaml"


def _ov(duration: float, **extra) -> dict:
    """The quickstart without the camera (lighter in real time), heading from the configuration."""
    ov = {"duration_s": duration, "motion": [{"static": {"duration_s": duration}}], "expectations": [],
          "links.psns": None, "sensors.camera": None, "firmware.alignment.heading_source": "config",
          "firmware.alignment.heading_deg": 30.0}
    ov.update(extra)
    return ov


# -- validation ------------------------------------------------------------------------------------

def test_direction_defaults_to_in_and_a_pty_still_replaces_the_sensor():
    scn = load_test_scenario(QS, _ov(5.0, **{"links.gnss.url": "pty://gnss"}))
    assert scn.links.gnss.direction == "in" and not scn.links.gnss.modelled
    assert load_test_scenario(QS, _ov(5.0, **{"links.gnss.url": "pty://gnss",
                                               "links.gnss.direction": "tee"})).links.gnss.modelled


@pytest.mark.parametrize(("changes", "where", "says"), [
    ({"links.gnss.direction": "tee"}, "links.gnss.direction", "mem://"),
    ({"links.host.url": "pty://host", "links.host.direction": "out"}, "links.host.direction", "not a sensor port"),
    ({"links.gnss.direction": "sideways", "links.gnss.url": "pty://g"}, "links.gnss.direction", "'in', 'out'"),
    ({"links.gnss.url": "pty://x", "links.gnss.direction": "tee", "links.gyro.url": "pty://x",
      "links.gyro.direction": "out"}, "links.gnss.url", "same pty name 'x' as links.gyro"),
    ({"firmware.nmea.rate_hz": 3.0}, "firmware.nmea.rate_hz", "must divide the IMU rate"),
])
def test_bad_directions_and_shared_ptys_are_validation_errors_naming_the_field(changes, where, says):
    with pytest.raises(ScenarioError) as ei:
        load_test_scenario(QS, _ov(5.0, **changes))
    msg = str(ei.value)
    assert where in msg and says in msg, msg


# -- realtime: pyserial on the bound port ------------------------------------------------------------------

def _capture_in(run_dir, link: str) -> bytes:
    from emulator.recording.capture import read_capture

    _hdr, recs = read_capture(run_dir / "capture.psnscap")
    return b"".join(r.data for r in recs if r.link == link and r.direction == "in")


async def _read_pty(path, until, baud: int) -> bytearray:
    """Read ``path`` with pyserial from the event loop until ``until()`` is done (a task of the caller)."""
    import serial

    ser = serial.Serial(str(path), baud, timeout=0)
    got = bytearray()
    loop = asyncio.get_running_loop()
    loop.add_reader(ser.fileno(), lambda: got.extend(ser.read(65536)))
    try:
        await until()
    finally:
        loop.remove_reader(ser.fileno())
        got.extend(ser.read(65536))
        ser.close()
    return got


@pytest.mark.pty
@pytest.mark.realtime
@pytest.mark.psns_emulator(mode="realtime")
async def test_tee_puts_the_modelled_gnss_on_a_pty_and_the_firmware_still_gets_its_fixes(tmp_path):
    from emulator.testing import start_emulator

    ov = _ov(8.0, **{"links.gnss.url": "pty://gnss", "links.gnss.direction": "tee"})
    async with start_emulator(QS, run_dir=tmp_path, overrides=ov) as emu:
        row = next(p for p in emu.emulator.ports if p["name"] == "gnss")
        assert row["direction"] == "tee" and row["url"] == "pty://gnss"
        assert str(tmp_path / "ports" / "gnss") in row["path"]
        assert emu.emulator.gnss is not None  # the receiver model runs
        pty = tmp_path / "ports" / "gnss"
        t_attach = emu.time

        async def until():
            await emu.wait_until(lambda: emu.emulator.bindings["gnss"].port.attached, timeout=2.0)
            await emu.wait_until(lambda: emu.fw.counters.get("gnss_fixes", 0) >= 4, timeout=7.0)
            await emu.run_for(0.4)  # the last epoch's RMC has left the 9600 baud line

        got = await _read_pty(pty, until, 9600)
        fixes = emu.fw.counters["gnss_fixes"]
    s = emu.summary
    assert t_attach < 1.0  # attached before the first epoch (t = 1.05 s): the pty saw every epoch
    # the pty carried exactly what the FPGA's GNSS port received (the capture), epoch for epoch
    sent = _capture_in(tmp_path, "gnss")
    assert bytes(got) == sent[:len(got)] and len(got) >= len(sent) - 200, (len(got), len(sent))
    dec = StreamDecoder([NmeaFormat()])
    frames = dec.feed(bytes(got))
    assert len(frames) >= 2 * 4 and dec.stats.crc_errors == 0 and dec.stats.garbage_bytes == 0
    assert fixes >= 4 and s["devices"]["gnss_epochs"] >= 4
    b = s["bound_ports"]["gnss"]
    assert b["direction"] == "tee" and b["bytes_out"] == len(sent) and b["dropped_out"] == 0


@pytest.mark.pty
@pytest.mark.realtime
@pytest.mark.psns_emulator(mode="realtime")
async def test_out_gyro_stream_is_paced_at_the_line_rate_and_leaves_the_fpga_idle(tmp_path):
    """The STIM210 at 200 Hz, 15-byte datagrams (format m) on a 460800 baud line: 200 datagrams/s on the pty,
    none at the FPGA (it counts the gyro missing)."""
    from emulator.testing import start_emulator

    ov = _ov(6.0, **{"links.gyro.url": "pty://gyro", "links.gyro.direction": "out"})
    async with start_emulator(QS, run_dir=tmp_path, overrides=ov) as emu:
        arrivals: list[tuple[float, int]] = []
        dec = StreamDecoder([Stim210Format("m")])
        import serial

        ser = serial.Serial(str(tmp_path / "ports" / "gyro"), 460800, timeout=0)
        loop = asyncio.get_running_loop()

        def on_readable() -> None:
            n = len(dec.feed(ser.read(65536)))
            if n:
                arrivals.append((time.monotonic(), n))

        loop.add_reader(ser.fileno(), on_readable)
        try:
            await emu.wait_until(lambda: sum(n for _t, n in arrivals) >= 600, timeout=5.0)
        finally:
            loop.remove_reader(ser.fileno())
            ser.close()
        missing = emu.emulator.fpga.gyro_missing
    assert dec.stats.crc_errors == 0 and dec.stats.garbage_bytes == 0
    # rate over the arrivals' own wall times (a busy host delays reads; it cannot create datagrams)
    t0, t1 = arrivals[0][0], arrivals[-1][0]
    n = sum(k for _t, k in arrivals[1:])
    rate = n / (t1 - t0)
    assert abs(rate / 200.0 - 1.0) < 0.05, f"{rate:.1f} datagrams/s"
    assert missing > 0 and emu.summary["links"]["uart1"]["frames"] > 0  # the FPGA still sends IMU frames


@pytest.mark.pty
@pytest.mark.realtime
@pytest.mark.psns_emulator(mode="realtime")
async def test_bytes_a_peer_writes_into_a_tee_port_reach_the_sensors_own_link(tmp_path):
    import serial

    from emulator.testing import start_emulator

    ov = _ov(6.0, **{"links.gnss.url": "pty://gnss", "links.gnss.direction": "tee"})
    poll = bytes.fromhex("b5620a0400000e34")  # UBX MON-VER poll (class 0x0A id 0x04, empty payload, checksum)
    async with start_emulator(QS, run_dir=tmp_path, overrides=ov) as emu:
        seen: list[bytes] = []

        class Tap:
            def on_link_bytes(self, link, direction, t, data):
                if direction == "in":
                    seen.append(data)

        emu.emulator.device_ends["gnss"].listeners.append(Tap())
        ser = serial.Serial(str(tmp_path / "ports" / "gnss"), 9600, timeout=0)
        try:
            await emu.wait_until(lambda: emu.emulator.bindings["gnss"].port.attached, timeout=2.0)
            ser.write(poll)
            await emu.wait_until(lambda: b"".join(seen) == poll, timeout=2.0)
        finally:
            ser.close()
        peer = emu.emulator.bindings["gnss"].peer_bytes
    assert peer == len(poll)
    assert emu.summary["bound_ports"]["gnss"]["peer_bytes"] == len(poll)
    # the peer's bytes are on the capture of the port, towards the device (direction out of the FPGA end)
    from emulator.recording.capture import read_capture

    _h, recs = read_capture(tmp_path / "capture.psnscap")
    assert b"".join(r.data for r in recs if r.link == "gnss" and r.direction == "out") == poll


@pytest.mark.pty
@pytest.mark.realtime
@pytest.mark.skipif(shutil.which("socat") is None,
                    reason="socat is not installed (apt-get install socat; .ci/run installs it)")
@pytest.mark.psns_emulator(mode="realtime")
async def test_tee_on_a_serial_device_reaches_the_other_end_of_the_line(tmp_path):
    """``serial://`` out: a socat pty pair stands for a USB-serial adapter and its cable; the far end reads the
    receiver's NMEA (the bytes of the FPGA end's capture) and its writes reach the receiver's link."""
    import serial

    from emulator.testing import start_emulator
    from tests.emulator.links.test_conformance import _socat_pair

    proc, near, far = _socat_pair(tmp_path)
    try:
        ov = _ov(6.0, **{"links.gnss.url": f"serial://{near}", "links.gnss.direction": "tee"})
        async with start_emulator(QS, run_dir=tmp_path / "run", overrides=ov) as emu:
            assert next(p for p in emu.emulator.ports if p["name"] == "gnss")["direction"] == "tee"

            async def until():
                await emu.wait_until(lambda: emu.fw.counters.get("gnss_fixes", 0) >= 3, timeout=5.5)
                await emu.run_for(0.4)

            got = await _read_pty(far, until, 9600)
            with serial.Serial(str(far), 9600, timeout=0) as ser:
                ser.write(b"\xb5\x62\x0a\x04\x00\x00\x0e\x34")
                await emu.wait_until(lambda: emu.emulator.bindings["gnss"].peer_bytes == 8, timeout=1.0)
    finally:
        proc.terminate()
        with contextlib.suppress(subprocess.TimeoutExpired):
            proc.wait(5)
    sent = _capture_in(tmp_path / "run", "gnss")
    assert len(got) > 3 * 100 and bytes(got) == sent[:len(got)]


@pytest.mark.pty
@pytest.mark.realtime
@pytest.mark.psns_emulator(mode="realtime")
async def test_link_faults_act_once_and_the_port_gets_the_same_damaged_bytes_as_the_fpga(tmp_path):
    """Bit errors on links.gnss (1e-3 per bit from 1.5 s): the pty carries the corrupted stream the FPGA got, byte
    for byte, so its NMEA checksums fail just as the firmware's do."""
    from emulator.testing import start_emulator

    ov = _ov(7.0, **{"links.gnss.url": "pty://gnss", "links.gnss.direction": "tee",
                     "faults": [{"link_bit_errors": {"link": "gnss", "ber": 1e-3, "start_s": 1.5}}]})
    async with start_emulator(QS, run_dir=tmp_path, overrides=ov) as emu:
        async def until():
            await emu.wait_until(lambda: emu.emulator.bindings["gnss"].port.attached, timeout=2.0)
            await emu.run_for(5.5)

        got = await _read_pty(tmp_path / "ports" / "gnss", until, 9600)
        corrupted = emu.emulator.links["gnss"].stats.corrupted_bytes
    sent = _capture_in(tmp_path, "gnss")
    assert corrupted > 0 and bytes(got) == sent[:len(got)] and len(got) >= len(sent) - 200
    dec = StreamDecoder([NmeaFormat()])
    dec.feed(bytes(got))
    assert dec.stats.crc_errors + dec.stats.garbage_bytes + dec.stats.parse_errors > 0  # the damage is on the pty


def test_port_map_and_summary_show_each_ports_direction_and_unheard_bytes(tmp_path):
    """Fast mode (the quickstart says so), nobody on the pty: the port map and the summary say which way each port
    goes; what the bound port carried is counted as unheard (no_peer_out), not dropped."""
    import io

    from emulator.assembly.session import run_scenario
    from emulator.cli.main import print_port_map

    scn = load_test_scenario(QS, _ov(3.0, **{"links.gnss.url": "pty://gnss", "links.gnss.direction": "tee"}))
    s = run_scenario(scn, tmp_path)
    dirs = {p["name"]: p["direction"] for p in s["ports"]}
    assert dirs == {"gyro": "model", "gnss": "tee", "host": "in/out", "uart0": "internal", "uart1": "internal",
                    "uart2": "internal", "uart3": "internal"}
    b = s["bound_ports"]["gnss"]
    assert b["bytes_out"] == s["link_stats"]["gnss"]["bytes_in"] > 0  # every byte the FPGA got went to the port
    assert b["no_peer_out"] == b["bytes_out"] and b["dropped_out"] == 0
    assert s["firmware"]["counters"]["gnss_fixes"] == s["devices"]["gnss_epochs"] == 3  # epochs at t = 0, 1, 2 s
    out = io.StringIO()
    print_port_map(s["ports"], out)
    line = next(x for x in out.getvalue().splitlines() if x.strip().startswith("gnss"))
    assert " tee " in line and str(tmp_path / "ports" / "gnss") in line


def test_a_psns_compass_stream_tees_like_the_others(tmp_path):
    """The polarization compass on links.psns (tee, nobody attached, fast mode): every frame the FPGA got also went
    to the port, and the firmware still solves them."""
    from emulator.assembly.session import run_scenario

    scn = load_test_scenario(QS, _ov(3.0, **{"links.psns": {"url": "pty://psns", "direction": "tee"},
                                             "sensors.compass": {"enabled": True, "rate_hz": 5.0}}))
    s = run_scenario(scn, tmp_path)
    b = s["bound_ports"]["psns"]
    assert s["devices"]["compass_frames"] >= 10
    assert b["bytes_out"] == s["link_stats"]["psns"]["bytes_in"] > 0 and b["dropped_out"] == 0
    assert s["links"]["psns"]["frames"] == s["devices"]["compass_frames"]
