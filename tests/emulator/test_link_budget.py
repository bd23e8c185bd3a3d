"""Links below their bandwidth need: overflow and lost frames match the ICD budget.

NAV_SOLUTION on the host port: 109-byte frames (5 header + 102 payload + 2 CRC, docs/icd.md) at
the firmware's output rate (100 Hz) need 10 900 B/s; an 8N1 line carries baud / 10 B/s. At 57 600
baud that is 5 760 B/s: 52.8 frames/s get through, 47.2 % of the frames are lost. The firmware's
UART driver drops whole frames when its TX ring is full, so what arrives is intact; the FPGA's
byte FIFO on the HOST port drops bytes, so frames arrive torn.
"""

from __future__ import annotations

import pytest

from emulator.links import LineConfig
from emulator.runner import run_scenario
from emulator.testing import load_test_scenario
from protocols.host import NAV_SOLUTION_LEN, build_host_frame
from tests.conftest import SCENARIOS

FRAME = len(build_host_frame(0x01, bytes(NAV_SOLUTION_LEN)))
T = 10.0


def _run(tmp_path, overrides):
    ov = {"duration_s": T, "motion": [{"static": {"duration_s": T}}], "expectations": []}
    ov.update(overrides)
    scn = load_test_scenario(SCENARIOS / "quickstart.yaml", ov)
    return scn, run_scenario(scn, tmp_path / "run")


def test_frame_length_and_need():
    assert FRAME == 109
    assert FRAME * 100 == 10_900  # B/s at 100 Hz


def test_dsp_uart0_below_its_need_drops_whole_frames_at_the_budgeted_rate(tmp_path):
    scn, s = _run(tmp_path, {"fpga.uarts.uart0.baud": 57600})
    line = LineConfig(baud=57600)
    rate = scn.firmware.output_rate_hz
    st = s["link_stats"]["uart0"]
    # frames the firmware wrote: one every (IMU rate / output rate) ticks
    produced = s["dsp"]["ticks"] // int(round(scn.sensors.imu.rate_hz / rate))
    left_dsp = st["bytes_out"] // FRAME
    lost = st["dropped_chunks_out"]
    t0 = 1.0 / 200 + 0.0036  # the first output: end of the first tick (+ its cycles)
    capacity = (T - t0) * line.bytes_per_second / FRAME  # frames the line can carry in the run
    # the firmware wrote one frame per output period; the ring holds at most 4096 // 109 of them
    assert produced >= rate * T - 1
    in_ring = produced - left_dsp - lost
    assert in_ring == 4096 // FRAME  # saturated: the 4 KiB TX ring is full at the end
    # what left the DSP is what the line could carry; the rest is lost, whole frames
    assert left_dsp == pytest.approx(capacity, abs=1.5)
    assert st["dropped_out"] == lost * FRAME
    expected_loss = 1 - line.bytes_per_second / (FRAME * rate)  # 47.16 %
    assert (lost + in_ring) / produced == pytest.approx(expected_loss, abs=2 / produced)
    # the host receives intact frames only
    assert s["links"]["host"]["crc_errors"] == 0 and s["links"]["host"]["garbage_bytes"] == 0
    assert s["links"]["host"]["frames"] == pytest.approx(left_dsp, abs=1)


def test_enough_baud_loses_nothing(tmp_path):
    _scn, s = _run(tmp_path, {"fpga.uarts.uart0.baud": 115200, "links.host.baud": 115200})
    for name in ("uart0", "host"):
        assert s["link_stats"][name]["dropped_out"] == 0
        assert s["link_stats"][name]["dropped_chunks_out"] == 0
    assert s["links"]["host"]["frames"] >= 100 * T - 2
    assert s["links"]["host"]["crc_errors"] == 0


def test_fpga_host_fifo_below_the_need_tears_frames(tmp_path):
    """UART0 at 460 800 feeds the FPGA; the HOST port at 57 600 drains its 4 KiB FIFO too slowly."""
    _scn, s = _run(tmp_path, {"links.host.baud": 57600})
    line = LineConfig(baud=57600)
    host = s["link_stats"]["host"]
    offered = s["link_stats"]["uart0"]["bytes_out"]  # what the DSP sent to the FPGA
    t_first = 0.0086
    capacity = (T - t_first) * line.bytes_per_second
    assert host["bytes_out"] == pytest.approx(capacity, abs=FRAME + 2)
    queued = offered - host["bytes_out"] - host["dropped_out"]
    assert 0 <= queued <= 4096
    assert host["dropped_out"] == pytest.approx(offered - capacity, abs=4096 + FRAME)
    # byte drops tear frames: fewer intact frames than the bytes would hold, CRC/garbage counted
    links = s["links"]["host"]
    assert links["frames"] < host["bytes_out"] / FRAME
    assert links["garbage_bytes"] > 0
