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
from .attitude import q2mat, rv2q
from .calibration import NOMINAL_POLARIZER_DEG, CameraCalibration
from .units import DEG

__all__ = [
    "COMPASS_N_UNITS",
    "COMPASS_RING_ZENITH_DEG",
    "IMX250MZR_NX",
    "IMX250MZR_NY",
    "IMX250MZR_PITCH_M",
    "CameraGeometry",
    "calibrated_mountings",
    "camera_from_calibration",
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
    cx_px, cy_px : principal point, 1-based pixels (None: the sensor centre, the paper's Eq. 4).
    k1, k2 : radial distortion (pinhole: on ``tan(theta)``; fisheye: on ``theta``), from the calibration file.
    exit_pupil_m : exit pupil to image plane, m (None: thin lens, the chief ray keeps the field angle).
    polarizer_deg : the calibrated orientations of the four micro-polarizer channels (nominally 0, 45, 90, 135),
        deg from image +x towards +y; :func:`firmware_model.psns.correct_polarizer` inverts the camera's nominal
        Stokes processing with them.
    extinction_ratio : the calibrated extinction ratio of the polarizers (None: the DOP is not rescaled).
    """

    nx: int = IMX250MZR_NX
    ny: int = IMX250MZR_NY
    dx_m: float = IMX250MZR_PITCH_M
    dy_m: float = IMX250MZR_PITCH_M
    focal_m: float = 4.0e-3
    projection: str = "pinhole"
    c_c_b: FloatArray = field(default_factory=lambda: np.eye(3))
    cx_px: float | None = None
    cy_px: float | None = None
    k1: float = 0.0
    k2: float = 0.0
    exit_pupil_m: float | None = None
    polarizer_deg: tuple[float, float, float, float] = NOMINAL_POLARIZER_DEG
    extinction_ratio: float | None = None

    @property
    def paper_lens(self) -> bool:
        """The paper's lens: centred, undistorted, thin (the E-vector is the orthographic inverse, Eq. 5-8)."""
        return (self.cx_px is None and self.cy_px is None and self.k1 == 0.0 and self.k2 == 0.0
                and self.exit_pupil_m is None)

    def __post_init__(self) -> None:
        if self.projection not in ("pinhole", "fisheye"):
            raise ValueError(f"projection must be 'pinhole' or 'fisheye', got {self.projection!r}")

    def focal_plane(self, x_px: FloatArray, y_px: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Focal-plane coordinates ``(X, Y)`` in m of 1-based pixel indices (Eq. 4)."""
        cx = (self.nx + 1) / 2.0 if self.cx_px is None else self.cx_px
        cy = (self.ny + 1) / 2.0 if self.cy_px is None else self.cy_px
        return (self.dx_m * (np.asarray(x_px, dtype=np.float64) - cx),
                self.dy_m * (np.asarray(y_px, dtype=np.float64) - cy))

    def field_angle(self, r_m: FloatArray) -> FloatArray:
        """Field angle (rad) of image radius ``r_m``: the distortion polynomial inverted by fixed-point steps
        (``u = rho / (1 + k1 u^2 + k2 u^4)``, six iterations; converges for ``|k1| u^2 < 0.3``)."""
        rho = np.asarray(r_m, dtype=np.float64) / self.focal_m
        u = rho
        if self.k1 != 0.0 or self.k2 != 0.0:
            for _ in range(6):
                u2 = u * u
                u = rho / (1.0 + self.k1 * u2 + self.k2 * u2 * u2)
        th: FloatArray = np.arctan(u) if self.projection == "pinhole" else u
        return th

    def view_rays(self, x_px: FloatArray, y_px: FloatArray) -> FloatArray:
        """Unit view rays ``V^c`` (N, 3) of 1-based pixels, for the configured projection."""
        X, Y = self.focal_plane(x_px, y_px)
        if not self.paper_lens:
            r = np.hypot(X, Y)
            th = self.field_angle(r)
            al = np.arctan2(Y, X)
            st = np.sin(th)
            return np.stack([st * np.cos(al), st * np.sin(al), np.cos(th)], axis=-1)
        if self.projection == "pinhole":
            v = np.stack([X, Y, np.full_like(X, self.focal_m)], axis=-1)
            rays: FloatArray = v / np.linalg.norm(v, axis=-1, keepdims=True)
            return rays
        r = np.hypot(X, Y)
        theta = r / self.focal_m
        alpha = np.arctan2(Y, X)
        st = np.sin(theta)
        return np.stack([st * np.cos(alpha), st * np.sin(alpha), np.cos(theta)], axis=-1)


def camera_from_calibration(cal: CameraCalibration) -> CameraGeometry:
    """The firmware's camera model from its calibration file (:mod:`firmware_model.calibration`)."""
    rv = np.asarray(cal.boresight_rotvec_deg, dtype=np.float64) * DEG
    return CameraGeometry(nx=cal.nx, ny=cal.ny, dx_m=cal.pixel_m, dy_m=cal.pixel_m, focal_m=cal.focal_m,
                          projection=cal.projection, c_c_b=q2mat(rv2q(rv)), cx_px=cal.cx_px, cy_px=cal.cy_px,
                          k1=cal.k1, k2=cal.k2, exit_pupil_m=cal.exit_pupil_m, polarizer_deg=cal.polarizer_deg,
                          extinction_ratio=cal.extinction_ratio)


def calibrated_mountings(nominal: FloatArray, unit_installation_deg: tuple[tuple[float, float, float], ...]
                         ) -> FloatArray:
    """Compass mountings as calibrated: each nominal ``C_u^b`` (n, 3, 3) turned by its unit's installation angles,
    a rotation vector about the unit's own axes (deg; the calibration file's ``compass.unit_installation_deg``):
    ``C_u^b = C_u,nominal^b R(rv_u)``. An empty tuple keeps the nominal layout; otherwise one angle triple per unit.
    """
    if not unit_installation_deg:
        return np.asarray(nominal, dtype=np.float64)
    if len(unit_installation_deg) != len(nominal):
        raise ValueError(f"the calibration gives installation angles for {len(unit_installation_deg)} compass units, "
                         f"the compass has {len(nominal)}")
    return np.stack([m @ q2mat(rv2q(np.asarray(rv, dtype=np.float64) * DEG))
                     for m, rv in zip(nominal, unit_installation_deg, strict=True)])


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
