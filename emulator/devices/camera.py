"""Division-of-focal-plane polarization camera (Sony IMX250MZR) on the RS232 PSNS port.

Geometry and conventions (``docs/architecture.md``, section "Conventions"):

* camera frame c: +z optical axis, +x along columns (x = 1..nx), +y along rows (y = 1..ny);
  pinhole pixel (x, y) looks along ``(Dx (x - (nx+1)/2), Dy (y - (ny+1)/2), f)`` (base paper
  Eq. 4); equidistant fisheye: ``theta = r/f``, ``alpha = atan2(Y, X)``,
  ``V = (sin theta cos alpha, sin theta sin alpha, cos theta)``;
* micro-polarizers per 2x2 super-pixel: (row 0, col 0) = 90 deg, (0, 1) = 45, (1, 0) = 135,
  (1, 1) = 0 (the layout polanalyser expects); angles from +x towards +y;
* the E-vector enters as its orthographic projection ``(E_x, E_y)`` on the image plane,
  ``psi = atan2(E_y, E_x)``, Malus ``I_theta = S0/2 [1 + D DOP cos 2(psi - theta)]`` with
  ``D = (ER - 1)/(ER + 1)``;
* on-camera processing ``S0 = (I0+I45+I90+I135)/2``, ``S1 = I0 - I90``, ``S2 = I45 - I135``,
  ``DOP = sqrt(S1^2 + S2^2)/S0``, ``psi = atan2(S2, S1)/2``; on the wire ``AOP = 90 deg - psi``
  wrapped to (-90, 90] (from image +y towards +x, base paper Eq. 5);
* mounting: ``C_c^b`` (nominal rotation and a small installation error from the scenario);
* ``latency_us`` runs from the middle of the exposure to the start bit of the frame's first byte.

Sensor (``docs/reference/algorithms.md`` 2.2-2.3, reference values of its simulation):
2448 x 2048 pixels of 3.45 um, full well 10 000 e-, read noise 5 e-, 12-bit ADC, extinction
ratio 300. The sky (``emulator.world.sky``) gives DOP, E-vector and a relative radiance; the
exposure is taken as auto-exposed so that unpolarized sky of radiance 1 puts ``signal_e``
electrons into a pixel behind an ideal polarizer (``S0/2``; default half the full well).

Observation points. The image is read out as a grid of ``grid`` points. Each point integrates
``n + 1`` super-pixel columns and rows (``n = bin_superpixels``) with separable weights
``[3/4, 1, ..., 1, 1/4]``: a box of ``n`` super-pixels linearly interpolated by half a
super-pixel, so that the weighted centroid of the super-pixel centres (which sit on half-integer
pixel coordinates) is the integer pixel ``(x_px, y_px)`` that the frame reports. Inside one
super-pixel the 0/90 and 45/135 pixels sit symmetrically about its centre, so with a smooth sky
the first-order pixel-offset errors cancel in ``S1`` and ``S2``; what remains is second order in
the window size (a test bounds it).

Fidelity:

``full``
    renders the whole 2448 x 2048 mosaic (every super-pixel sees the sky along its own centre
    ray; shot noise as a Gaussian of variance ``mean + read_noise^2`` electrons, drawn from a
    16-bit inverse-CDF table; rounding to 12-bit DN with clipping), then runs the on-camera
    processing on the mosaic exactly as the real camera would.
``binned``
    evaluates the sky only along the ray of each observation point and draws the window means
    directly: each channel mean is Gaussian with the variance of the same weighted sum of
    independent pixels, ``kappa ((mean + read^2) g^2 + 1/12)`` DN^2 (g = DN per electron,
    1/12 the rounding, ``kappa = sum w^2 / (sum w)^2``). A test shows that both fidelities give
    the same AOP/DOP statistics.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
from scipy.special import ndtri

from firmware_model.attitude import a2mat
from protocols.psns import PolarizationPoint, PsnsHeader, PsnsStatus, encode_polarization_obs, max_points

from ..links.base import Link
from ..world.sky import SkyModel
from ..world.sun import SunModel
from ..world.trajectory import Trajectory

__all__ = [
    "IMX250MZR_NX",
    "IMX250MZR_NY",
    "IMX250MZR_PIXEL_M",
    "CHANNEL_OFFSETS",
    "CameraConfig",
    "CameraGeometry",
    "PointObservations",
    "PolarizationCameraModel",
    "PolarizationCamera",
    "rotation_vector_matrix",
    "stokes_superpixel",
    "wire_aop_cdeg",
]

DEG = math.pi / 180.0
IMX250MZR_NX = 2448
IMX250MZR_NY = 2048
IMX250MZR_PIXEL_M = 3.45e-6
#: micro-polarizer angle (deg) -> (row, col) offset inside the 2x2 super-pixel (camera conventions, polanalyser layout).
CHANNEL_OFFSETS = {90: (0, 0), 45: (0, 1), 135: (1, 0), 0: (1, 1)}


def _normal_table() -> np.ndarray:
    """65536 standard-normal quantiles at (k + 1/2)/65536, rescaled to unit variance (float32)."""
    z = ndtri((np.arange(65536, dtype=np.float64) + 0.5) / 65536.0)
    return (z / z.std()).astype(np.float32)


_NORMAL_TABLE = _normal_table()


def rotation_vector_matrix(rv: np.ndarray) -> np.ndarray:
    """Rotation matrix of a rotation vector (rad), Rodrigues."""
    rv = np.asarray(rv, dtype=np.float64)
    a = float(np.linalg.norm(rv))
    if a < 1e-15:
        return np.eye(3)
    k = rv / a
    kx = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    return np.eye(3) + math.sin(a) * kx + (1.0 - math.cos(a)) * (kx @ kx)


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
    grid: tuple[int, int] = (15, 15)
    bin_superpixels: int = 8
    fidelity: str = "binned"
    sun_glare: float = 3.0 * DEG
    min_sun_elevation: float = 0.0
    dop_threshold: float = 0.05
    min_points: int = 10
    noise: bool = True

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
        xc = 2.0 * np.arange(nsx) + 1.5  # 1-based pixel coordinate of super-pixel centres
        yc = 2.0 * np.arange(nsy) + 1.5
        X, Y = np.meshgrid(xc, yc)
        vx, vy, vz, valid = self.rays(X, Y)
        self.sp_v = np.stack([vx, vy, vz]).astype(np.float32)
        self.sp_valid = valid
        #: largest angle between a (valid) super-pixel ray and the optical axis, rad
        self.max_field_angle = float(np.arccos(np.clip(np.min(np.where(valid, vz, 1.0)), -1.0, 1.0))) + 2e-3
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
            X0 = cfg.pixel_m * (x_px - (cfg.nx + 1) / 2.0)
            Y0 = cfg.pixel_m * (y_px - (cfg.ny + 1) / 2.0)
            keep &= (np.hypot(X0, Y0) + r_win) / cfg.focal_m <= cfg.fisheye_max_theta
        self.x_px = x_px[keep]
        self.y_px = y_px[keep]
        self.pt_v = np.stack([pvx[keep], pvy[keep], pvz[keep]], axis=1)
        self.win_cols = J0[keep, None] + np.arange(n + 1)[None, :]
        self.win_rows = I0[keep, None] + np.arange(n + 1)[None, :]

    @property
    def n_points(self) -> int:
        return len(self.x_px)

    def rays(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Unit view rays (camera frame) of 1-based pixel coordinates ``x`` (column), ``y`` (row) (conventions)."""
        c = self.cfg
        X = c.pixel_m * (np.asarray(x, dtype=np.float64) - (c.nx + 1) / 2.0)
        Y = c.pixel_m * (np.asarray(y, dtype=np.float64) - (c.ny + 1) / 2.0)
        if c.lens == "pinhole":
            n = np.sqrt(X * X + Y * Y + c.focal_m * c.focal_m)
            return X / n, Y / n, np.full_like(X, c.focal_m) / n, np.ones(X.shape, dtype=bool)
        r = np.hypot(X, Y)
        th = r / c.focal_m
        al = np.arctan2(Y, X)
        st = np.sin(th)
        return st * np.cos(al), st * np.sin(al), np.cos(th), th <= c.fisheye_max_theta


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


