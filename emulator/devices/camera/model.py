"""The camera model: render one frame of the sky (full mosaic or binned windows) and process it as the camera
does, without link or clock (see :mod:`emulator.devices.camera`)."""

from __future__ import annotations

import math

import numpy as np
from scipy.special import ndtri

from protocols.psns import PsnsStatus

from ...world.sky import SkyModel
from ...world.sun import SunModel
from ...world.trajectory import Trajectory, TruthState
from .geometry import CHANNEL_OFFSETS, CameraConfig, CameraGeometry, PointObservations, rotation_vector_matrix
from .optics import SensorDefects, defect_maps, radial_diattenuation, sensor_plane_field

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
        #: auto exposure: the electrons per unit radiance the last frame's metering asked for (None: not metered yet)
        self._ae_signal_e: float | None = None
        #: this frame's exposure over the configured one (1.0 without auto exposure); the frame header reports it
        self.exposure_scale = 1.0
        self._att_key: tuple[float, bool, int] | None = None
        #: truth at instants the device will observe (:meth:`truth_ahead`), taken by :meth:`_camera_attitude`
        self._truth: dict[float, TruthState] = {}
        self._att: tuple[np.ndarray, np.ndarray, float] | None = None
        # the sensor's fixed pattern: per-super-pixel maps (full) and their window means (binned), one draw per
        # physical sensor (defect_seed), the same in both fidelities
        d = cfg.defects
        self._maps: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] | None = None
        self._trig: dict[tuple[int, str], dict[int, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]] = {}
        self._pt_maps: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] | None = None
        if d != SensorDefects() and (d.orientation_sigma_deg or d.extinction_spread or d.prnu
                                     or any(d.orientation_bias_deg)):
            g = self.geo
            win = (g.win_rows[:, :, None], g.win_cols[:, None, :])
            shape = (cfg.ny // 2, cfg.nx // 2)
            if cfg.fidelity == "full":
                self._maps = defect_maps(d, cfg.extinction_ratio, shape, np.random.default_rng(cfg.defect_seed))
                win_maps = {th: tuple(m[win] for m in ms) for th, ms in self._maps.items()}
            else:  # the same draw, evaluated at the windows only
                win_maps = defect_maps(d, cfg.extinction_ratio, shape, np.random.default_rng(cfg.defect_seed), at=win)
            norm = g.w_row.sum() * g.w_col.sum()
            self._pt_maps = {th: tuple(
                np.einsum("pij,i,j->p", m.astype(np.float64), g.w_row, g.w_col) / norm for m in ms)
                for th, ms in win_maps.items()}

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

    def truth_ahead(self, ts: list[float]) -> None:
        """Evaluate the truth at the instants ``ts`` (s) that frames will be observed at, in one vectorised
        trajectory call (``Trajectory.states``: bit for bit :meth:`Trajectory.state` at each instant), instead of
        one ~0.1 ms evaluation per frame. Replaces what was kept; an instant asked for that is not here is
        evaluated on its own."""
        self._truth = dict(zip(ts, self.traj.states(ts)))

    def has_truth(self, t: float) -> bool:
        """True when the truth at ``t`` is kept (:meth:`truth_ahead`)."""
        return t in self._truth

    def _camera_attitude(self, t: float) -> tuple[np.ndarray, np.ndarray, float]:
        st = self._truth.pop(t, None)
        if st is None:
            st = self.traj.state(t)
        lat, lon, h = float(st.pos[0]), float(st.pos[1]), float(st.pos[2])
        s_n = self.sun.sun_enu(t, lat, lon, h)
        c_cb = self.cfg.mounting_c_b if self.mounting_error is None else self.cfg.mounting_c_b @ self.mounting_error
        c_nc = c_cb.T @ st.c_bn.T
        return c_nc, c_nc @ s_n, math.asin(max(-1.0, min(1.0, float(s_n[2]))))

    def _point_glare(self, s_c: np.ndarray) -> np.ndarray:
        """(P,) bool: the observation points whose window reaches into the sun's glare disc (``s_c`` the sun in the
        camera frame): the window's angular half-size around the point ray widens the glare radius."""
        cfg = self.cfg
        half = (cfg.bin_superpixels + 1) * cfg.pixel_m / cfg.focal_m
        return np.asarray(self.geo.pt_v @ s_c > math.cos(cfg.sun_glare + half))

    # -- exposure ------------------------------------------------------------------------------
    def _frame_signal_e(self, radiance: np.ndarray, dop: np.ndarray, metered: np.ndarray | None) -> float:
        """Electrons per unit radiance of this frame (``signal_e`` behind an ideal polarizer, module docstring).

        Without auto exposure, ``cfg.signal_e``. With it (``cfg.auto_exposure_target``), a machine-vision camera's
        loop: this frame is exposed as the last frame's metering asked (the first frame meters itself), and this
        frame's sky at the observation points (``radiance``, ``dop``; ``metered`` the points that count: not in the
        sun's glare, inside the image circle) sets the next exposure so that the ``auto_exposure_percentile`` of the
        brightest channel, ``radiance (1 + D dop)`` per unit signal (D the diattenuation), reaches
        ``auto_exposure_target`` of the full well."""
        cfg = self.cfg
        if cfg.auto_exposure_target is None:
            return cfg.signal_e
        pick = np.isfinite(radiance) & (radiance > 0)
        if metered is not None:
            pick &= metered
        use = self._ae_signal_e
        if pick.any():
            peak = float(np.percentile(radiance[pick] * (1.0 + cfg.diattenuation * dop[pick]),
                                       cfg.auto_exposure_percentile))
            if peak > 0.0:
                self._ae_signal_e = cfg.auto_exposure_target * cfg.full_well_e / peak
        if use is None:
            use = self._ae_signal_e if self._ae_signal_e is not None else cfg.signal_e
        self.exposure_scale = use / cfg.signal_e
        return use

    # -- full fidelity ---------------------------------------------------------------------------
    def render_mosaic(self, t: float, out: np.ndarray | None = None) -> np.ndarray:
        """The raw 12-bit mosaic (ny, nx) uint16 at scenario time ``t`` (middle of the exposure)."""
        cfg = self.cfg
        c_nc, s_c, _ = self.camera_attitude(t)
        vx, vy, vz = self.geo.sp_v
        f32 = np.float32
        fld = self.sky.evaluate(t, s_c, vx, vy, vz, c_nc)
        ex, ey = sensor_plane_field(vx, vy, vz, fld.ex, fld.ey, fld.ez, self.geo.sp_cos_cra)
        signal_e = cfg.signal_e
        if cfg.auto_exposure_target is not None:  # metered at the observation points, as in the binned fidelity
            v = self.geo.pt_v
            pf = self.sky.evaluate(t, s_c, v[:, 0], v[:, 1], v[:, 2], c_nc)
            signal_e = self._frame_signal_e(pf.radiance, pf.dop, ~self._point_glare(s_c))
        radiance = (f32(signal_e) * fld.radiance).astype(f32)
        means = self._channel_means(radiance, fld.dop.astype(f32), ex, ey, self.geo.sp_cos_cra, self._maps,
                                    self.geo.sp_lens_dia)
        glare = None
        if math.acos(max(-1.0, min(1.0, float(s_c[2])))) < self.geo.max_field_angle + cfg.sun_glare:
            cs = s_c.astype(np.float32)
            glare = (cs[0] * vx + cs[1] * vy + cs[2] * vz) > f32(math.cos(cfg.sun_glare))
        if not self.geo.sp_valid.all():
            valid = self.geo.sp_valid
            means = {th: np.where(valid, m, f32(0.0)).astype(f32) for th, m in means.items()}
        if out is None:
            out = np.empty((cfg.ny, cfg.nx), dtype=np.uint16)
        g = f32(cfg.gain_dn_per_e)
        r2n = f32(cfg.read_noise_e ** 2)
        dn_max = f32(cfg.dn_max)
        nsy, nsx = cfg.ny // 2, cfg.nx // 2
        for theta in (0, 90, 45, 135):
            mean = np.broadcast_to(means[theta], (nsy, nsx)).astype(f32)
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

    def _channel_means(self, radiance: np.ndarray, dop: np.ndarray, ex: np.ndarray, ey: np.ndarray,
                       cos_cra: np.ndarray, maps: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]] | None,
                       lens_dia: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> dict[int, np.ndarray]:
        """Mean electrons of the four channels: the lens's radial diattenuation (``lens_dia``, if any), Malus
        through a polarizer at ``theta + delta`` with diattenuation D, PRNU gain, cos^4 vignetting of the chief-ray
        angle, dark signal, then the crosstalk of the four edge neighbours (docs/sensors.md, "Polarization
        camera")."""
        cfg = self.cfg
        dfx = cfg.defects
        dt = ex.dtype
        r2 = np.maximum(ex * ex + ey * ey, dt.type(1e-30))
        pr = dop * radiance / r2
        c2 = pr * (ex * ex - ey * ey)
        s2 = pr * dt.type(2.0) * ex * ey
        if lens_dia is not None:
            radiance, c2, s2 = radial_diattenuation(radiance, c2, s2, *lens_dia)
        if dfx.vignetting:
            c4 = cos_cra * cos_cra
            c4 = (c4 * c4).astype(dt, copy=False)
            radiance, c2, s2 = radiance * c4, c2 * c4, s2 * c4
        out = {}
        for i, theta in enumerate((0, 45, 90, 135)):
            if maps is None:
                ang = math.radians(theta + dfx.orientation_bias_deg[i])
                dia: np.ndarray | float = cfg.diattenuation
                gain: np.ndarray | float = 1.0
                ca: np.ndarray | float = math.cos(2 * ang)
                sa: np.ndarray | float = math.sin(2 * ang)
            else:
                ca, sa, dia, gain = self._polarizer_terms(maps, dt)[theta]
            m = radiance + dia * (c2 * ca + s2 * sa)
            if maps is not None or dfx.prnu:
                m = m * gain
            out[theta] = (m + dt.type(dfx.dark_e)).astype(dt, copy=False)
        c = dfx.crosstalk
        if c:
            k0, k1 = dt.type(1.0 - 4.0 * c), dt.type(2.0 * c)
            a, b = out[45] + out[135], out[0] + out[90]
            out = {0: k0 * out[0] + k1 * a, 90: k0 * out[90] + k1 * a, 45: k0 * out[45] + k1 * b,
                   135: k0 * out[135] + k1 * b}
        return out

    def _polarizer_terms(self, maps: dict[int, tuple[np.ndarray, np.ndarray, np.ndarray]], dt: np.dtype
                         ) -> dict[int, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]]:
        """Per channel ``(cos 2(theta + delta), sin 2(theta + delta), D, gain)`` of the fixed-pattern ``maps`` in
        ``dt``: they depend on the sensor only, so they are computed once per maps and dtype, not per frame."""
        key = (id(maps), dt.str)
        terms = self._trig.get(key)
        if terms is None:
            terms = {}
            for theta, (delta, dia, gain) in maps.items():
                ang2 = 2.0 * (math.radians(theta) + delta)
                terms[theta] = (np.cos(ang2).astype(dt), np.sin(ang2).astype(dt), dia, gain)
            self._trig[key] = terms
        return terms

    # -- binned fidelity -------------------------------------------------------------------------
    def binned_channels(self, t: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Window-mean channels drawn directly (see module docstring); same outputs as :meth:`process_mosaic`."""
        cfg = self.cfg
        c_nc, s_c, _ = self.camera_attitude(t)
        v = self.geo.pt_v
        fld = self.sky.evaluate(t, s_c, v[:, 0], v[:, 1], v[:, 2], c_nc)
        ex, ey = sensor_plane_field(v[:, 0], v[:, 1], v[:, 2], fld.ex, fld.ey, fld.ez, self.geo.pt_cos_cra)
        glare = self._point_glare(s_c)
        signal_e = self._frame_signal_e(fld.radiance, fld.dop, ~glare)
        means = self._channel_means(signal_e * fld.radiance, fld.dop, ex, ey, self.geo.pt_cos_cra, self._pt_maps,
                                    self.geo.pt_lens_dia)
        g = cfg.gain_dn_per_e
        out = []
        sat = glare.copy()
        for theta in (0, 45, 90, 135):
            d = np.maximum(means[theta], 0.0)
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
