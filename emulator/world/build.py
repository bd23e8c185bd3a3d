"""Build the truth model of a scenario."""

from __future__ import annotations

from ..scenario.schema import Scenario
from .trajectory import StaticTrajectory, Trajectory

__all__ = ["build_trajectory"]


def build_trajectory(scn: Scenario) -> Trajectory:
    """The truth trajectory of a scenario (static in this build)."""
    o, a = scn.origin, scn.attitude
    return StaticTrajectory(o.lat_deg, o.lon_deg, o.height_m, a.heading_deg, a.pitch_deg, a.roll_deg,
                            duration=scn.duration_s)
