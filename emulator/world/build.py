"""Build the truth model of a scenario: motion segments -> phases -> :class:`SegmentTrajectory`."""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from protocols.constants import DEG

from ..errors import ScenarioError
from ..scenario.schema import Scenario
from ..scenario.world_schema import MotionSegment
from .frames import yaw_from_heading
from .trajectory import Phase, SegmentTrajectory, StaticTrajectory, Trajectory

__all__ = ["build_trajectory", "phases_from_segments", "trajectory_from_segments"]

#: Largest pitch a manoeuvre may reach (the Euler angles are singular at +-90 deg), rad.
PITCH_LIMIT = 89.0 * DEG


def _err(where: str, msg: str, file: str = "<scenario>") -> ScenarioError:
    return ScenarioError(f"{where}: {msg}", file=file)


def phases_from_segments(segments: Sequence[MotionSegment], pitch0: float, roll0: float, yaw0: float,
                         duration: float | None = None, file: str = "<scenario>") -> list[Phase]:
    """Compile motion segments into phases (angles rad, PSINS yaw; see ``world_schema``).

    The vehicle starts at rest. A last hold phase is appended when ``duration`` exceeds the
    segments (or when there are none).
    """
    th, ga, psi, u = pitch0, roll0, yaw0, 0.0
    t = 0.0
    out: list[Phase] = []

    def add(T: float, dth: float = 0.0, dga: float = 0.0, dpsi: float = 0.0, du: float = 0.0, label: str = "") -> None:
        nonlocal th, ga, psi, u, t
        if T <= 0.0:
            return
        ph = Phase(t, t + T, th, ga, psi, dth, dga, dpsi, u, du, label)
        out.append(ph)
        th, ga, psi, u = ph.end_values()
        if du != 0.0 and abs(u) < 1e-9:
            u = 0.0
        t = ph.t1

    for i, seg in enumerate(segments):
        kind = seg.kind
        p: Any = seg.params
        where = f"motion[{i}].{kind}"
        if kind == "static":
            if u != 0.0:
                raise _err(where, f"the vehicle moves at {u:g} m/s; stop it first (accelerate: {{to_speed_mps: 0}})",
                           file)
            add(p.duration_s, label=where)
        elif kind == "accelerate":
            du = p.accel_mps2 if p.accel_mps2 is not None else (p.to_speed_mps - u) / p.duration_s
            if u + du * p.duration_s < -1e-9:
                raise _err(where, f"the speed would become negative ({u + du * p.duration_s:g} m/s)", file)
            add(p.duration_s, du=du, label=where)
        elif kind == "cruise":
            add(p.duration_s, label=where)
        elif kind == "turn":
            add(p.total_s, dpsi=-p.heading_rate_dps * DEG, label=where)  # heading clockwise = -yaw
        elif kind in ("climb", "descend"):
            sign = 1.0 if kind == "climb" else -1.0
            if p.pitch_deg is not None:
                target = th + sign * p.pitch_deg * DEG
            else:
                if u <= 0.0 or p.vertical_speed_mps >= u:
                    raise _err(where, f"vertical_speed_mps {p.vertical_speed_mps:g} needs a forward speed above it "
                               f"(now {u:g} m/s)", file)
                target = sign * math.asin(p.vertical_speed_mps / u)
            if abs(target) > PITCH_LIMIT:
                raise _err(where, f"pitch would reach {target / DEG:.1f} deg (limit 89)", file)
            start = th
            Ttr = p.transition_s
            rate = (target - start) / Ttr
            add(Ttr, dth=rate, label=where)
            add(p.duration_s - 2.0 * Ttr, label=where)
            add(Ttr, dth=-rate, label=where)
            th = start  # remove rounding drift
        elif kind in ("pitch", "roll"):
            cur = th if kind == "pitch" else ga
            delta = p.by_deg * DEG if p.by_deg is not None else p.to_deg * DEG - cur
            T_total = p.total_s
            T_man = abs(delta) / (p.rate_dps * DEG) if p.rate_dps is not None else T_total
            if T_man > T_total + 1e-9:
                raise _err(where, f"the rotation by {delta / DEG:g} deg at {p.rate_dps:g} deg/s takes {T_man:g} s, "
                           f"more than duration_s {T_total:g}", file)
            rate = delta / T_man if T_man > 0 else 0.0
            if kind == "pitch":
                if abs(cur + delta) > PITCH_LIMIT:
                    raise _err(where, f"pitch would reach {(cur + delta) / DEG:.1f} deg (limit 89)", file)
                add(T_man, dth=rate, label=where)
            else:
                add(T_man, dga=rate, label=where)
            add(T_total - T_man, label=where)
        else:  # pragma: no cover - the schema lists every kind
            raise _err(where, f"unknown motion kind {kind!r}", file)
    if duration is not None and t < duration - 1e-12:
        if u != 0.0:
            add(duration - t, label="hold (after the last segment)")
        else:
            add(duration - t, label="static (after the last segment)")
    if not out:
        add(duration if duration is not None else 1.0, label="static")
    return out


def trajectory_from_segments(segments: Sequence[MotionSegment], lat_deg: float, lon_deg: float, h_m: float,
                             heading_deg: float = 0.0, pitch_deg: float = 0.0, roll_deg: float = 0.0,
                             duration: float | None = None, file: str = "<scenario>") -> SegmentTrajectory:
    """A :class:`SegmentTrajectory` from segments and the initial position/attitude (deg, m)."""
    phases = phases_from_segments(segments, pitch_deg * DEG, roll_deg * DEG, yaw_from_heading(heading_deg * DEG),
                                  duration, file)
    return SegmentTrajectory(phases, np.array([lat_deg * DEG, lon_deg * DEG, h_m]), duration)


def build_trajectory(scn: Scenario) -> Trajectory:
    """The truth trajectory of a scenario.

    A scenario whose motion is only ``static`` segments (or none) gets the closed-form
    :class:`StaticTrajectory`; anything else a :class:`SegmentTrajectory`.
    """
    o, a = scn.origin, scn.attitude
    if all(seg.kind == "static" for seg in scn.motion):
        return StaticTrajectory(o.lat_deg, o.lon_deg, o.height_m, a.heading_deg, a.pitch_deg, a.roll_deg,
                                duration=scn.duration_s)
    return trajectory_from_segments(scn.motion, o.lat_deg, o.lon_deg, o.height_m, a.heading_deg, a.pitch_deg,
                                    a.roll_deg, duration=scn.duration_s, file=scn.source_file)
