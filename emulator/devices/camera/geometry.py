"""Camera geometry and on-camera arithmetic: parameters, view rays of the pixels and observation points,
the mosaic layout, the super-pixel Stokes split, the wire AOP and the mounting (see :mod:`emulator.devices.camera`)."""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from protocols.constants import DEG

from ...world.frames import cbn_from_euler, rotvec_matrix, yaw_from_heading
from .optics import LensModel, SensorDefects

__all__ = [
    "CHANNEL_OFFSETS",
    "DEG",
    "IMX250MZR_NX",
    "IMX250MZR_NY",
    "IMX250MZR_PIXEL_M",
    "CameraConfig",
    "CameraGeometry",
    "PointObservations",
    "mounting_matrix",
    "rotation_vector_matrix",
    "stokes_superpixel",
    "wire_aop_cdeg",
]

IMX250MZR_NX = 2448
IMX250MZR_NY = 2048
IMX250MZR_PIXEL_M = 3.45e-6
#: micro-polarizer angle (deg) -> (row, col) offset inside the 2x2 super-pixel (camera conventions, polanalyser layout).
CHANNEL_OFFSETS = {90: (0, 0), 45: (0, 1), 135: (1, 0), 0: (1, 1)}


def rotation_vector_matrix(rv: np.ndarray) -> np.ndarray:
    """Rotation matrix of a rotation vector (rad) (scipy ``Rotation``)."""
    return rotvec_matrix(rv)


@dataclass
class CameraConfig:
    """Camera parameters (SI; see module docstring).

    ``mounting_c_b`` is ``C_c^b`` (camera to body) including the installation error.
    """

    nx: int = IMX250MZR_NX
    ny: int = IMX250MZR_NY
    pixel_m: float = IMX250MZR_PIXEL_M
    lens: str = "pinhole"
    focal_m: float = 4.0e-3
    fisheye_max_theta: float = 90.0 * DEG
    mounting_c_b: np.ndarray = field(default_factory=lambda: np.eye(3))
    full_well_e: float = 10000.0
    read_noise_e: float = 5.0
    adc_bits: int = 12
    extinction_ratio: float = 300.0
    signal_e: float = 5000.0
    #: auto exposure (None: off, every frame at ``signal_e``): the exposure of each frame is the one the last frame's
    #: metering asked for, so that the ``auto_exposure_percentile`` of the observation points' brightest channel
    #: (glare excluded) reaches this fraction of the full well (:meth:`PolarizationCameraModel.exposure_scale`)
    auto_exposure_target: float | None = None
    auto_exposure_percentile: float = 98.0
    grid: tuple[int, int] = (15, 15)
    bin_superpixels: int = 8
    fidelity: str = "binned"
    sun_glare: float = 3.0 * DEG
    min_sun_elevation: float = 0.0
    dop_threshold: float = 0.05
    min_points: int = 10
    noise: bool = True
    #: principal point (1-based pixels; None: the sensor centre), radial distortion, exit pupil to image plane (m;
    #: None: a thin lens with its stop at the lens, chief-ray angle = field angle; inf: image-space telecentric)
    cx_px: float | None = None
    cy_px: float | None = None
    k1: float = 0.0
    k2: float = 0.0
    exit_pupil_m: float | None = None
    #: pinhole lenses: sixth-order radial and decentering distortion (outside the firmware's lens family)
    k3: float = 0.0
    p1: float = 0.0
    p2: float = 0.0
    #: the lens's radial diattenuation at the sensor's corner (:func:`.optics.radial_diattenuation`); 0: none
    lens_diattenuation_edge: float = 0.0
    defects: SensorDefects = field(default_factory=SensorDefects)
    #: seed of the sensor's fixed pattern (orientation, extinction, PRNU maps): one physical sensor per seed
    defect_seed: int = 0

    @property
    def lens_model(self) -> LensModel:
        return LensModel(self.lens, self.focal_m, self.pixel_m, self.nx, self.ny, self.cx_px, self.cy_px, self.k1,
                         self.k2, math.inf if self.exit_pupil_m is None else self.exit_pupil_m, self.k3, self.p1,
                         self.p2)

    @property
    def diattenuation(self) -> float:
        er = self.extinction_ratio
        return 1.0 if math.isinf(er) else (er - 1.0) / (er + 1.0)

    @property
    def dn_max(self) -> int:
        return (1 << self.adc_bits) - 1

    @property
    def gain_dn_per_e(self) -> float:
        return self.dn_max / self.full_well_e


