"""Units and physical constants of the firmware (SI and radians inside the code).

The units both sides use (``DEG``, ``DPH``, ``G_STD``) are declared once, in :mod:`protocols.constants` (the lowest
layer, which the world may import too); this module gives the firmware its one place to import them from.

Multiply by a unit to convert into SI: ``heading_deg * DEG`` is radians, ``bias_deg_h * DPH`` is rad/s,
``bias_mg * 1e-3 * G_STD`` is m/s^2; divide by it to convert back (``pitch / DEG`` is degrees).
"""

from __future__ import annotations

import math

from protocols.constants import DEG, DPH, G_STD

__all__ = ["DEG", "DPH", "G_STD", "HALF_PI", "TWO_PI"]

HALF_PI = 0.5 * math.pi
TWO_PI = 2.0 * math.pi
