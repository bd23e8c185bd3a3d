"""The FPGA MONITOR port: every channel mirrored, tagged and time-stamped (docs/icd.md)."""

from __future__ import annotations

import pytest

from emulator.assembly.session import run_scenario
from emulator.recording.capture import read_capture
from emulator.testing import load_test_scenario
from protocols import monitor
from protocols.stream import StreamDecoder
from tests.conftest import SCENARIOS


@pytest.fixture(scope="module")
def mon_run(tmp_path_factory):
    d = tmp_path_factory.mktemp("mon")
    # the quickstart without its camera: IMU + GNSS fit the 921600-baud monitor line, a camera's frames would not
    scn = load_test_scenario(SCENARIOS / "quickstart.yaml", {
        "duration_s": 4.0, "motion": [{"static": {"duration_s": 4.0}}], "expectations": [],
        "links.psns": None, "sensors.camera": None, "firmware.alignment.heading_source": "config",
        "links.monitor": {"url": "mem://monitor", "baud": 921600}})
    s = run_scenario(scn, d / "run")
    return s, d / "run"


def test_every_channel_is_mirrored_byte_for_byte(mon_run):
    s, run_dir = mon_run
    _h, recs = read_capture(run_dir / "capture.psnscap")
    stream = b"".join(r.data for r in recs if r.link == "monitor" and r.direction == "out")
    dec = StreamDecoder([monitor.MonitorFormat()])
    records = dec.feed(stream)
    assert dec.stats.crc_errors == 0 and s["link_stats"]["monitor"]["dropped_out"] == 0
    # all records but the last few still on the monitor line when the run ended
    assert s["fpga"]["monitor_records"] - 3 <= len(records) <= s["fpga"]["monitor_records"]
    assert len(records) > 1000
    ch = monitor.MONITOR_CHANNELS
    t_cut = 3.9  # compare everything that passed before the monitor line's tail
    by = {}
    for r in records:
        if r.t_us < t_cut * 1e6:
            by.setdefault((r.channel, r.direction), bytearray()).extend(r.data)

    def cap(link, direction):
        return b"".join(r.data for r in recs if r.link == link and r.direction == direction and r.t_s < t_cut)

    # towards the DSP (0): what the FPGA received on its ports and sent on the FPGA-DSP lines
    assert bytes(by[(ch["gyro"], 0)]) == cap("gyro", "in")
    assert bytes(by[(ch["gnss"], 0)]) == cap("gnss", "in")
    assert bytes(by[(ch["uart1"], 0)]) == cap("uart1", "in")
    assert bytes(by[(ch["uart3"], 0)]) == cap("uart3", "in")
    # away from the DSP (1): the nav frames on UART0 and on the HOST connector
    assert bytes(by[(ch["uart0"], 1)]) == cap("uart0", "out")
    assert bytes(by[(ch["host"], 1)]) == cap("host", "out")
    # time stamps: the FPGA counter (us) when each chunk passed, non-decreasing per channel
    for key in by:
        ts = [r.t_us for r in records if (r.channel, r.direction) == key]
        assert ts == sorted(ts)


def test_monitor_command_unpacks_channels(mon_run):
    import io

    from emulator.cli.monitor import run_monitor

    _s, run_dir = mon_run
    out = io.StringIO()
    st = run_monitor(str(run_dir / "capture.psnscap"), links=["monitor"], count=400, out=out)
    text = out.getvalue()
    assert st["frames"] == 400
    for kind in ("StimDatagram", "ImuFrame", "NavSolution"):
        assert kind in text
    assert "monitor:uart1/in" in st["decoders"] and st["decoders"]["monitor/out"]["crc_errors"] == 0


def test_a_slow_monitor_line_overflows_and_counts(tmp_path):
    scn = load_test_scenario(SCENARIOS / "quickstart.yaml", {
        "duration_s": 3.0, "motion": [{"static": {"duration_s": 3.0}}], "expectations": [],
        "links.monitor": {"url": "mem://monitor", "baud": 115200}})  # 11.5 kB/s for ~41 kB/s of records
    s = run_scenario(scn, tmp_path / "run")
    assert s["link_stats"]["monitor"]["dropped_out"] > 0
