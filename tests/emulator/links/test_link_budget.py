"""Links below their bandwidth need: overflow and lost frames match the ICD budget.

NAV_SOLUTION on the host port: 109-byte frames (5 header + 102 payload + 2 CRC, docs/icd.md) at
the firmware's output rate (100 Hz) plus one 71-byte STATUS frame per second need 10 971 B/s; an
8N1 line carries baud / 10 B/s. At 57 600 baud that is 5 760 B/s: 47.5 % of the bytes are lost. The firmware's
UART driver drops whole frames when its TX ring is full, so what arrives is intact; the FPGA's
byte FIFO on the HOST port drops bytes, so frames arrive torn.
"""

from __future__ import annotations

import pytest

from emulator.assembly.session import run_scenario
from emulator.links import LineConfig
from emulator.testing import load_test_scenario
from protocols.host import NAV_SOLUTION_LEN, STATUS_LEN, build_host_frame
from tests.conftest import SCENARIOS

FRAME = len(build_host_frame(0x01, bytes(NAV_SOLUTION_LEN)))
STATUS_FRAME = len(build_host_frame(0x02, bytes(STATUS_LEN)))
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
    # bytes the firmware wrote: one NAV_SOLUTION per output period, one STATUS per whole second
    n_nav = s["dsp"]["ticks"] // round(scn.sensors.imu.rate_hz / rate)
    t_last_tick = (s["dsp"]["ticks"] - 1) / scn.sensors.imu.rate_hz  # ticks at t = 0, 5 ms, ...
    n_status = int(t_last_tick)  # STATUS at t = 1, 2, ... s
    assert n_nav >= rate * T - 1
    produced = n_nav * FRAME + n_status * STATUS_FRAME
    need = rate * FRAME + STATUS_FRAME  # B/s
    t0 = 1.0 / 200 + 0.0036  # the first output: end of the first tick (+ its cycles)
    capacity = (T - t0) * line.bytes_per_second  # bytes the line can carry in the run
    # what left the DSP is what the line could carry (to within the frame on the wire at the end)
    assert st["bytes_out"] == pytest.approx(capacity, abs=FRAME)
    # whole frames are dropped: every dropped chunk is one frame of one of the two sizes
    nav_lost = (st["dropped_out"] - st["dropped_chunks_out"] * STATUS_FRAME) / (FRAME - STATUS_FRAME)
    assert nav_lost == int(nav_lost) and 0 <= st["dropped_chunks_out"] - nav_lost <= n_status
    # the rest sits in the saturated 4 KiB TX ring
    in_ring = produced - st["bytes_out"] - st["dropped_out"]
    assert 4096 - FRAME < in_ring <= 4096
    expected_loss = 1 - line.bytes_per_second / need  # 47.5 % of the bytes
    assert (st["dropped_out"] + in_ring) / produced == pytest.approx(expected_loss, abs=2 * FRAME / produced)
    # the host receives intact frames only
    assert s["links"]["host"]["crc_errors"] == 0 and s["links"]["host"]["garbage_bytes"] == 0
    assert s["links"]["host"]["frames"] == pytest.approx(st["chunks_out"], abs=1)


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
