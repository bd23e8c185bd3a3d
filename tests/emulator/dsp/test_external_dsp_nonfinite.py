"""An outside DSP that sends NAV_SOLUTION frames with +-inf / NaN attitude (valid CRC) leaves the run alive (issue 41
item 2: the recorder's attitude comparison ended the run with 'math domain error'): the frames are decoded,
counted as navigation frames with non-finite values (``nav_nonfinite`` events), left out of the error statistics,
and the summary is written."""

from __future__ import annotations

import json
import math
import os

import pytest

from emulator.assembly.session import Emulator, run_emulator
from emulator.scenario import load_scenario
from protocols.host import NavMode, NavSolution, encode_host

from .test_external_dsp import _scenario


def _nav(k: int, **change: float) -> bytes:
    n = dict(seq=k, time_s=0.5 + 0.01 * k, lat_deg=39.979, lon_deg=116.339, height_m=50.0,
             vel_enu_mps=(0.0, 0.0, 0.0), roll_deg=-1.5, pitch_deg=2.0, heading_deg=30.0, sigma=(0.1,) * 9,
             mode=int(NavMode.NAVIGATING), gnss_status=1, psns_status=0, cpu_load_pct=0.2, deadline_misses=0)
    n.update(change)
    return encode_host(NavSolution(**n))  # type: ignore[arg-type]


@pytest.mark.realtime
@pytest.mark.pty
def test_an_external_dsp_sending_infinite_attitude_is_counted_not_a_crash(tmp_path):
    scn = load_scenario(_scenario(tmp_path / "i.yaml", {"uart0": "pty://dsp_uart0", "uart1": "pty://dsp_uart1"},
                                  duration_s=3.0))
    run_dir = tmp_path / "run"
    frames = (_nav(0) + _nav(1, roll_deg=math.inf) + _nav(2, pitch_deg=-math.inf) + _nav(3, heading_deg=math.inf)
              + _nav(4, heading_deg=math.nan) + _nav(5))
    fds: list[int] = []

    def on_started(emu: Emulator) -> None:
        fd = os.open(run_dir / "ports" / "dsp_uart0", os.O_RDWR | os.O_NOCTTY)
        fds.append(fd)
        emu.loop.call_later(0.5, os.write, fd, frames)  # type: ignore[union-attr]

    try:
        summary = run_emulator(Emulator(scn, run_dir), 1.0, on_started)
    finally:
        for fd in fds:
            os.close(fd)
    assert summary["external_dsp"]["nav_frames"] == 6 and summary["nav_frames"] == 6
    assert summary["events"].get("nav_nonfinite", 0) >= 1
    events = [json.loads(x) for x in (run_dir / "events.jsonl").read_text().splitlines()]
    assert sum(e["frames"] for e in events if e["event"] == "nav_nonfinite") == 4
    saved = json.loads((run_dir / "summary.json").read_text())
    assert saved["nav_error"]["attitude_deg"]["rms"] is not None  # the two finite frames were compared