class PolarizationCameraModel:
    """Render and process one frame (no link, no clock): see module docstring.

    Parameters
    ----------
    cfg : camera parameters.
    sky, sun, trajectory : the world.
    rng : noise generator.
    """

    def __init__(self, cfg: CameraConfig, sky: SkyModel, sun: SunModel, trajectory: Trajectory,
                 rng: np.random.Generator) -> None:
        if cfg.fidelity not in ("full", "binned"):
            raise ValueError(f"fidelity must be full or binned, got {cfg.fidelity!r}")
        self.cfg = cfg
        self.geo = CameraGeometry(cfg)
        self.sky = sky
        self.sun = sun
        self.traj = trajectory
        self.rng = rng
        self._mosaic: np.ndarray | None = None
        #: injected installation error (emulator.faults): extra rotation about the camera axes, or None
        self.mounting_error: np.ndarray | None = None
        #: frames observed while the injected installation error was applied (fault evidence)
        self.frames_with_mounting_error = 0
        self._att_key: tuple[float, bool, int] | None = None
        self._att: tuple[np.ndarray, np.ndarray, float] | None = None

    # -- injected faults (emulator.faults) ----------------------------------------------------------
    def set_mounting_error(self, rotation_vector_rad: np.ndarray | None) -> None:
        """Shift the mount by a small rotation about the camera axes (``C_c^b R``); None removes it."""
        self.mounting_error = None if rotation_vector_rad is None else rotation_vector_matrix(rotation_vector_rad)

    # -- world -> camera -----------------------------------------------------------------------
    def camera_attitude(self, t: float) -> tuple[np.ndarray, np.ndarray, float]:
        """``C_n^c`` (3x3), the sun vector in the camera frame and the sun's elevation (rad) at ``t``.

        The last result is kept: one frame asks twice (elevation check, then the rendering)."""
        key = (t, self.mounting_error is None, id(self.mounting_error))
        if self._att_key == key and self._att is not None:
            c_nc, s_c, el = self._att
            return c_nc.copy(), s_c.copy(), el
        self._att = self._camera_attitude(t)
        self._att_key = key
        c_nc, s_c, el = self._att
        return c_nc.copy(), s_c.copy(), el

    def _camera_attitude(self, t: float) -> tuple[np.ndarray, np.ndarray, float]:
        st = self.traj.state(t)
        lat, lon, h = float(st.pos[0]), float(st.pos[1]), float(st.pos[2])
        s_n = self.sun.sun_enu(t, lat, lon, h)
        c_cb = self.cfg.mounting_c_b if self.mounting_error is None else self.cfg.mounting_c_b @ self.mounting_error
        c_nc = c_cb.T @ st.c_bn.T
        return c_nc, c_nc @ s_n, math.asin(max(-1.0, min(1.0, float(s_n[2]))))

    # -- full fidelity ---------------------------------------------------------------------------
    def render_mosaic(self, t: float, out: np.ndarray | None = None) -> np.ndarray:
        """The raw 12-bit mosaic (ny, nx) uint16 at scenario time ``t`` (middle of the exposure)."""
        cfg = self.cfg
        c_nc, s_c, _ = self.camera_attitude(t)
        vx, vy, vz = self.geo.sp_v
        f32 = np.float32
        A = f32(cfg.signal_e)
        D = f32(cfg.diattenuation)
        if self.sky.uniform:
            sx, sy, sz = f32(s_c[0]), f32(s_c[1]), f32(s_c[2])
            ex = sy * vz - sz * vy
            ey = sz * vx - sx * vz
            c2 = sx * vx + sy * vy + sz * vz
            c2 *= c2
            # k = A D P sin^2(g) / ((1 + cos^2(g)) (Ex^2 + Ey^2)): Malus amplitude over the projection's norm^2
            r2 = ex * ex + ey * ey
            np.maximum(r2, f32(1e-30), out=r2)
            k = (f32(1.0) - c2) / ((f32(1.0) + c2) * r2)
            k *= A * D * f32(self.sky.p_max)
            radiance: np.ndarray | float = A
        else:
            fld = self.sky.evaluate(t, s_c, vx, vy, vz, c_nc)
            ex, ey = fld.ex, fld.ey
            r2 = ex * ex + ey * ey
            np.maximum(r2, f32(1e-30), out=r2)
            radiance = (A * fld.radiance).astype(f32)
            k = D * fld.dop * radiance / r2
        glare = None
        if math.acos(max(-1.0, min(1.0, float(s_c[2])))) < self.geo.max_field_angle + cfg.sun_glare:
            cs = s_c.astype(np.float32)
            glare = (cs[0] * vx + cs[1] * vy + cs[2] * vz) > f32(math.cos(cfg.sun_glare))
        dq = k * (ex * ex - ey * ey)
        du = f32(2.0) * k * ex * ey
        if not self.geo.sp_valid.all():
            valid = self.geo.sp_valid
            dq = np.where(valid, dq, f32(0.0))
            du = np.where(valid, du, f32(0.0))
            radiance = np.where(valid, radiance, f32(0.0)).astype(f32)
        if out is None:
            out = np.empty((cfg.ny, cfg.nx), dtype=np.uint16)
        g = f32(cfg.gain_dn_per_e)
        r2n = f32(cfg.read_noise_e ** 2)
        dn_max = f32(cfg.dn_max)
        nsy, nsx = cfg.ny // 2, cfg.nx // 2
        for theta, sign, d in ((0, 1.0, dq), (90, -1.0, dq), (45, 1.0, du), (135, -1.0, du)):
            mean = radiance + d if sign > 0 else radiance - d
            if not isinstance(mean, np.ndarray):
                mean = np.full((nsy, nsx), mean, dtype=f32)
            if glare is not None and np.any(glare):
                mean = np.where(glare, f32(4.0 * cfg.full_well_e), mean).astype(f32)
            np.maximum(mean, f32(0.0), out=mean)
            if cfg.noise:
                z = _NORMAL_TABLE[self.rng.bit_generator.random_raw((nsy * nsx + 3) // 4).view(np.uint16)[:nsy * nsx]]
                sig = np.sqrt(mean + r2n)
                sig *= z.reshape(nsy, nsx)
                mean += sig
            mean *= g
            np.rint(mean, out=mean)
            np.clip(mean, f32(0.0), dn_max, out=mean)
            r, c = CHANNEL_OFFSETS[theta]
            out[r::2, c::2] = mean
        self._mosaic = out
        return out

    def process_mosaic(self, mosaic: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """On-camera processing of a raw mosaic into the observation points.

        Returns window-mean channel intensities ``(I0, I45, I90, I135)`` (each (P,) DN, float64)
        and a (P,) bool ``saturated`` (some pixel of the window at full scale).
        """
        g = self.geo
        rows, cols = g.win_rows, g.win_cols
        wr, wc = g.w_row, g.w_col
        norm = wr.sum() * wc.sum()
        dn_max = self.cfg.dn_max
        means = {}
        sat = np.zeros(g.n_points, dtype=bool)
        for theta, (r, c) in CHANNEL_OFFSETS.items():
            ch = mosaic[r::2, c::2]
            blk = ch[rows[:, :, None], cols[:, None, :]]
            sat |= (blk >= dn_max).any(axis=(1, 2))
            means[theta] = np.einsum("pij,i,j->p", blk.astype(np.float64), wr, wc) / norm
        return means[0], means[45], means[90], means[135], sat

    # -- binned fidelity -------------------------------------------------------------------------
    def binned_channels(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Window-mean channels drawn directly (see module docstring); same outputs as :meth:`process_mosaic`."""
        cfg = self.cfg
        c_nc, s_c, _ = self.camera_attitude(t)
        v = self.geo.pt_v
        fld = self.sky.evaluate(t, s_c, v[:, 0], v[:, 1], v[:, 2], c_nc)
        r2 = np.maximum(fld.ex * fld.ex + fld.ey * fld.ey, 1e-30)
        a = cfg.signal_e * fld.radiance
        k = cfg.diattenuation * fld.dop * a / r2
        dq = k * (fld.ex * fld.ex - fld.ey * fld.ey)
        du = 2.0 * k * fld.ex * fld.ey
        g = cfg.gain_dn_per_e
        # the window's angular half-size around the point ray decides glare
        half = (cfg.bin_superpixels + 1) * cfg.pixel_m / cfg.focal_m
        cos_sun = v @ s_c
        glare = cos_sun > math.cos(cfg.sun_glare + half)
        out = []
        sat = glare.copy()
        for d in (a + dq, a + du, a - dq, a - du):  # 0, 45, 90, 135
            d = np.maximum(d, 0.0)
            mean_dn = d * g
            if cfg.noise:
                var = self.geo.kappa * ((d + cfg.read_noise_e ** 2) * g * g + 1.0 / 12.0)
                val = mean_dn + np.sqrt(var) * self.rng.standard_normal(len(d))
            else:
                val = mean_dn
            sat |= d + 3.0 * np.sqrt(d + cfg.read_noise_e ** 2) >= cfg.full_well_e
            out.append(np.clip(val, 0.0, cfg.dn_max))
        return out[0], out[1], out[2], out[3], sat

    # -- both ----------------------------------------------------------------------------------
    def observe(self, t: float, mosaic: np.ndarray | None = None) -> PointObservations:
        """One frame's observation points at scenario time ``t`` (the middle of the exposure).

        ``mosaic`` (a recorded raw frame) replaces the rendering when given.
        """
        cfg = self.cfg
        _, _, sun_el = self.camera_attitude(t)
        if self.mounting_error is not None:
            self.frames_with_mounting_error += 1
        g = self.geo
        empty = np.zeros(0)
        if mosaic is None and sun_el < cfg.min_sun_elevation:
            return PointObservations(empty.astype(int), empty.astype(int), empty, empty, empty,
                                     np.zeros(0, dtype=bool), int(PsnsStatus.SUN_BELOW_HORIZON), sun_el)
        if mosaic is not None:
            i0, i45, i90, i135, sat = self.process_mosaic(mosaic)
        elif cfg.fidelity == "full":
            i0, i45, i90, i135, sat = self.process_mosaic(self.render_mosaic(t))
        else:
            i0, i45, i90, i135, sat = self.binned_channels(t)
        s0 = 0.5 * (i0 + i45 + i90 + i135)
        s1 = i0 - i90
        s2 = i45 - i135
        with np.errstate(invalid="ignore", divide="ignore"):
            dop = np.where(s0 > 0, np.hypot(s1, s2) / s0, 0.0)
        psi = 0.5 * np.arctan2(s2, s1)
        aop = math.pi / 2 - psi  # (-pi/2 .. pi/2] after wrapping
        aop = np.where(aop > math.pi / 2, aop - math.pi, aop)
        status = 0
        if sat.any():
            status |= PsnsStatus.SATURATED
        good = ~sat
        med = np.median(s0[good]) if good.any() else 0.0
        if med > 0 and np.any(good & ((s0 < 0.7 * med) | (s0 > 1.3 * med))):
            status |= PsnsStatus.OCCLUDED
        if int(np.count_nonzero(good & (dop >= cfg.dop_threshold))) < cfg.min_points:
            status |= PsnsStatus.LOW_DOP
        else:
            status |= PsnsStatus.VALID
        if sun_el < cfg.min_sun_elevation:
            status = (status & ~PsnsStatus.VALID) | PsnsStatus.SUN_BELOW_HORIZON
        return PointObservations(g.x_px[good], g.y_px[good], aop[good], dop[good], s0[good], sat, int(status), sun_el)


class PolarizationCamera:
    """The camera as a device: captures at ``rate_hz`` and sends POLARIZATION_OBS frames on its link.

    Parameters
    ----------
    link : the PSNS port (RS232) towards the FPGA.
    model : the rendering/processing model.
    rate_hz : frame rate.
    exposure_s : exposure time (the frame's ``exposure_us``).
    processing_s : end of exposure to the frame being handed to the UART.
    phase_s : time of the first exposure start.
    mosaic_source : for recorded data: ``f(t_mid) -> mosaic | None`` replaces the rendering.
    """

    def __init__(self, link: Link, model: PolarizationCameraModel, rate_hz: float = 5.0, exposure_s: float = 1e-3,
                 processing_s: float = 0.02, phase_s: float = 0.0,
                 mosaic_source: Callable[[float], np.ndarray | None] | None = None) -> None:
        self.link = link
        self.model = model
        self.rate_hz = rate_hz
        self.exposure_s = exposure_s
        self.processing_s = processing_s
        self.phase_s = phase_s
        self.mosaic_source = mosaic_source
        budget = max_points(link.line.baud, rate_hz, int(round(link.line.bits_per_byte)))
        if model.geo.n_points > budget:
            raise ValueError(f"{model.geo.n_points} observation points do not fit the PSNS line: "
                             f"{link.line.baud} baud at {rate_hz:g} frames/s carries at most {budget} "
                             f"(protocols.psns.max_points); use a smaller grid or a lower rate")
        self.seq = 0
        self.frames_sent = 0
        self.last: PointObservations | None = None
        self._k = 0
        #: injected fault: the lens is covered (frames without points); frames sent so (fault evidence)
        self.blocked = False
        self.frames_blocked = 0

    def set_blocked(self, blocked: bool) -> None:
        """Cover or uncover the lens (emulator.faults): a covered camera sends frames with no points,
        status OCCLUDED | LOW_DOP."""
        self.blocked = blocked

    def start(self) -> None:
        self._schedule()

    def _schedule(self) -> None:
        t0 = self.phase_s + self._k / self.rate_hz
        self.link.loop.call_at(t0 + self.exposure_s + self.processing_s, self._capture, t0)

    def _capture(self, t_start: float) -> None:
        self._k += 1
        self._schedule()
        t_mid = t_start + 0.5 * self.exposure_s
        mosaic = None
        if self.mosaic_source is not None:
            mosaic = self.mosaic_source(t_mid)
            if mosaic is None:  # no recorded frame for this capture
                return
        obs = self.model.observe(t_mid, mosaic)
        if self.blocked:
            e = np.zeros(0)
            obs = PointObservations(e.astype(int), e.astype(int), e, e, e, np.zeros(0, dtype=bool),
                                    int(PsnsStatus.OCCLUDED | PsnsStatus.LOW_DOP), obs.sun_elevation)
            self.frames_blocked += 1
        self.last = obs
        self.link.send(self.encode(obs, t_mid))
        self.frames_sent += 1
        self.seq = (self.seq + 1) & 0xFFFF

    def encode(self, obs: PointObservations, t_mid: float) -> bytes:
        """The POLARIZATION_OBS frame of ``obs`` with its latency from ``t_mid`` to the first start bit."""
        now = self.link.loop.time()
        t_first_bit = max(now, self.link.busy_until())
        latency_us = int(round((t_first_bit - t_mid) * 1e6))
        aop = wire_aop_cdeg(obs.aop)
        dop = np.clip(np.round(obs.dop * 65535.0), 0, 65535).astype(np.int64)
        s0 = np.clip(np.round(obs.s0_dn), 0, 65535).astype(np.int64)
        pts = [PolarizationPoint(x, y, a, d, i)  # plain ints (tolist), as int() of each element gave
               for x, y, a, d, i in zip(np.asarray(obs.x_px).astype(np.int64).tolist(),
                                        np.asarray(obs.y_px).astype(np.int64).tolist(),
                                        aop.tolist(), dop.tolist(), s0.tolist())]
        hdr = PsnsHeader(self.seq, int(round(self.exposure_s * 1e6)), latency_us, obs.status, len(pts))
        return encode_polarization_obs(hdr, pts)


def mounting_matrix(heading_deg: float = 0.0, pitch_deg: float = 0.0, roll_deg: float = 0.0,
                    installation_error_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> np.ndarray:
    """``C_c^b``: a nominal mount (Euler angles, the body-attitude convention) times a small installation
    error (rotation vector about the camera axes, deg)."""
    from firmware_model.attitude import yaw_from_heading

    nominal = a2mat(pitch_deg * DEG, roll_deg * DEG, yaw_from_heading(heading_deg * DEG))
    return nominal @ rotation_vector_matrix(np.asarray(installation_error_deg, dtype=np.float64) * DEG)
