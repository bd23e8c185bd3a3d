"""Physical and geodetic constants that both sides of the emulator need, owned by neither.

The world (``emulator.world``, ``emulator.devices``) and the firmware (``firmware_model``) must not share
models (docs/architecture.md, the independence rule), but they do share the *defining constants* of the
reference systems they both work in. Those live here, in the lowest layer, once. Models built on them (gravity,
radii of curvature, rotations) are written separately on each side, or taken from a well-kept library on the world
side.

Sources: NIMA TR8350.2 (WGS-84, third edition, 2000), Table 3.1 (defining parameters) and Table 3.3.

Units, once for every layer: multiply by a unit to convert into SI (``heading_deg * DEG`` is radians,
``bias_deg_h * DPH`` is rad/s, ``bias_mg * 1e-3 * G_STD`` is m/s^2); divide by it to convert back.
"""

from __future__ import annotations

import math

__all__ = ["A_WGS84", "DEG", "DPH", "E2_WGS84", "F_WGS84", "GM_WGS84", "G_STD", "OMEGA_IE", "SPEED_OF_LIGHT"]

#: WGS-84 semi-major axis, m (TR8350.2 Table 3.1).
A_WGS84 = 6378137.0
#: WGS-84 flattening 1/f = 298.257223563 (TR8350.2 Table 3.1).
F_WGS84 = 1.0 / 298.257223563
#: First eccentricity squared, e^2 = f (2 - f).
E2_WGS84 = F_WGS84 * (2.0 - F_WGS84)
#: Earth's angular velocity, rad/s (TR8350.2 Table 3.1).
OMEGA_IE = 7.2921151467e-5
#: Earth's gravitational constant GM including the atmosphere, m^3/s^2 (TR8350.2 Table 3.1).
GM_WGS84 = 3.986004418e14
#: Speed of light in vacuum, m/s (exact, SI).
SPEED_OF_LIGHT = 299_792_458.0

#: One degree in radians.
DEG = math.pi / 180.0
#: One degree per hour in rad/s (gyro bias figures).
DPH = DEG / 3600.0
#: Standard gravity, m/s^2 (the accelerometers' "g", mg and ug figures; CGPM 1901, exact by definition).
G_STD = 9.80665
