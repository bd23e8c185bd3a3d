"""The camera as an instrument: lens (intrinsics, radial distortion, exit pupil), the transfer of the sky's
polarization through the lens onto the sensor plane, and the sensor's fixed-pattern defects.

This is the world's model of the optics (docs/sensors.md, "Polarization camera"); the firmware inverts its own,
simpler model configured from its calibration file, and the two share no code (docs/architecture.md, the
independence rule).

Lens
    Rotationally symmetric about the optical axis (camera +z), principal point ``(cx, cy)`` in 1-based pixel
    coordinates. A ray at field angle ``theta`` (from +z) and azimuth ``phi`` is imaged at radius
    ``r = f * rho(theta)`` from the principal point along ``phi``, with ``rho(theta) = tan(theta) (1 + k1 t^2 +
    k2 t^4)``, ``t = tan(theta)`` (Brown's radial distortion) for ``pinhole`` and ``rho = theta (1 + k1 theta^2 +
    k2 theta^4)`` for the equidistant ``fisheye`` (Kannala-Brandt). Pixel -> ray inverts ``rho`` by Newton steps.
    A pinhole lens may also have a sixth-order radial term ``k3 t^6`` and Brown-Conrady decentering ``p1``, ``p2``
    (Brown 1966, "Decentering distortion of lenses", Photogramm. Eng. 32(3) 444): on the normalised image
    coordinates ``(x, y) = tan(theta) (cos phi, sin phi)``, ``r^2 = x^2 + y^2``::

        x_d = x (1 + k1 r^2 + k2 r^4 + k3 r^6) + 2 p1 x y + p2 (r^2 + 2 x^2)
        y_d = y (1 + k1 r^2 + k2 r^4 + k3 r^6) + p1 (r^2 + 2 y^2) + 2 p2 x y

    (the OpenCV form), inverted by fixed-point iteration. These are outside the firmware's lens family (radial k1, k2
    only: docs/calibration.md), so a calibration in that family leaves a model-form residual. The polarization
    transfer below keeps the rotationally symmetric rule (the decentering moves the image by < 1e-3 rad).

Polarization transfer (the meridional-plane rule)
    A non-polarizing rotationally symmetric lens keeps a ray in its meridional plane (the plane of the ray and
    the optical axis) and transports the field's components in the ray's local (s, p) basis: s perpendicular to
    the meridional plane (the azimuthal unit vector ``e_phi``), p in it and perpendicular to the ray (the
    polarization ray-tracing calculus of Yun, Crabtree & Chipman, Appl. Opt. 50(18), 2855 (2011); Chipman, Lam &
    Young, *Polarized Light and Optical Systems*, CRC 2018, ch. 10). Behind the lens the chief ray reaches the
    sensor at the chief-ray angle ``theta'`` with ``tan(theta') = r / d_xp`` (``d_xp`` the exit pupil's distance
    from the image plane), so the field that the wire-grid micro-polarizers see in the sensor plane is
    ``E_s e_phi + E_p cos(theta') e_rho``. The paper's model (an orthographic projection of the object-space
    E-vector) is the special case ``theta' = theta`` of a thin lens with its stop at the lens. Fresnel
    diattenuation and retardance of the lens surfaces (``t_s != t_p``, a few 0.1 % per coated surface at these
    angles) are neglected unless the camera has a ``radial_diattenuation_edge`` (the envelope's lenses): then the
    lens is a radial diattenuator, ``D(theta) = D_edge sin^2(theta) / sin^2(theta_edge)`` (theta_edge the field
    angle of the sensor's corner; Fresnel diattenuation grows as the square of the angle of incidence), its p axis
    (transmitted better) along the image radius: the Stokes vector at the sensor is that of a diattenuator's Mueller
    matrix (Chipman, Lam & Young 2018, ch. 6, Eq. 6.46), :func:`radial_diattenuation`. The obliquity dependence of
    the wire grid is neglected.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["LensModel", "SensorDefects", "defect_maps", "radial_diattenuation", "sensor_plane_field"]


@dataclass(frozen=True)
class LensModel:
    """Lens intrinsics (SI; see module docstring). ``cx_px``/``cy_px`` None: the sensor centre."""

    projection: str = "pinhole"
    focal_m: float = 4.0e-3
    pixel_m: float = 3.45e-6
    nx: int = 2448
    ny: int = 2048
    cx_px: float | None = None
    cy_px: float | None = None
    k1: float = 0.0
    k2: float = 0.0
    #: exit pupil to image plane, m; inf = image-space telecentric
    exit_pupil_m: float = math.inf
    #: pinhole only: sixth-order radial and decentering distortion (module docstring; outside the firmware's family)
    k3: float = 0.0
    p1: float = 0.0
    p2: float = 0.0

    @property
    def brown_conrady(self) -> bool:
        """True when the lens has terms beyond the rotationally symmetric ``rho(theta)``."""
        return self.projection == "pinhole" and (self.k3 != 0.0 or self.p1 != 0.0 or self.p2 != 0.0)

    def _distort(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r2 = x * x + y * y
        rad = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3))
        return (x * rad + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x),
                y * rad + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y)

    def _undistort(self, xd: np.ndarray, yd: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Normalised undistorted coordinates of distorted ones (fixed point, as OpenCV's undistortPoints)."""
        x, y = xd.copy(), yd.copy()
        for _ in range(40):
            r2 = x * x + y * y
            rad = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3))
            dx = 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x)
            dy = self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y
            x, y = (xd - dx) / rad, (yd - dy) / rad
        return x, y

    @property
    def cx(self) -> float:
        return (self.nx + 1) / 2.0 if self.cx_px is None else self.cx_px

    @property
    def cy(self) -> float:
        return (self.ny + 1) / 2.0 if self.cy_px is None else self.cy_px

    def _rho(self, th: np.ndarray) -> np.ndarray:
        if self.projection == "pinhole":
            t = np.tan(th)
            return t * (1.0 + self.k1 * t * t + self.k2 * t ** 4)
        return th * (1.0 + self.k1 * th * th + self.k2 * th ** 4)

    def _theta(self, rho: np.ndarray) -> np.ndarray:
        """Invert ``rho(theta)`` (Newton, from the undistorted guess); NaN where no field angle images there
        (beyond the largest radius a barrel-distorted lens reaches)."""
        rho = np.asarray(rho, dtype=np.float64)
        th = np.arctan(rho) if self.projection == "pinhole" else rho.copy()
        if self.k1 == 0.0 and self.k2 == 0.0:
            return th
        with np.errstate(all="ignore"):
            for _ in range(12):
                h = 1e-7
                f0 = self._rho(th) - rho
                d = (self._rho(th + h) - self._rho(th - h)) / (2 * h)
                th = th - f0 / np.where(np.abs(d) > 1e-12, d, 1e-12)
            ok = (np.abs(self._rho(th) - rho) < 1e-9) & (th >= 0.0) & (th < math.pi)
        return np.where(ok, th, np.nan)

    def radial_m(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Image-plane offsets ``(X, Y)`` and radius ``r`` (m) of 1-based pixel coordinates from the principal
        point."""
        X = self.pixel_m * (np.asarray(x, dtype=np.float64) - self.cx)
        Y = self.pixel_m * (np.asarray(y, dtype=np.float64) - self.cy)
        return X, Y, np.hypot(X, Y)

    def rays(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Unit object-space rays (camera frame) of pixels and their field angles ``theta`` (rad)."""
        X, Y, r = self.radial_m(x, y)
        if self.brown_conrady:
            xu, yu = self._undistort(X / self.focal_m, Y / self.focal_m)
            th = np.arctan(np.hypot(xu, yu))
            al = np.arctan2(yu, xu)
            st = np.sin(th)
            return np.stack([st * np.cos(al), st * np.sin(al), np.cos(th)]), th, np.cos(self.chief_ray_angle(r)), al
        th = self._theta(r / self.focal_m)  # NaN outside the lens's image: reported as invalid by the caller
        al = np.arctan2(Y, X)
        tv = np.where(np.isnan(th), 0.0, th)
        st = np.sin(tv)
        return np.stack([st * np.cos(al), st * np.sin(al), np.cos(tv)]), th, np.cos(self.chief_ray_angle(r)), al

    def chief_ray_angle(self, r: np.ndarray) -> np.ndarray:
        """Chief-ray angle ``theta'`` (rad) at image radius ``r`` (m)."""
        if math.isinf(self.exit_pupil_m):
            return np.zeros_like(np.asarray(r, dtype=np.float64))
        return np.arctan(np.asarray(r, dtype=np.float64) / self.exit_pupil_m)

    def project(self, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """1-based pixel coordinates of object-space rays ``v`` (3, N) (camera frame)."""
        if self.brown_conrady:
            xd, yd = self._distort(v[0] / v[2], v[1] / v[2])
            return self.cx + self.focal_m * xd / self.pixel_m, self.cy + self.focal_m * yd / self.pixel_m
        th = np.arccos(np.clip(v[2] / np.linalg.norm(v, axis=0), -1.0, 1.0))
        al = np.arctan2(v[1], v[0])
        r = self.focal_m * self._rho(th)
        return self.cx + r * np.cos(al) / self.pixel_m, self.cy + r * np.sin(al) / self.pixel_m


def sensor_plane_field(vx: np.ndarray, vy: np.ndarray, vz: np.ndarray, ex: np.ndarray, ey: np.ndarray,
                       ez: np.ndarray, cos_cra: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The field the micro-polarizers see: ``E_s e_phi + E_p cos(theta') e_rho`` (x, y components), see module
    docstring. ``v`` object-space rays, ``e`` the sky's E-vector (unit, perpendicular to v), camera frame."""
    rho = np.sqrt(vx * vx + vy * vy)
    on_axis = rho < 1e-12
    safe = np.where(on_axis, 1.0, rho)
    cphi = np.where(on_axis, 1.0, vx / safe)
    sphi = np.where(on_axis, 0.0, vy / safe)
    # e_rho = (cphi, sphi, 0), e_phi = (-sphi, cphi, 0); p = cos(theta) e_rho - sin(theta) z, sin(theta) = rho
    e_s = -sphi * ex + cphi * ey
    e_p = vz * (cphi * ex + sphi * ey) - rho * ez
    a_rho = e_p * cos_cra
    return (cphi * a_rho - sphi * e_s).astype(ex.dtype, copy=False), (sphi * a_rho + cphi * e_s).astype(
        ex.dtype, copy=False)


def radial_diattenuation(radiance: np.ndarray, s1: np.ndarray, s2: np.ndarray, d: np.ndarray, c2phi: np.ndarray,
                         s2phi: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The Stokes vector ``(S0, S1, S2)`` (sensor-plane x axis) behind a diattenuator of diattenuation ``d`` whose
    axis of higher transmission is at ``phi`` (``c2phi = cos 2 phi``, ``s2phi = sin 2 phi``), unit mean
    transmission: the diattenuator's Mueller matrix (Chipman, Lam & Young 2018, Eq. 6.46) with
    ``k = sqrt(1 - d^2)``."""
    k = np.sqrt(1.0 - d * d)
    cs = (1.0 - k) * c2phi * s2phi
    s0n = radiance + d * (c2phi * s1 + s2phi * s2)
    s1n = d * c2phi * radiance + (c2phi * c2phi + k * s2phi * s2phi) * s1 + cs * s2
    s2n = d * s2phi * radiance + cs * s1 + (s2phi * s2phi + k * c2phi * c2phi) * s2
    dt = radiance.dtype
    return s0n.astype(dt, copy=False), s1n.astype(dt, copy=False), s2n.astype(dt, copy=False)


@dataclass(frozen=True)
class SensorDefects:
    """Fixed-pattern defects of the polarization sensor (docs/sensors.md gives each figure's source).

    ``orientation_sigma_deg`` per-pixel micro-polarizer orientation error (rms), ``orientation_bias_deg`` the
    per-channel systematic offsets (0, 45, 90, 135); ``extinction_ratio`` at the sky's effective wavelength and
    ``extinction_spread`` its relative pixel-to-pixel spread (lognormal); ``prnu`` the photo-response
    non-uniformity (rms, relative); ``dark_e`` dark signal per exposure (e-); ``crosstalk`` the fraction of each
    of the four edge neighbours' signal a pixel collects; ``vignetting`` applies the cos^4 law of the chief-ray
    angle.
    """

    orientation_sigma_deg: float = 0.0
    orientation_bias_deg: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)
    extinction_spread: float = 0.0
    prnu: float = 0.0
    dark_e: float = 0.0
    crosstalk: float = 0.0
    vignetting: bool = False


def defect_maps(d: SensorDefects, extinction_ratio: float, shape: tuple[int, int],
                rng: np.random.Generator, at: tuple[np.ndarray, np.ndarray] | None = None
                ) -> dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]]:
    """Per channel (0, 45, 90, 135): per-super-pixel ``(delta (rad), diattenuation, gain)`` maps, float32.

    ``at``: (row, column) index arrays: the maps' values at those super-pixels only (the shape of the indices),
    the same values as indexing the whole maps (the whole sensor is drawn from ``rng`` either way, in the same
    order; only the arithmetic is restricted) -- the binned camera needs its windows, not 1.25 M super-pixels."""
    def draw() -> np.ndarray:
        z = rng.standard_normal(shape)
        return z if at is None else z[at]

    out_shape = shape if at is None else np.broadcast_shapes(np.shape(at[0]), np.shape(at[1]))
    out = {}
    for i, theta in enumerate((0, 45, 90, 135)):
        delta = (d.orientation_bias_deg[i] + d.orientation_sigma_deg * draw()) * math.pi / 180.0
        if math.isinf(extinction_ratio):
            dia = np.ones(out_shape)
        else:
            er = extinction_ratio * np.exp(d.extinction_spread * draw()) \
                if d.extinction_spread > 0 else np.full(out_shape, extinction_ratio)
            dia = (er - 1.0) / (er + 1.0)
        gain = 1.0 + d.prnu * draw() if d.prnu > 0 else np.ones(out_shape)
        out[theta] = (delta.astype(np.float32), dia.astype(np.float32), gain.astype(np.float32))
    return out
