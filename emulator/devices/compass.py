"""Multi-unit polarization compass (9 single-direction units) on the PSNS port (COMPASS frames).

Each unit u is a single-direction polarization analyser (docs/architecture.md, "Conventions"): its view ray is its own
+z axis, its AOP is measured in its x-y plane from +y towards +x, and ``C_u^b`` (columns: the
unit's x, y, z axes in body coordinates) is its mounting matrix. The default geometry (unit 0 at
the zenith, 8 units on a ring at zenith angle 45 deg every 45 deg of azimuth from body +y towards
+x, each ring unit's +y axis up the hemisphere) is the world's own declaration of the installed
compass (:func:`default_mountings`, built here with :func:`unit_mounting`). The firmware keeps its own nominal
copy of the layout (and, with a calibration, an estimate of it); a test compares the two, and a per-unit
installation error (``installation_error_sigma_deg``) makes the installed geometry differ from the nominal one,
as it does on real hardware (docs/sensors.md).

Measurement model: a unit sees the sky polarization along its ray (``emulator.world.sky``),
analyses it with four polarizers (0/45/90/135 deg, extinction ratio ``ER``) and reports Stokes ->
DOP/AOP exactly as the camera does. The channel noise (relative to S0) is set from the
accuracy figure: ``aop_sigma`` (1 sigma) at ``dop_ref``, so ``sigma_I = sqrt(2) S0 DOP_ref
sigma_AOP``, and the AOP error grows as ``sigma_I/(sqrt(2) S0 DOP)`` when the DOP falls
(docs/reference/algorithms.md 2.3). The sun inside a unit's field of view (``fov_half``) saturates it (the unit
is left out of the frame and SATURATED is set); a sun below ``min_sun_elevation`` gives frames
with no units and SUN_BELOW_HORIZON.

``dop_noise_model: zhang`` (the ``field`` preset) replaces the 1/DOP law for the AOP by the one Zhang et al.
(2021) measured outdoors: per DOP bin a mean error and a spread that grow ~14x from DOP 0.525 to 0.275
(:func:`zhang_aop_error_deg`); each unit keeps its own sign of the mean (a systematic error), the spread is
drawn per reading.

Units and mountings are configurable (``sensors.compass.units``: view directions as zenith/azimuth,
:func:`unit_mounting`), e.g. the three sensors of the dual-vector
switching study. **Blocked units** (``sensors.compass.blocked``, or :meth:`CompassModel.block_units` for
a fault injector): while a unit is blocked it sees unpolarized light (an obstruction, a thick cloud in its
narrow field of view): its DOP is that of the channel noise (~0) and its AOP is scrambled (uniform); the
unit stays in the frame, as a real sensor would keep reporting.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from protocols.constants import DEG
from protocols.psns import CompassUnit, PsnsHeader, PsnsStatus, encode_compass

from ..links.base import Link
from ..world.sky import SkyModel
from ..world.sun import SunModel
from ..world.trajectory import Trajectory
from .camera import rotation_vector_matrix, wire_aop_cdeg

__all__ = ["CompassConfig", "CompassModel", "CompassReading", "PolarizationCompass", "default_mountings",
           "mountings_from_directions", "turned_about_view_rays", "unit_mounting"]

N_UNITS = 9
RING_ZENITH = 45.0 * DEG


def unit_mounting(zenith: float, azimuth: float) -> np.ndarray:
    """``C_u^b`` (3, 3) of a single-direction unit whose view ray has ``zenith`` / ``azimuth`` (rad) in the body frame.

    Azimuth in the body x-y plane from body +y (forward) towards +x (right), zenith angle from body +z. The unit's
    +z is its view ray, its +y points up the hemisphere (towards body +z in the ray's vertical plane) and
    ``x = y x z``; a unit at the zenith is the identity turned by ``azimuth`` about z. Columns: the unit's axes in
    body coordinates (docs/architecture.md, "Conventions", contract C1).
    """
    if zenith < 1e-9:
        c, s = math.cos(azimuth), math.sin(azimuth)
        return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])
    st, ct = math.sin(zenith), math.cos(zenith)
    sa, ca = math.sin(azimuth), math.cos(azimuth)
    z = np.array([st * sa, st * ca, ct])
    y = np.array([-ct * sa, -ct * ca, st])
    return np.column_stack([np.cross(y, z), y, z])


def mountings_from_directions(directions_deg: list[tuple[float, float]] | tuple[tuple[float, float], ...]
                              ) -> np.ndarray:
    """Mountings (n, 3, 3) of units given as ``(zenith_deg, azimuth_deg)`` pairs (:func:`unit_mounting`)."""
    return np.stack([unit_mounting(z * DEG, a * DEG) for z, a in directions_deg])


def _own_mountings() -> np.ndarray:
    return mountings_from_directions([(0.0, 0.0)] + [(RING_ZENITH / DEG, 360.0 * k / (N_UNITS - 1))
                                                     for k in range(N_UNITS - 1)])


def default_mountings() -> np.ndarray:
    """``C_u^b`` of the 9 installed units, (9, 3, 3): the world's own declaration (module docstring)."""
    return _own_mountings()


@dataclass
class CompassConfig:
    """Compass parameters (rad, s)."""

    mountings: np.ndarray = field(default_factory=default_mountings)
    aop_sigma: float = 0.1 * DEG
    dop_ref: float = 0.5
    extinction_ratio: float = 300.0
    fov_half: float = 5.0 * DEG
    min_sun_elevation: float = 0.0
    dop_threshold: float = 0.05
    noise: bool = True
    #: AOP error law: ``inverse`` (channel noise, sigma ~ 1/DOP) or ``zhang`` (:func:`zhang_aop_error_deg`)
    dop_noise_model: str = "inverse"
    #: blocked windows: (units, start_s, end_s)
    blocked: tuple[tuple[tuple[int, ...], float, float], ...] = ()

    @property
    def channel_sigma(self) -> float:
        """Per-channel noise relative to S0."""
        return math.sqrt(2.0) * self.dop_ref * self.aop_sigma


@dataclass
class CompassReading:
    """One reading: per reported unit its index, wire AOP (rad) and measured DOP; the status bits."""

    units: np.ndarray
    aop: np.ndarray
    dop: np.ndarray
    status: int


#: Zhang et al. 2021 (sun-elevation positioning paper, docs/reference/sources.md), Fig. 16b: E-vector error
#: statistics of their 9-unit compass under a clear sky, per DOP bin: (bin centre, mean deg, standard deviation deg).
ZHANG_BINS = ((0.275, 2.05, 2.38), (0.525, 0.14, 0.17))


def zhang_aop_error_deg(dop: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Mean and standard deviation (deg) of a unit's E-vector error at ``dop``: log-linear in DOP through Zhang et
    al.'s two measured bins (14.6x from DOP 0.525 to 0.275, 14.0x for the spread), DOP clipped to [0.05, 0.75]."""
    (d1, m1, s1), (d2, m2, s2) = ZHANG_BINS
    x = (np.clip(dop, 0.05, 0.75) - d1) / (d2 - d1)
    return m1 * (m2 / m1) ** x, s1 * (s2 / s1) ** x


class CompassModel:
    """The measurement of all units at one instant (see module docstring)."""

    #: injected mounting shift (emulator.faults, :meth:`set_mounting_error`): a rotation matrix, or None
    mounting_error: np.ndarray | None = None
    #: fault evidence: unit readings taken while blocked; readings taken with the mounting shift
    blocked_readings = 0
    readings_with_mounting_error = 0

    def __init__(self, cfg: CompassConfig, sky: SkyModel, sun: SunModel, trajectory: Trajectory,
                 rng: np.random.Generator) -> None:
        self.cfg = cfg
        self.sky = sky
        self.sun = sun
        self.traj = trajectory
        self.rng = rng
        m = np.asarray(cfg.mountings, dtype=np.float64)
        self.mountings = m
        self.rays_b = m[:, :, 2].copy()  # (U, 3) view rays, body frame
        self.blocked: list[tuple[tuple[int, ...], float, float]] = []
        #: zhang law: each unit's systematic E-vector error has its own sign (drawn once)
        self.error_sign = rng.choice([-1.0, 1.0], len(m)) if cfg.dop_noise_model == "zhang" else np.ones(len(m))
        for units, start, end in cfg.blocked:
            self.block_units(units, start, end)

    def block_units(self, units: tuple[int, ...] | list[int], start_s: float, end_s: float) -> None:
        """Block ``units`` from ``start_s`` to ``end_s`` (scenario time): unpolarized light, scrambled AOP."""
        n = len(self.mountings)
        bad = [u for u in units if not 0 <= int(u) < n]
        if bad:
            raise ValueError(f"compass has units 0..{n - 1}; cannot block {bad}")
        if not end_s > start_s:
            raise ValueError(f"a blocked window needs end > start, got {start_s}..{end_s}")
        self.blocked.append((tuple(int(u) for u in units), float(start_s), float(end_s)))

    def blocked_units(self, t: float) -> list[int]:
        """Units blocked at ``t``."""
        out: set[int] = set()
        for units, start, end in self.blocked:
            if start <= t < end:
                out.update(units)
        return sorted(out)

    def read(self, t: float) -> CompassReading:
        cfg = self.cfg
        st = self.traj.state(t)
        s_n = self.sun.sun_enu(t, float(st.pos[0]), float(st.pos[1]), float(st.pos[2]))
        sun_el = math.asin(max(-1.0, min(1.0, float(s_n[2]))))
        n_u = len(self.mountings)
        if sun_el < cfg.min_sun_elevation:
            return CompassReading(np.zeros(0, int), np.zeros(0), np.zeros(0), int(PsnsStatus.SUN_BELOW_HORIZON))
        c_nb = st.c_bn.T
        s_b = c_nb @ s_n
        v = self.rays_b
        fld = self.sky.evaluate(t, s_b, v[:, 0], v[:, 1], v[:, 2], c_nb)
        e_b = np.stack([fld.ex, fld.ey, fld.ez], axis=1)
        e_u = np.einsum("uji,uj->ui", self.mountings, e_b)  # C_b^u E^b
        psi = np.arctan2(e_u[:, 1], e_u[:, 0])
        d = (cfg.extinction_ratio - 1.0) / (cfg.extinction_ratio + 1.0)
        sky_dop = fld.dop
        blocked = self.blocked_units(t) if self.blocked else []
        if blocked:  # unpolarized light on the blocked units
            sky_dop = np.array(sky_dop, dtype=np.float64, copy=True)
            sky_dop[blocked] = 0.0
        q = d * sky_dop * np.cos(2 * psi)
        u = d * sky_dop * np.sin(2 * psi)
        i0, i90, i45, i135 = 0.5 * (1 + q), 0.5 * (1 - q), 0.5 * (1 + u), 0.5 * (1 - u)
        if cfg.noise:
            z = self.rng.standard_normal((4, n_u)) * cfg.channel_sigma
            i0, i45, i90, i135 = i0 + z[0], i45 + z[1], i90 + z[2], i135 + z[3]
        s0 = 0.5 * (i0 + i45 + i90 + i135)
        s1, s2 = i0 - i90, i45 - i135
        dop = np.hypot(s1, s2) / s0
        aop = math.pi / 2 - 0.5 * np.arctan2(s2, s1)
        if cfg.noise and cfg.dop_noise_model == "zhang":
            # the measured law replaces the 1/DOP growth of the channel noise: systematic part plus spread
            aop0 = math.pi / 2 - 0.5 * np.arctan2(u, q)
            mean, sd = zhang_aop_error_deg(np.asarray(sky_dop, dtype=np.float64))
            aop = aop0 + (self.error_sign * mean + sd * self.rng.standard_normal(n_u)) * DEG
            aop = np.mod(aop + math.pi / 2, math.pi) - math.pi / 2
            aop = np.where(aop <= -math.pi / 2, aop + math.pi, aop)
        aop = np.where(aop > math.pi / 2, aop - math.pi, aop)
        if blocked:  # scrambled AOP (also without channel noise)
            aop[blocked] = self.rng.uniform(-0.5 * math.pi, 0.5 * math.pi, len(blocked))
        sat = (v @ s_b) > math.cos(cfg.fov_half)
        status = int(PsnsStatus.SATURATED) if sat.any() else 0
        keep = ~sat
        if blocked:
            self.blocked_readings += len(blocked)
        if self.mounting_error is not None:
            self.readings_with_mounting_error += 1
        if np.count_nonzero(keep & (dop >= cfg.dop_threshold)) >= 2:
            status |= PsnsStatus.VALID
        else:
            status |= PsnsStatus.LOW_DOP
        idx = np.nonzero(keep)[0]
        return CompassReading(idx, aop[idx], dop[idx], status)

    def set_mounting_error(self, rotation_vector_rad: np.ndarray | None) -> None:
        """Rotate the whole compass block by a small rotation about the body axes (``R C_u^b``, an injected
        installation error); None removes it."""
        nominal = self.__dict__.setdefault("_nominal_mountings", self.mountings)
        if rotation_vector_rad is None:
            self.mounting_error = None
            self.mountings = nominal
        else:
            self.mounting_error = rotation_vector_matrix(rotation_vector_rad)
            self.mountings = np.einsum("ij,ujk->uik", self.mounting_error, nominal)
        self.rays_b = self.mountings[:, :, 2].copy()


class PolarizationCompass:
    """The compass as a device: COMPASS frames at ``rate_hz`` on the PSNS link (latency tag as in the conventions)."""

    def __init__(self, link: Link, model: CompassModel, rate_hz: float = 5.0, integration_s: float = 0.01,
                 processing_s: float = 0.005, phase_s: float = 0.0) -> None:
        self.link = link
        self.model = model
        self.rate_hz = rate_hz
        self.integration_s = integration_s
        self.processing_s = processing_s
        self.phase_s = phase_s
        self.seq = 0
        self.frames_sent = 0
        self.last: CompassReading | None = None
        self._k = 0

    def start(self) -> None:
        self._schedule()

    def _schedule(self) -> None:
        t0 = self.phase_s + self._k / self.rate_hz
        self.link.loop.call_at(t0 + self.integration_s + self.processing_s, self._measure, t0)

    def _measure(self, t_start: float) -> None:
        self._k += 1
        self._schedule()
        t_mid = t_start + 0.5 * self.integration_s
        r = self.model.read(t_mid)
        self.last = r
        now = self.link.loop.time()
        latency_us = round((max(now, self.link.busy_until()) - t_mid) * 1e6)
        aop = wire_aop_cdeg(r.aop)
        dop = np.clip(np.round(r.dop * 65535.0), 0, 65535).astype(np.int64)
        units = [CompassUnit(int(u), int(a), int(d)) for u, a, d in zip(r.units, aop, dop)]
        hdr = PsnsHeader(self.seq, round(self.integration_s * 1e6), latency_us, r.status, len(units))
        self.link.send(encode_compass(hdr, units))
        self.frames_sent += 1
        self.seq = (self.seq + 1) & 0xFFFF


def turned_about_view_rays(base: np.ndarray, offsets: np.ndarray) -> np.ndarray:
    """Mountings whose units are turned about their own view ray (+z) by ``offsets`` (rad, one per unit).

    ``C_u^b' = C_u^b R_z(delta)``: a fixed E-vector then reads ``A + delta`` (AOP from +y towards +x), the constant
    E-vector error a calibration leaves per unit (Zhang et al. 2021, Table 2).
    """
    out = []
    for m, d in zip(base, offsets, strict=True):
        c, s = math.cos(float(d)), math.sin(float(d))
        out.append(m @ np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]))
    return np.stack(out)


def perturbed_mountings(base: np.ndarray, sigma: float, rng: np.random.Generator) -> np.ndarray:
    """Mountings with a random installation error (rotation vector, ``sigma`` rad per axis) per unit."""
    return np.stack([m @ rotation_vector_matrix(rng.standard_normal(3) * sigma) for m in base])
