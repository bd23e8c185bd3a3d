"""NMEA 0183 sentences of the navigation output that :mod:`protocols.nmea_build` does not declare: HDT, THS
(true heading) and PASHR (attitude). One builder per sentence; the position, velocity and time sentences
(GGA, RMC, VTG, ZDA) come from :mod:`protocols.nmea_build` unchanged.

Layouts (docs/icd.md, section "NMEA navigation output"):

=========  ==============================================================================================
sentence   fields
=========  ==============================================================================================
``HDT``    heading, deg true (2 decimals, [0, 360)), ``T``
``THS``    heading, deg true (2 decimals), mode indicator ``A`` autonomous / ``E`` estimated (dead
           reckoning) / ``M`` manual / ``S`` simulator / ``V`` not valid (NMEA 0183 v3.0+)
``PASHR``  UTC ``hhmmss.sss``, heading deg true (2 decimals), ``T``, roll deg (2 decimals, positive right
           wing down = port side up), pitch deg (2 decimals, nose up), heave m (2 decimals), roll,
           pitch and heading 1-sigma deg (3 decimals), aiding flag (0 none, 1 GNSS, 2 GNSS + heading
           aid), IMU flag (0 satisfactory, 1 IMU out). The Ashtech/Applanix layout that gpsd's NMEA
           driver and the ROS NMEA drivers read; the talker is ``P`` (proprietary) + ``ASHR``.
=========  ==============================================================================================
"""

from __future__ import annotations

import datetime as _dt

from .nmea_build import build_sentence

__all__ = ["THS_MODES", "build_hdt", "build_pashr", "build_ths"]

#: THS mode indicators (NMEA 0183 v3.0): autonomous, estimated, manual, simulator, not valid.
THS_MODES = frozenset("AEMSV")


def build_hdt(heading_deg: float, talker: str = "GN") -> bytes:
    """HDT: true heading, deg (2 decimals, wrapped to [0, 360))."""
    return build_sentence(talker, "HDT", [f"{_wrap360(heading_deg):.2f}", "T"])


def build_ths(heading_deg: float | None, mode: str = "A", talker: str = "GN") -> bytes:
    """THS: true heading, deg (2 decimals) and its mode indicator; ``None`` leaves the heading empty (mode V)."""
    if mode not in THS_MODES:
        raise ValueError(f"THS mode must be one of {''.join(sorted(THS_MODES))}, got {mode!r}")
    return build_sentence(talker, "THS", ["" if heading_deg is None else f"{_wrap360(heading_deg):.2f}", mode])


def build_pashr(time_utc: _dt.time, heading_deg: float, roll_deg: float, pitch_deg: float, heave_m: float = 0.0,
                roll_sigma_deg: float = 0.0, pitch_sigma_deg: float = 0.0, heading_sigma_deg: float = 0.0,
                aiding: int = 1, imu_ok: bool = True) -> bytes:
    """PASHR attitude sentence (layout in the module docstring): angles in degrees, heave in metres."""
    if aiding not in (0, 1, 2):
        raise ValueError(f"PASHR aiding flag is 0, 1 or 2, got {aiding}")
    sec = time_utc.second + time_utc.microsecond / 1e6
    hms = f"{time_utc.hour:02d}{time_utc.minute:02d}{sec:06.3f}"
    return build_sentence("P", "ASHR", [
        hms, f"{_wrap360(heading_deg):.2f}", "T", f"{roll_deg:.2f}", f"{pitch_deg:.2f}", f"{heave_m:.2f}",
        f"{roll_sigma_deg:.3f}", f"{pitch_sigma_deg:.3f}", f"{heading_sigma_deg:.3f}", str(aiding),
        "0" if imu_ok else "1"])


def _wrap360(deg: float) -> float:
    """``deg`` in [0, 360) as it will print with 2 decimals (359.999 -> 0.00, not 360.00)."""
    w = deg % 360.0
    return 0.0 if round(w, 2) >= 360.0 else w
