"""Runtime sections of a scenario: routing, per-side line settings, mode resolution."""

from __future__ import annotations

import pytest

from emulator.assembly.ports import resolve_mode
from emulator.assembly.session import run_scenario
from emulator.errors import ScenarioError
from emulator.testing import load_test_scenario
from tests.conftest import SCENARIOS

QS = SCENARIOS / "quickstart.yaml"


def _scn(**ov):
    base = {"duration_s": 5.0, "motion": [{"static": {"duration_s": 5.0}}], "expectations": []}
    base.update(ov)
    return load_test_scenario(QS, base)


def test_two_ports_on_one_uart_is_an_error_with_its_location():
    with pytest.raises(ScenarioError) as ei:
        load_test_scenario(QS, {"fpga": {"routing": {"host": "uart0", "gnss": "uart0"}}})
    msg = str(ei.value)
    assert "fpga.routing" in msg and "both routed to uart0" in msg


def test_trigger_level_above_the_fifo_is_an_error():
    with pytest.raises(ScenarioError, match="trigger_level 14 exceeds fifo_bytes 8"):
        load_test_scenario(QS, {"dsp": {"uarts": {"uart1": {"fifo_bytes": 8, "trigger_level": 14}}}})


def test_mode_follows_the_endpoints_unless_told():
    assert resolve_mode(_scn()) == "fast"  # the quickstart sets mode: fast explicitly
    data = {"links.host.url": "pty://uart0"}
    assert resolve_mode(_scn(**data)) == "fast"  # still explicit in the file
    from emulator.scenario.loader import validate_scenario_data

    raw = _scn(**data).model_dump(mode="json", exclude={"mode"})
    implicit = validate_scenario_data(raw, {})
    assert resolve_mode(implicit) == "realtime"
    assert resolve_mode(implicit, "fast") == "fast"


def test_gnss_receiver_set_to_the_wrong_baud_gives_framing_errors_and_no_fixes(tmp_path):
    """The receiver talks 115 200 into a 9 600 FPGA port: the FPGA's UART samples garbage."""
    s = run_scenario(_scn(**{"links.gnss.device_baud": 115200}), tmp_path / "bad")
    assert s["link_stats"]["gnss"]["framing_errors"] > 0 or s["links"]["gnss"]["garbage_bytes"] > 0
    assert s["firmware"]["counters"]["gnss_fixes"] == 0
    assert s["links"]["gnss"]["frames"] == 0
    # 3 % off is within a UART's tolerance: everything gets through
    ok = run_scenario(_scn(**{"links.gnss.device_baud": 9888}), tmp_path / "ok")
    assert ok["link_stats"]["gnss"]["framing_errors"] == 0
    assert ok["firmware"]["counters"]["gnss_fixes"] == ok["devices"]["gnss_epochs"] > 0


def test_dsp_uart_clock_quantizes_the_dsp_side_baud_within_tolerance(tmp_path):
    s = run_scenario(_scn(**{"dsp.uart_clock_hz": 150e6}), tmp_path / "q")
    row = next(p for p in s["ports"] if p["name"] == "uart0")
    assert row["baud"] == "460800/468750"  # FPGA side / DSP divisor baud (+1.7 %)
    assert s["link_stats"]["uart1"]["framing_errors"] == 0
    assert s["firmware"]["decoders"]["uart1"]["crc_errors"] == 0
    assert s["links"]["host"]["frames"] >= 495


def test_dsp_uart_format_mismatch_breaks_the_imu_link(tmp_path):
    """The DSP's UART1 programmed 8E1 while the FPGA sends 8N1: parity/framing errors, no frames."""
    s = run_scenario(_scn(**{"dsp.uarts.uart1.mode": "8E1"}), tmp_path / "m")
    st = s["link_stats"]["uart1"]
    assert st["framing_errors"] + st["parity_errors"] > 1000
    assert s["firmware"]["counters"]["imu_frames"] < 10


def test_monitor_port_records_every_channel(tmp_path):
    scn = _scn(**{"links.monitor": {"url": "mem://monitor", "baud": 921600}})
    s = run_scenario(scn, tmp_path / "mon")
    assert s["fpga"]["monitor_records"] > 1000


def test_uart3_is_an_emifa_core_unless_given_a_serial_baud(tmp_path):
    from emulator.recording.capture import read_capture

    s = run_scenario(_scn(), tmp_path / "emifa")
    assert next(p for p in s["ports"] if p["name"] == "uart3")["baud"] == "EMIFA"
    s2 = run_scenario(_scn(**{"fpga.uarts.uart3.baud": 230400}), tmp_path / "serial")
    assert next(p for p in s2["ports"] if p["name"] == "uart3")["baud"] == "230400"
    # over a serial hop each GNSS chunk reaches the DSP one 230400-baud byte after the port got it
    _h, recs = read_capture(tmp_path / "serial" / "capture.psnscap")
    gnss = [r.t_s for r in recs if r.link == "gnss" and r.direction == "in"]
    u3 = [r.t_s for r in recs if r.link == "uart3" and r.direction == "in"]
    assert len(gnss) == len(u3) > 3
    assert all(abs((b - a) - 10 / 230400) < 1e-9 for a, b in zip(gnss, u3))
    assert s2["firmware"]["counters"]["gnss_fixes"] == s["firmware"]["counters"]["gnss_fixes"] > 0


def test_gnss_port_with_ubx_counts_ubx_frames_not_garbage(tmp_path):
    scn = _scn(**{"sensors.gnss.ubx": ["NAV-PVT"]})
    s = run_scenario(scn, tmp_path / "ubx")
    per_epoch = len(scn.sensors.gnss.sentences) + 1  # quickstart's sentences (GGA, RMC, GST) + NAV-PVT
    assert per_epoch == 4
    for name in ("gnss", "uart3"):
        assert s["links"][name]["garbage_bytes"] == 0
        assert s["links"][name]["frames"] == per_epoch * s["devices"]["gnss_epochs"] > 0
