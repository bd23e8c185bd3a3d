"""No silent fallbacks: what a scenario leaves the firmware to guess, said before the run and after it.

The firmware falls back quietly where a real box would: a coarse alignment without a solar vector takes the
configured heading (``firmware.alignment.heading_deg``, 0 when the file does not give one), a polarization sensor
with the sun below ``firmware.psns.min_sun_elevation_deg`` gives no solar vector. A 30 deg heading error that
nobody asked for looks like a filter defect, so:

* :func:`scenario_warnings` (``psns-hil validate`` and the start of ``psns-hil run``) names, with file:line, the
  fallbacks the scenario makes certain or likely: ``heading_source: psns`` without a camera or compass, the sun
  below the PSNS minimum elevation at some time of the run (a camera at night), an alignment that needs a heading
  nothing gives (no ``heading_deg`` in the file);
* :func:`run_fallbacks` names the fallbacks the run took, from its events and its solar-vector statistics (the
  alignment's ``heading_source`` was ``config`` where the sky was asked for, solar vectors refused for a low sun);
* both go into ``summary.json`` ``warnings`` (``{kind, source, message, path, line, column, t_s}``).

The sun is the world's (:class:`emulator.world.sun.SunModel`, SPA) at the scenario's origin: a land vehicle moves
a few km in a run, which moves the sun's elevation by hundredths of a degree.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass
from typing import Any

from ..scenario.cross_checks import link_names
from ..scenario.schema import Scenario
from ..world.sun import SunModel

__all__ = ["SUN_SAMPLES", "Fallback", "has_polarization_sensor", "run_fallbacks", "scenario_warnings",
           "sun_below_minimum"]

#: how many instants of the run the sun's elevation is sampled at (and at most every 10 s)
SUN_SAMPLES = 400


@dataclass(frozen=True)
class Fallback:
    """One fallback: its kind, where it was seen (``scenario``: before the run; ``run``: in its events), the
    message, the scenario field it concerns (dotted path, file line and column when known) and when (s)."""

    kind: str
    source: str
    message: str
    path: str = ""
    file: str = ""
    line: int | None = None
    column: int | None = None
    t_s: float | None = None

    def __str__(self) -> str:
        where = self.file + (f":{self.line}" if self.line is not None else "") + (
            f":{self.column}" if self.line is not None and self.column is not None else "")
        field = f" {self.path}:" if self.path else ""
        return f"{where}:{field} {self.message}" if where else f"{self.path + ': ' if self.path else ''}{self.message}"

    def as_dict(self) -> dict[str, Any]:
        return {"kind": self.kind, "source": self.source, "message": self.message, "path": self.path,
                "line": self.line, "column": self.column, "t_s": self.t_s}


def has_polarization_sensor(scn: Scenario) -> bool:
    """A camera or compass on the PSNS port that the firmware reads (the rule of
    :func:`emulator.scenario.cross_checks.cross_check`: without a ``sensors.camera`` section a PSNS link carries the
    default camera)."""
    if "psns" not in link_names(scn) or scn.firmware.psns.enabled is False:
        return False
    s = scn.sensors
    compass = s.compass is not None and s.compass.enabled
    camera = (s.camera is not None and s.camera.enabled) or (s.camera is None and not compass)
    return camera or compass


def sun_below_minimum(scn: Scenario) -> tuple[list[tuple[float, float]], float, float]:
    """The spans (s) of the run when the sun is below ``firmware.psns.min_sun_elevation_deg`` at the origin, the
    lowest elevation (deg) and its time (s)."""
    sun = SunModel(scn.epoch)
    lat, lon, h = math.radians(scn.origin.lat_deg), math.radians(scn.origin.lon_deg), scn.origin.height_m
    n = max(2, min(SUN_SAMPLES, int(scn.duration_s / 10.0) + 2))
    limit = scn.firmware.psns.min_sun_elevation_deg
    spans: list[tuple[float, float]] = []
    start: float | None = None
    lowest, t_low = math.inf, 0.0
    prev = 0.0
    for k in range(n):
        t = scn.duration_s * k / (n - 1)
        el = math.degrees(sun.az_el(t, lat, lon, h)[1])
        if el < lowest:
            lowest, t_low = el, t
        if el < limit and start is None:
            start = t
        elif el >= limit and start is not None:
            spans.append((start, prev))
            start = None
        prev = t
    if start is not None:
        spans.append((start, scn.duration_s))
    return spans, lowest, t_low


def _at(scn: Scenario, kind: str, message: str, *path: Any, t_s: float | None = None) -> Fallback:
    """A scenario-level fallback located at the deepest key of ``path`` the file has."""
    marks = getattr(scn, "_marks", {}) or {}
    probe = tuple(path)
    while probe and probe not in marks:
        probe = probe[:-1]
    line, col = marks.get(probe, (None, None))
    return Fallback(kind, "scenario", message, ".".join(str(p) for p in path), scn.source_file, line, col, t_s)


def scenario_warnings(scn: Scenario) -> list[Fallback]:
    """The fallbacks the scenario makes certain or likely (see module docstring), in file order."""
    out: list[Fallback] = []
    al = scn.firmware.alignment
    pol = has_polarization_sensor(scn)
    heading_given = "heading_deg" in al.model_fields_set
    if al.heading_source == "psns" and not pol:
        out.append(_at(scn, "heading_source_without_sensor",
                       "heading_source psns, but the scenario has no polarization camera or compass the firmware "
                       "reads (sensors.camera / sensors.compass with links.psns): the alignment takes the configured "
                       f"heading_deg {al.heading_deg:g} deg instead", "firmware", "alignment", "heading_source"))
    if (al.heading_source == "config" or not pol) and not heading_given:
        why = "heading_source config" if al.heading_source == "config" else "no polarization sensor gives one"
        out.append(_at(scn, "alignment_heading_not_given",
                       f"the alignment needs a heading that nothing gives ({why}) and the file sets no "
                       f"firmware.alignment.heading_deg: the firmware aligns on heading {al.heading_deg:g} deg "
                       f"(the truth starts at {scn.attitude.heading_deg:g} deg)", "firmware", "alignment"))
    if pol:
        spans, lowest, t_low = sun_below_minimum(scn)
        if spans:
            limit = scn.firmware.psns.min_sun_elevation_deg
            when = ", ".join(f"{a:g}-{b:g} s" for a, b in spans[:4]) + (" ..." if len(spans) > 4 else "")
            whole = len(spans) == 1 and spans[0][0] == 0.0 and spans[0][1] >= scn.duration_s
            alignment = spans[0][0] <= al.time_s and al.heading_source in ("auto", "psns")
            out.append(_at(scn, "sun_below_psns_minimum",
                           f"the sun is below firmware.psns.min_sun_elevation_deg ({limit:g} deg) "
                           + ("for the whole run" if whole else f"at t = {when}")
                           + f" (lowest {lowest:.1f} deg at t = {t_low:g} s): the polarization sensor gives no "
                           "solar vector then" + (", and the alignment falls back to heading_deg "
                                                  f"{al.heading_deg:g} deg" if alignment else ""),
                           "epoch", t_s=spans[0][0]))
    return sorted(out, key=lambda f: (f.line or 0, f.column or 0))


def run_fallbacks(scn: Scenario, events: Iterable[dict[str, Any]], psns: dict[str, Any] | None) -> list[Fallback]:
    """The fallbacks the run took: alignments on the configured heading where the sky was asked for or the
    heading was not given, and solar vectors not used for a low sun (``psns.uses.sun_low``)."""
    out: list[Fallback] = []
    al = scn.firmware.alignment
    pol = has_polarization_sensor(scn)
    heading_given = "heading_deg" in al.model_fields_set
    for ev in events:
        if ev.get("event") != "alignment_done" or ev.get("heading_source") != "config":
            continue
        t = ev.get("t_s")
        at = f"t = {t:.2f} s" if isinstance(t, (int, float)) else "the alignment"
        heading = ev.get("heading_deg")
        hd = f"{heading:.2f} deg" if isinstance(heading, (int, float)) else f"{al.heading_deg:g} deg"
        if al.heading_source in ("auto", "psns") and pol:
            wait = f" nor in the {al.psns_timeout_s:g} s psns_timeout_s after it" if al.heading_source == "psns" else ""
            out.append(Fallback("alignment_heading_fallback", "run",
                                f"the alignment at {at} took the configured heading ({hd}): no usable solar vector "
                                f"during the {al.time_s:g} s levelling{wait} (heading_source {al.heading_source})",
                                "firmware.alignment.heading_source", scn.source_file, t_s=t))
        elif al.heading_source == "psns":
            out.append(Fallback("alignment_heading_fallback", "run",
                                f"the alignment at {at} took the configured heading ({hd}): heading_source psns "
                                "without a polarization sensor", "firmware.alignment.heading_source",
                                scn.source_file, t_s=t))
        if not heading_given:
            out.append(Fallback("alignment_heading_default", "run",
                                f"the alignment at {at} used heading_deg's default ({al.heading_deg:g} deg): the "
                                "file gives no firmware.alignment.heading_deg", "firmware.alignment.heading_deg",
                                scn.source_file, t_s=t))
    low = ((psns or {}).get("uses") or {}).get("sun_low", 0)
    if low:
        out.append(Fallback("psns_sun_low", "run",
                            f"{low} solar vector(s) not used: the sun was below firmware.psns.min_sun_elevation_deg "
                            f"({scn.firmware.psns.min_sun_elevation_deg:g} deg)", "firmware.psns.min_sun_elevation_deg",
                            scn.source_file))
    return out
