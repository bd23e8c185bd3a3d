"""The camera model: render one frame of the sky (full mosaic or binned windows) and process it as the camera
does, without link or clock (see :mod:`emulator.devices.camera`)."""

from __future__ import annotations

import math

import numpy as np
from scipy.special import ndtri

from protocols.psns import PsnsStatus

from ...world.sky import SkyModel
from ...world.sun import SunModel
from ...world.trajectory import Trajectory
from .geometry import CHANNEL_OFFSETS, CameraConfig, CameraGeometry, PointObservations, rotation_vector_matrix

__all__ = ["PolarizationCameraModel"]


def _normal_table() -> np.ndarray:
    """65536 standard-normal quantiles at (k + 1/2)/65536, rescaled to unit variance (float32)."""
    z = ndtri((np.arange(65536, dtype=np.float64) + 0.5) / 65536.0)
    return (z / z.std()).astype(np.float32)


_NORMAL_TABLE = _normal_table()


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
            radiance: np.ndarray | np.float32 = A
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
