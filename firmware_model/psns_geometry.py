"""Polarization-sensor geometry shared by the firmware and the emulator's sensor models (docs/architecture.md
"Conventions").

Camera frame c: origin at the imager centre, +z along the optical axis towards the scene, +x along
image columns (column index x = 1..nx), +y along image rows (row index y = 1..ny).

* Pinhole: pixel (x, y) (1-based) looks along ``V^c = (Dx (x - (nx+1)/2), Dy (y - (ny+1)/2), f)``
  (base paper Eq. 4).
* Equidistant fisheye: focal-plane point ``(X, Y)`` as above, ``r = hypot(X, Y)``, ``theta = r / f``,
  ``alpha = atan2(Y, X)``, ``V^c = (sin theta cos alpha, sin theta sin alpha, cos theta)``.

Mounting: ``C_c^b`` (camera to body). The default is the identity: the camera looks along body +z
(up), x_c = x_b (right), y_c = y_b (forward).

Multi-unit compass: each unit u is a single-direction polarization sensor with the same frame
convention (view ray = its +z axis, AOP in its x-y plane from +y towards +x). The default 9-unit
geometry (:func:`compass_unit_mountings`) is defined here once; the emulator's compass model imports
it. Unit 0 looks at the zenith with ``C_0^b = I``; units 1..8 sit on a ring at zenith angle 45 deg,
every 45 deg of azimuth, azimuth measured in the body x-y plane from body +y (forward) towards
body +x (right), unit 1 at azimuth 0. Each ring unit's +y axis points "up the hemisphere" (towards
the zenith, in the vertical plane of its view ray) and ``x_u = y_u x z_u``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from .arrays import FloatArray
from .units import DEG

__all__ = [
    "COMPASS_N_UNITS",
    "COMPASS_RING_ZENITH_DEG",
    "IMX250MZR_NX",
    "IMX250MZR_NY",
    "IMX250MZR_PITCH_M",
    "CameraGeometry",
    "compass_unit_mountings",
    "compass_view_rays",
]

#: Sony IMX250MZR: 2448 x 2048 pixels, 3.45 um pitch (base paper section III.A).
IMX250MZR_NX = 2448
IMX250MZR_NY = 2048
IMX250MZR_PITCH_M = 3.45e-6

COMPASS_N_UNITS = 9
COMPASS_RING_ZENITH_DEG = 45.0


@dataclass(frozen=True)
class CameraGeometry:
    """Intrinsics and mounting of the polarization camera (docs/architecture.md "Conventions").

    Attributes
    ----------
    nx, ny : pixels along x (columns) and y (rows).
    dx_m, dy_m : pixel pitch, m.
    focal_m : focal length, m (default 4 mm, the reference study's lens).
    projection : ``"pinhole"`` or ``"fisheye"`` (equidistant).
    c_c_b : (3, 3) mounting ``C_c^b``.
    """

    nx: int = IMX250MZR_NX
    ny: int = IMX250MZR_NY
    dx_m: float = IMX250MZR_PITCH_M
    dy_m: float = IMX250MZR_PITCH_M
    focal_m: float = 4.0e-3
    projection: str = "pinhole"
    c_c_b: FloatArray = field(default_factory=lambda: np.eye(3))

    def __post_init__(self) -> None:
        if self.projection not in ("pinhole", "fisheye"):
            raise ValueError(f"projection must be 'pinhole' or 'fisheye', got {self.projection!r}")

    def focal_plane(self, x_px: FloatArray, y_px: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Focal-plane coordinates ``(X, Y)`` in m of 1-based pixel indices (Eq. 4)."""
        return (self.dx_m * (np.asarray(x_px, dtype=np.float64) - (self.nx + 1) / 2.0),
                self.dy_m * (np.asarray(y_px, dtype=np.float64) - (self.ny + 1) / 2.0))

    def view_rays(self, x_px: FloatArray, y_px: FloatArray) -> FloatArray:
        """Unit view rays ``V^c`` (N, 3) of 1-based pixels, for the configured projection."""
        X, Y = self.focal_plane(x_px, y_px)
        if self.projection == "pinhole":
            v = np.stack([X, Y, np.full_like(X, self.focal_m)], axis=-1)
            rays: FloatArray = v / np.linalg.norm(v, axis=-1, keepdims=True)
            return rays
        r = np.hypot(X, Y)
        theta = r / self.focal_m
        alpha = np.arctan2(Y, X)
        st = np.sin(theta)
        return np.stack([st * np.cos(alpha), st * np.sin(alpha), np.cos(theta)], axis=-1)


def compass_unit_mountings(n_ring: int = COMPASS_N_UNITS - 1,
                           ring_zenith_deg: float = COMPASS_RING_ZENITH_DEG) -> FloatArray:
    """Mounting matrices ``C_u^b`` of the default compass (see module docstring), shape (1 + n_ring, 3, 3).

    Columns of ``C_u^b`` are the unit's x, y, z axes in body coordinates.
    """
    out = np.empty((1 + n_ring, 3, 3))
    out[0] = np.eye(3)
    th = ring_zenith_deg * DEG
    for k in range(n_ring):
        az = 2.0 * math.pi * k / n_ring
        z = np.array([math.sin(th) * math.sin(az), math.sin(th) * math.cos(az), math.cos(th)])
        y = np.array([-math.cos(th) * math.sin(az), -math.cos(th) * math.cos(az), math.sin(th)])
        x = np.array([y[1] * z[2] - y[2] * z[1], y[2] * z[0] - y[0] * z[2], y[0] * z[1] - y[1] * z[0]])
        out[1 + k] = np.column_stack([x, y, z])
    return out


def compass_view_rays(mountings: FloatArray | None = None) -> FloatArray:
    """Body-frame view rays (unit +z axes) of the compass units, shape (n, 3)."""
    m = compass_unit_mountings() if mountings is None else mountings
    return m[:, :, 2].copy()