class CameraGeometry:
    """Rays of every super-pixel and of every observation point, and the point windows.

    Attributes
    ----------
    sp_v : (3, ny/2, nx/2) float32 unit rays of the super-pixel centres, camera frame.
    sp_valid : (ny/2, nx/2) bool, False outside a fisheye's image circle.
    sp_cos_cra : (ny/2, nx/2) float32 cos of the chief-ray angle of the super-pixels.
    max_field_angle : largest field angle of a valid super-pixel, rad (plus 2 mrad).
        The four super-pixel attributes cover the whole sensor (1.25 M rays through the lens inversion, about a
        second): only the full fidelity renders them, so they are computed on first use (binned: never).
    x_px, y_px : (P,) int observation-point pixels (1-based column, row).
    pt_v : (P, 3) float64 rays of those pixels (the pinhole / fisheye formula of the conventions, exact).
    win_rows, win_cols : (P, n+1) super-pixel row / column indices of each window.
    w_row, w_col : (n+1,) separable window weights.
    kappa : ``sum w^2 / (sum w)^2`` of the 2-D window (variance factor of its weighted mean).
    """

    def __init__(self, cfg: CameraConfig) -> None:
        if cfg.nx % 2 or cfg.ny % 2:
            raise ValueError("the sensor needs an even number of rows and columns (2x2 super-pixels)")
        if cfg.lens not in ("pinhole", "fisheye"):
            raise ValueError(f"lens must be pinhole or fisheye, got {cfg.lens!r}")
        self.cfg = cfg
        nsx, nsy = cfg.nx // 2, cfg.ny // 2
        self.lens = cfg.lens_model
        n = cfg.bin_superpixels
        if n < 1:
            raise ValueError("bin_superpixels must be >= 1")
        w = np.ones(n + 1)
        w[0], w[-1] = 0.75, 0.25
        self.w_row = self.w_col = w
        self.kappa = float((w @ w) ** 2 / (w.sum() ** 2) ** 2)
        gx, gy = cfg.grid
        if n + 1 > nsx or n + 1 > nsy:
            raise ValueError("the observation window is larger than the sensor")
        j0 = np.unique(np.round(np.linspace(0, nsx - (n + 1), gx)).astype(int))
        i0 = np.unique(np.round(np.linspace(0, nsy - (n + 1), gy)).astype(int))
        J0, I0 = np.meshgrid(j0, i0)
        J0, I0 = J0.ravel(), I0.ravel()
        x_px = 2 * J0 + 1 + n
        y_px = 2 * I0 + 1 + n
        pvx, pvy, pvz, pvalid = self.rays(x_px.astype(np.float64), y_px.astype(np.float64))
        keep = pvalid
        if cfg.lens == "fisheye":  # the whole window must be inside the image circle
            r_win = (n + 1) * cfg.pixel_m
            _, _, r0 = self.lens.radial_m(x_px, y_px)
            with np.errstate(invalid="ignore"):
                keep &= self.lens._theta((r0 + r_win) / cfg.focal_m) <= cfg.fisheye_max_theta
        self.x_px = x_px[keep]
        self.y_px = y_px[keep]
        self.pt_v = np.stack([pvx[keep], pvy[keep], pvz[keep]], axis=1)
        self.pt_cos_cra = self.cos_cra(self.x_px.astype(np.float64), self.y_px.astype(np.float64))
        self.pt_lens_dia = self.lens_diattenuation(self.x_px.astype(np.float64), self.y_px.astype(np.float64),
                                                   self.pt_v[:, 2])
        self.win_cols = J0[keep, None] + np.arange(n + 1)[None, :]
        self.win_rows = I0[keep, None] + np.arange(n + 1)[None, :]

    @functools.cached_property
    def _superpixels(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
        """``(sp_v, sp_valid, sp_cos_cra, max_field_angle)`` of the whole sensor (see the class docstring)."""
        cfg = self.cfg
        xc = 2.0 * np.arange(cfg.nx // 2) + 1.5  # 1-based pixel coordinate of super-pixel centres
        yc = 2.0 * np.arange(cfg.ny // 2) + 1.5
        X, Y = np.meshgrid(xc, yc)
        vx, vy, vz, valid = self.rays(X, Y)
        sp_v = np.stack([vx, vy, vz]).astype(np.float32)
        # cos of the chief-ray angle on the sensor of every super-pixel (polarization transfer, vignetting); a
        # thin lens keeps the field angle: the rays' z just computed (what cos_cra would compute again)
        cos_cra = vz if cfg.exit_pupil_m is None else self.cos_cra(X, Y)
        # largest angle between a (valid) super-pixel ray and the optical axis, rad
        max_field_angle = float(np.arccos(np.clip(np.min(np.where(valid, vz, 1.0)), -1.0, 1.0))) + 2e-3
        return sp_v, valid, np.asarray(cos_cra, dtype=np.float64).astype(np.float32), max_field_angle

    def lens_diattenuation(self, x: np.ndarray, y: np.ndarray, vz: np.ndarray
                           ) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """``(D, cos 2 phi, sin 2 phi)`` of the lens's radial diattenuation at pixels ``(x, y)`` whose rays have
        ``cos(theta) = vz`` (phi the image-plane azimuth from the principal point); None without one."""
        d_edge = self.cfg.lens_diattenuation_edge
        if d_edge <= 0.0:
            return None
        cfg = self.cfg
        corners_x = np.array([1.0, cfg.nx, 1.0, float(cfg.nx)])
        corners_y = np.array([1.0, 1.0, float(cfg.ny), float(cfg.ny)])
        _, _, cz, _ = self.rays(corners_x, corners_y)
        s2_edge = float(np.max(1.0 - np.asarray(cz) ** 2))
        X, Y, _ = self.lens.radial_m(x, y)
        phi = np.arctan2(Y, X)
        vz = np.asarray(vz, dtype=np.float64)
        d = d_edge * np.clip((1.0 - vz * vz) / s2_edge, 0.0, 1.0)
        return d, np.cos(2.0 * phi), np.sin(2.0 * phi)

    @functools.cached_property
    def sp_lens_dia(self) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
        """:meth:`lens_diattenuation` of every super-pixel (float32), None without one."""
        if self.cfg.lens_diattenuation_edge <= 0.0:
            return None
        cfg = self.cfg
        xc = 2.0 * np.arange(cfg.nx // 2) + 1.5
        yc = 2.0 * np.arange(cfg.ny // 2) + 1.5
        X, Y = np.meshgrid(xc, yc)
        out = self.lens_diattenuation(X, Y, self.sp_v[2].astype(np.float64))
        assert out is not None
        return tuple(a.astype(np.float32) for a in out)  # type: ignore[return-value]

    @property
    def sp_v(self) -> np.ndarray:
        return self._superpixels[0]

    @property
    def sp_valid(self) -> np.ndarray:
        return self._superpixels[1]

    @property
    def sp_cos_cra(self) -> np.ndarray:
        return self._superpixels[2]

    @property
    def max_field_angle(self) -> float:
        return self._superpixels[3]

    @property
    def n_points(self) -> int:
        return len(self.x_px)

    def rays(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Unit view rays (camera frame) of 1-based pixel coordinates ``x`` (column), ``y`` (row), through the lens
        (:class:`emulator.devices.camera.optics.LensModel`), and whether they are inside the image circle."""
        v, th, _, _ = self.lens.rays(np.asarray(x, dtype=np.float64), np.asarray(y, dtype=np.float64))
        with np.errstate(invalid="ignore"):
            valid = ~np.isnan(th) if self.cfg.lens == "pinhole" else th <= self.cfg.fisheye_max_theta
        return v[0], v[1], v[2], valid

    def cos_cra(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """cos of the chief-ray angle on the sensor at pixels ``(x, y)``; a thin lens (``exit_pupil_m`` None)
        keeps the field angle."""
        if self.cfg.exit_pupil_m is None:
            return np.asarray(self.rays(x, y)[2], dtype=np.float64)
        _, _, r = self.lens.radial_m(x, y)
        return np.cos(self.lens.chief_ray_angle(r))


@dataclass
class PointObservations:
    """What the on-camera processing produces for one frame (P points).

    ``aop`` is the wire AOP (rad, from image +y towards +x, (-pi/2, pi/2]); ``dop`` measured
    DOP; ``s0_dn`` the window-mean S0 in DN; ``saturated`` and ``outlier`` per point;
    ``status`` the :class:`PsnsStatus` bits.
    """

    x_px: np.ndarray
    y_px: np.ndarray
    aop: np.ndarray
    dop: np.ndarray
    s0_dn: np.ndarray
    saturated: np.ndarray
    status: int
    sun_elevation: float = 0.0


def wire_aop_cdeg(aop: np.ndarray) -> np.ndarray:
    """AOP (rad) to the wire's i16 0.01 deg in (-9000, 9000]."""
    c = np.round(np.asarray(aop) / DEG * 100.0).astype(np.int64)
    c = np.where(c <= -9000, c + 18000, c)
    return np.where(c > 9000, c - 18000, c)


def stokes_superpixel(mosaic: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Half-resolution super-pixel split: S0, DOP and psi (rad, ``atan2(S2, S1)/2``) images, float32.

    This is the fast on-camera path of docs/reference/algorithms.md section 4 (no interpolation).
    """
    m = mosaic
    i90 = m[0::2, 0::2].astype(np.float32)
    i45 = m[0::2, 1::2].astype(np.float32)
    i135 = m[1::2, 0::2].astype(np.float32)
    i0 = m[1::2, 1::2].astype(np.float32)
    s1 = i0 - i90
    s2 = i45 - i135
    s0 = (i0 + i90 + i45 + i135) * np.float32(0.5)
    lin = np.sqrt(s1 * s1 + s2 * s2)
    dop = np.divide(lin, s0, out=np.zeros_like(s0), where=s0 > 0)
    psi = np.float32(0.5) * np.arctan2(s2, s1)
    return s0, dop, psi


def mounting_matrix(heading_deg: float = 0.0, pitch_deg: float = 0.0, roll_deg: float = 0.0,
                    installation_error_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> np.ndarray:
    """``C_c^b``: a nominal mount (Euler angles, the body-attitude convention) times a small installation
    error (rotation vector about the camera axes, deg)."""
    nominal = cbn_from_euler(pitch_deg * DEG, roll_deg * DEG, yaw_from_heading(heading_deg * DEG))
    return nominal @ rotation_vector_matrix(np.asarray(installation_error_deg, dtype=np.float64) * DEG)
