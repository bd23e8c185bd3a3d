"""The box navigates on a u-blox without NAV-PVT (issue 37 item 5): the same IMU + GNSS run with the emulated
u-blox sending NAV-PVT, and sending the u-blox 5/6/7 set (NAV-SOL, NAV-POSLLH, NAV-VELNED, NAV-TIMEUTC, NAV-TIMEGPS,
NAV-STATUS) instead; the second must stay within the first's error bounds."""

from __future__ import annotations

from pathlib import Path

import pytest

from emulator.assembly.session import run_scenario
from emulator.testing import load_test_scenario
from tests.conftest import SCENARIOS

LEGACY = ["NAV-SOL", "NAV-POSLLH", "NAV-VELNED", "NAV-TIMEUTC", "NAV-TIMEGPS", "NAV-STATUS"]


def _run(tmp: Path, ubx: list[str]) -> dict:
    scn = load_test_scenario(SCENARIOS / "quickstart.yaml", {
        "duration_s": 40, "motion": [{"static": {"duration_s": 40}}], "expectations": [], "links.psns": None,
        "sensors.camera": None, "firmware.alignment.heading_source": "config", "sensors.gnss.sentences": [],
        "sensors.gnss.ubx": ubx, "links.gnss.baud": 115200})
    return run_scenario(scn, tmp / "-".join(ubx))


@pytest.mark.slow
def test_the_box_navigates_on_the_legacy_ubx_set_within_nav_pvt_bounds(tmp_path: Path) -> None:
    pvt = _run(tmp_path, ["NAV-PVT"])
    leg = _run(tmp_path, LEGACY)
    c_pvt, c_leg = pvt["firmware"]["counters"], leg["firmware"]["counters"]
    assert c_leg["gnss_pvt"] == 0 and c_leg["gnss_ubx_other"] == 0
    assert c_leg["gnss_legacy_ubx"] >= len(LEGACY) * 38
    assert c_leg["gnss_updates"] >= c_pvt["gnss_updates"] - 1 >= 35
    e_pvt, e_leg = pvt["nav_error"], leg["nav_error"]
    # the same receiver, the same errors: the position and velocity errors within NAV-PVT's (+ the rounding of
    # NAV-VELNED's cm/s and NAV-POSLLH's mm)
    assert e_leg["position_m"]["rms"] <= 1.05 * e_pvt["position_m"]["rms"] + 0.1
    assert e_leg["velocity_mps"]["rms"] <= 1.05 * e_pvt["velocity_mps"]["rms"] + 0.01
