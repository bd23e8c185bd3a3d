"""Units and physical constants of the firmware, defined once (SI and radians inside the code).

Multiply by a unit to convert into SI: ``heading_deg * DEG`` is radians, ``bias_deg_h * DPH`` is rad/s,
``bias_mg * 1e-3 * G_STD`` is m/s^2; divide by it to convert back (``pitch / DEG`` is degrees).
"""

from __future__ import annotations

import math

__all__ = ["DEG", "DPH", "G_STD", "HALF_PI", "TWO_PI"]

#: One degree in radians.
DEG = math.pi / 180.0
#: One degree per hour in rad/s (gyro bias figures).
DPH = DEG / 3600.0
#: Standard gravity, m/s^2 (the accelerometers' "g", mg and ug figures).
G_STD = 9.80665
HALF_PI = 0.5 * math.pi
TWO_PI = 2.0 * math.pi
