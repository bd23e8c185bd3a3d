"""studies/scripts/precision_builds.py: the stretched motion covers the duration, and the frame-by-frame differences
against closed forms (a known rotation, a known offset in latitude)."""

from __future__ import annotations

import math

import pytest

from studies.scripts import precision_builds as pb


def _seconds(seg: list[dict]) -> float:
    total = 0.0
    for s in seg:
        (kind, p), = s.items()
        total += p["angle_deg"] / p["rate_dps"] if kind == "turn" else p["duration_s"]
    return total


@pytest.mark.parametrize("duration", [120.0, 600.0, 3600.0, 3615.5])
def test_laps_cover_the_duration(duration):
    assert _seconds(pb.laps(duration)) == pytest.approx(duration)


def _row(t, lat=40.0, lon=116.0, heading=30.0, pitch=0.0, roll=0.0, ve=0.0):
    return {"time_s": f"{t}", "lat_deg": f"{lat}", "lon_deg": f"{lon}", "heading_deg": f"{heading}",
            "pitch_deg": f"{pitch}", "roll_deg": f"{roll}", "vel_e_mps": f"{ve}", "vel_n_mps": "0", "vel_u_mps": "0"}


def test_differences_by_closed_form():
    ref = [_row(k) for k in range(5)]
    assert pb.differences(ref, ref) == {"att_deg": 0.0, "pos_m": 0.0, "vel_mps": 0.0, "frames": 5}
    dlat = 1e-6  # deg: a * dlat in radians metres north
    other = [_row(k, lat=40.0 + dlat, heading=30.01, ve=0.003) for k in range(5)]
    d = pb.differences(other, ref)
    assert d["att_deg"] == pytest.approx(0.01, rel=1e-6)  # a pure heading difference: the rotation angle
    assert d["pos_m"] == pytest.approx(math.radians(dlat) * 6_378_137.0, rel=1e-6)
    assert d["vel_mps"] == pytest.approx(0.003)
    # frames are matched by time: a row without a partner does not count
    assert pb.differences([*other, _row(99)], ref)["frames"] == 5
