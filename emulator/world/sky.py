"""Skylight polarization: a realistic turbid sky, Rayleigh single scattering, Berry's neutral-point model, clouds
and occluders.

Rayleigh (``docs/reference/algorithms.md`` section 2.1): for the unit sun vector ``S`` and
view ray ``V`` with scattering angle ``gamma`` (``cos gamma = S . V``)::

    DOP = P_max sin^2(gamma) / (1 + cos^2(gamma)),     E  ∝  S x V  (perpendicular to S and V)

Berry, Dennis & Lee (2004, "Polarization singularities in the clear sky", New J. Phys. 6:162):
on the stereographic plane ``zeta = (V_E + i V_N)/(1 + V_U)`` the sky is described by::

    w(zeta) = -4 (zeta - zB)(zeta - zb)(zeta + 1/conj(zB))(zeta + 1/conj(zb))
              / ((1 + |zeta|^2)^2 |zB + 1/conj(zB)| |zb + 1/conj(zb)|)

with the Brewster and Babinet neutral points ``zB``, ``zb`` on the sun's vertical at ``delta``
(half the ``neutral_point_sep_deg``) below and above the sun, and their antipodes (Arago and the
fourth point). ``DOP = P_max |w|/(2 - |w|)`` and the E-vector makes the angle
``arg(w exp(-2 i phi_sun))/2`` with the real axis of the zeta plane (``phi_sun = arg(zeta_sun)``) (the
projection is conformal, so that direction is carried back to the sphere by the projection's Jacobian).
With ``delta = 0`` it is exactly Rayleigh (a test checks this).

The **realistic** sky (``model: realistic``, the scenario default; docs/sensors.md "Sky") keeps Berry's
polarization pattern (four neutral points; their distance ``delta`` from the sun and the antisun, 20 deg by
default, the typical clear-sky distances of the Babinet, Brewster and Arago points, Horvath et al. 2002) and adds
the aerosol of a turbid atmosphere as a second, unpolarized single scatterer. With Preetham's turbidity
``T = (tau_m + tau_a) / tau_m`` (Preetham, Shirley & Smits 1999) the aerosol-to-molecule radiance ratio at
scattering angle ``gamma`` is ``(T - 1) p_HG(gamma; g) / p_R(gamma)`` (Henyey-Greenstein phase function, asymmetry
``g`` 0.7 for continental aerosol; Rayleigh phase ``3/(16 pi) (1 + cos^2 gamma)``), so::

    DOP = P_mol * berry(V) * L_R / (L_R + L_A)          P_mol = 0.94 (depolarization factor of air 0.0279)

which gives a maximum DOP of ~0.68 at T = 2, ~0.55 at T = 3, ~0.38 at T = 5 (the DOP falls with haze), and a
bright, nearly unpolarized aureole round the sun (glare: the radiance rises steeply within ~10 deg and the DOP
goes to ~0 there). The radiance is ``(p_R + (T - 1) p_HG)`` times the CIE standard clear-sky gradation
``phi(Z) = 1 + a exp(b / cos Z)`` (a = -1, b = -0.32; CIE S 011/E:2003, sky type 12), normalised to 1 at 90 deg
from the sun at the zenith. A sun at the zenith is handled (the Babinet point goes through the zenith).

**QUEEN placement** (``model: queen``, or ``neutral_points: pan2023`` on the realistic and berry skies): the
Babinet and Brewster points are not symmetric about the sun; their distances from it follow the solar elevation
``e`` (deg) as fitted by Pan et al. (2023, "High-similarity analytical model of skylight polarization pattern based
on position variations of neutral points", Opt. Express 31(9) 15189), Eqs. (25) and (26)::

    delta_Brewster = 37.34 + 0.49 e  (e <= 27),   56.84 - 0.25 e  (e > 27)      below the sun
    delta_Babinet  = 42.53 - 0.56 e                                              above the sun

(measured at Hefei over e = 0-64 deg), the antisolar pair at their antipodes, in Berry's quartic with the
``P_max |w| / (2 - |w|)`` DOP. ``model: queen`` is that sky alone, the QuEEN model of pyskylumos (0.1.3) term for
term (a test compares it with vectors that pyskylumos generated, tests/vectors/sky/); on the realistic sky the same
placement takes the aerosol's dilution and the CIE radiance. Above ``e`` = 75.95 deg Eq. (26) turns negative: the
queen sky extrapolates as printed (as pyskylumos does), the realistic sky closes the Babinet point in on the sun.

Clouds are circular sky regions (ENU azimuth/elevation, optional azimuth drift and a time
window): inside, DOP is multiplied by ``dop_scale``, the radiance by ``intensity_scale`` and the
E-vector is rotated about the view ray by a smooth pseudo-random texture with standard
deviation ``aop_sigma_deg`` (eight plane waves on the sphere with wavelengths of a few degrees,
drawn once from the scenario seed, so every sensor and every fidelity sees the same cloud).
Occluders (azimuth sector up to an elevation: buildings, trees) and the ground (below the
horizon) are unpolarized with a scaled radiance.

Every function here works in any frame ``f``: give ``S`` and ``V`` in ``f`` and the rotation
``C_n^f`` (ENU to ``f``) for the region tests; the camera evaluates directly in its own frame.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from protocols.constants import DEG

__all__ = [
    "NEUTRAL_POINT_SEP_DEG",
    "Cloud",
    "Occluder",
    "SkyField",
    "SkyModel",
    "SunOccluder",
    "aerosol_fraction",
    "cie_gradation",
    "rayleigh_dop",
    "sky_from_spec",
    "textured_cloud",
]

#: Radiance of the ground relative to the sky (a diffuse, unpolarized surface).
GROUND_RADIANCE = 0.3
#: Maximum DOP of pure molecular scattering: (1 - rho) / (1 + rho) with the depolarization factor of air
#: rho = 0.0279 (Young 1980, Appl. Opt. 19:3427).
P_MOLECULAR = (1.0 - 0.0279) / (1.0 + 0.0279)
#: CIE standard clear sky (type 12) gradation coefficients a, b (CIE S 011/E:2003).
CIE_CLEAR_A, CIE_CLEAR_B = -1.0, -0.32
SKY_MODELS = ("realistic", "rayleigh", "berry", "queen")
#: Placements of the neutral points: ``symmetric`` (``delta`` = half ``neutral_point_sep``, above and below the sun),
#: ``pan2023`` (Pan et al. 2023, Eqs. 25 and 26, from the solar elevation; module docstring)
NEUTRAL_POINT_PLACEMENTS = ("symmetric", "pan2023")
#: Default Babinet-Brewster separation ``2 delta`` per model, deg: the realistic sky puts each neutral point ~20 deg
#: from the sun and the antisun (the typical clear-sky distances, Coulson 1988; Horvath et al. 2002); Berry's model
#: keeps the 20 deg of its paper's figures; Rayleigh has no neutral points off the sun (the value is unused).
NEUTRAL_POINT_SEP_DEG = {"realistic": 40.0, "berry": 20.0, "rayleigh": 20.0, "queen": 20.0}


def pan2023_offsets_deg(sun_elevation_deg: float) -> tuple[float, float]:
    """Sun-to-Brewster (below the sun) and sun-to-Babinet (above) distances, deg, for a solar elevation (deg):
    Pan et al. (2023) Eqs. (25) and (26), the linear fits as printed (the Brewster fit takes its lower branch at
    27 deg; outside the measured 0-64 deg they are extrapolated)."""
    e = float(sun_elevation_deg)
    brewster = 37.34 + 0.49 * e if e <= 27.0 else 56.84 - 0.25 * e
    return brewster, 42.53 - 0.56 * e


def _rayleigh_phase(cos_gamma: np.ndarray) -> np.ndarray:
    return 3.0 / (16.0 * math.pi) * (1.0 + cos_gamma * cos_gamma)


def _hg_phase(cos_gamma: np.ndarray, g: float) -> np.ndarray:
    return (1.0 - g * g) / (4.0 * math.pi * (1.0 + g * g - 2.0 * g * cos_gamma) ** 1.5)


def aerosol_fraction(cos_gamma: np.ndarray, turbidity: float, g: float = 0.7) -> np.ndarray:
    """Share of the sky radiance scattered by aerosol at scattering angle ``gamma`` (module docstring)."""
    la = (turbidity - 1.0) * _hg_phase(cos_gamma, g)
    return np.asarray(la / (_rayleigh_phase(cos_gamma) + la))


def cie_gradation(cos_zenith: np.ndarray) -> np.ndarray:
    """CIE clear-sky gradation ``phi(Z) / phi(0)`` (module docstring); brighter towards the horizon."""
    cz = np.maximum(cos_zenith, 1e-3)
    return np.asarray((1.0 + CIE_CLEAR_A * np.exp(CIE_CLEAR_B / cz)) / (1.0 + CIE_CLEAR_A * math.exp(CIE_CLEAR_B)))


def rayleigh_dop(cos_gamma: np.ndarray, p_max: float) -> np.ndarray:
    """``P_max sin^2(gamma)/(1 + cos^2(gamma))`` from ``cos(gamma)``."""
    c2 = cos_gamma * cos_gamma
    return p_max * (1.0 - c2) / (1.0 + c2)


@dataclass
class Cloud:
    """See module docstring; angles in rad, times in s."""

    az: float
    el: float
    radius: float
    dop_scale: float = 0.2
    aop_sigma: float = 20.0 * DEG
    intensity_scale: float = 1.5
    start_s: float = 0.0
    end_s: float = math.inf
    drift_az_rps: float = 0.0
    waves: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))  # (K, 3) wave vectors, rad^-1
    phases: np.ndarray = field(default_factory=lambda: np.zeros(0))
    #: view rays evaluated inside the cloud so far (evidence for an injected cloud fault)
    hits: int = 0

    def centre_enu(self, t: float) -> np.ndarray:
        az = self.az + self.drift_az_rps * t
        ce = math.cos(self.el)
        return np.array([math.sin(az) * ce, math.cos(az) * ce, math.sin(self.el)])

    def active(self, t: float) -> bool:
        return self.start_s <= t < self.end_s


@dataclass
class Occluder:
    """Azimuth sector ``[az_min, az_max]`` (clockwise from north, rad; may wrap through north) up to ``el_max``."""

    az_min: float
    az_max: float
    el_max: float
    intensity_scale: float = 0.3


@dataclass
class SunOccluder:
    """The sky within ``radius`` (rad) of the sun hidden over ``[start_s, end_s)`` (a cloud over the sun, a
    building): DOP times ``dop_scale``, radiance times ``intensity_scale``. ``hits`` counts the view rays
    it covered."""

    radius: float
    dop_scale: float = 0.0
    intensity_scale: float = 0.3
    start_s: float = 0.0
    end_s: float = math.inf
    hits: int = 0

    def active(self, t: float) -> bool:
        return self.start_s <= t < self.end_s


@dataclass
class SkyField:
    """Polarization at N view rays in frame f: DOP (N,), E-vector components (N,) each (unit, ⟂ V), radiance (N,)."""

    dop: np.ndarray
    ex: np.ndarray
    ey: np.ndarray
    ez: np.ndarray
    radiance: np.ndarray


class SkyModel:
    """The sky of one scenario (see module docstring).

    Parameters
    ----------
    model : ``"realistic"``, ``"rayleigh"``, ``"berry"`` or ``"queen"`` (Berry's quartic with Pan et al.'s placement).
    p_max : maximum DOP (0..1) of the rayleigh and berry models (the realistic sky derives it from ``turbidity``).
    neutral_point_sep : Berry's Babinet-Brewster separation ``2 delta``, rad; None: the model's default
        (:data:`NEUTRAL_POINT_SEP_DEG`).
    turbidity : realistic sky: Preetham's turbidity ``T`` (1 = molecules only, 2 very clear, 3 clear, 6+ hazy).
    aerosol_g : realistic sky: Henyey-Greenstein asymmetry of the aerosol.
    clouds, occluders : regions.
    neutral_points : ``"symmetric"`` or ``"pan2023"`` (:data:`NEUTRAL_POINT_PLACEMENTS`; ``queen`` is always
        ``pan2023``).
    """

    def __init__(self, model: str = "rayleigh", p_max: float = 0.7, neutral_point_sep: float | None = None,
                 clouds: list[Cloud] | None = None, occluders: list[Occluder] | None = None,
                 turbidity: float = 3.0, aerosol_g: float = 0.7, neutral_points: str = "symmetric") -> None:
        if model not in SKY_MODELS:
            raise ValueError(f"sky model must be one of {', '.join(SKY_MODELS)}, got {model!r}")
        if not 1.0 <= turbidity <= 20.0 or not 0.0 <= aerosol_g < 1.0:
            raise ValueError(f"turbidity must be in [1, 20] and aerosol_g in [0, 1), got {turbidity}, {aerosol_g}")
        if neutral_points not in NEUTRAL_POINT_PLACEMENTS:
            raise ValueError(f"neutral_points must be one of {', '.join(NEUTRAL_POINT_PLACEMENTS)}, "
                             f"got {neutral_points!r}")
        self.model = model
        self.neutral_points = "pan2023" if model == "queen" else neutral_points
        self.p_max = float(p_max) if model != "realistic" else P_MOLECULAR
        self.turbidity = float(turbidity)
        self.aerosol_g = float(aerosol_g)
        if neutral_point_sep is None:
            neutral_point_sep = NEUTRAL_POINT_SEP_DEG[model] * DEG
        self.delta = 0.5 * float(neutral_point_sep)
        self.clouds = clouds or []
        self.occluders = occluders or []
        self.sun_occluders: list[SunOccluder] = []

    @property
    def uniform(self) -> bool:
        """True for a clear Rayleigh sky without regions (the camera's fast path)."""
        return self.model == "rayleigh" and not self.clouds and not self.occluders and not self.sun_occluders

    # ------------------------------------------------------------------------------------------
    def evaluate(self, t: float, s_f: np.ndarray, vx: np.ndarray, vy: np.ndarray, vz: np.ndarray,
                 c_nf: np.ndarray) -> SkyField:
        """Polarization at view rays ``(vx, vy, vz)`` (unit, frame f) for the sun ``s_f`` (unit, frame f).

        ``c_nf`` is ``C_n^f`` (3x3, ENU to f). Arrays may be float32 (the camera) or float64.
        """
        dt = vx.dtype
        sx, sy, sz = (dt.type(s_f[0]), dt.type(s_f[1]), dt.type(s_f[2]))
        sun_up = float(np.asarray(c_nf[:, 2], dtype=np.float64) @ np.asarray(s_f, dtype=np.float64))
        if self.model == "rayleigh" or (self.model == "realistic" and sun_up > 1.0 - 1e-12):
            # (a realistic sky with the sun at the zenith: the neutral points have merged into the sun and
            # the antisun, leaving the symmetric pattern)
            ex = sy * vz - sz * vy
            ey = sz * vx - sx * vz
            ez = sx * vy - sy * vx
            cg = sx * vx + sy * vy + sz * vz
            dop = rayleigh_dop(cg, dt.type(self.p_max))
        else:
            dop, ex, ey, ez = self._berry(s_f, vx, vy, vz, c_nf)
        radiance = np.ones_like(vx)
        up = c_nf[:, 2]
        vu = up[0] * vx + up[1] * vy + up[2] * vz
        if self.model == "realistic":
            cg64 = np.clip((sx * vx + sy * vy + sz * vz).astype(np.float64), -1.0, 1.0)
            frac = aerosol_fraction(cg64, self.turbidity, self.aerosol_g)
            dop = (dop * (1.0 - frac)).astype(dt)
            lum = (_rayleigh_phase(cg64) + (self.turbidity - 1.0) * _hg_phase(cg64, self.aerosol_g))
            ref = float(_rayleigh_phase(np.zeros(1))[0]
                        + (self.turbidity - 1.0) * _hg_phase(np.zeros(1), self.aerosol_g)[0])
            radiance = (lum / ref * cie_gradation(vu.astype(np.float64))).astype(dt)
        n = np.sqrt(ex * ex + ey * ey + ez * ez)
        tiny = n < 1e-12
        if np.any(tiny):  # looking straight at the sun or anti-sun: unpolarized, any E ⟂ V
            n = np.where(tiny, 1.0, n).astype(dt)
            ax, ay, az_ = _any_perpendicular(vx, vy, vz)
            ex = np.where(tiny, ax, ex)
            ey = np.where(tiny, ay, ey)
            ez = np.where(tiny, az_, ez)
            dop = np.where(tiny, 0.0, dop).astype(dt)
        inv = (1.0 / n).astype(dt)
        ex, ey, ez = ex * inv, ey * inv, ez * inv
        ground = vu < 0.0
        if np.any(ground):
            dop = np.where(ground, 0.0, dop).astype(dt)
            radiance = np.where(ground, GROUND_RADIANCE, radiance).astype(dt)
        for cl in self.clouds:
            if not cl.active(t):
                continue
            c_f = c_nf @ cl.centre_enu(t)
            inside = (c_f[0] * vx + c_f[1] * vy + c_f[2] * vz) > math.cos(cl.radius)
            inside &= ~ground
            if not np.any(inside):
                continue
            cl.hits += int(np.count_nonzero(inside))
            dop = np.where(inside, dop * dt.type(cl.dop_scale), dop).astype(dt)
            radiance = np.where(inside, radiance * dt.type(cl.intensity_scale), radiance).astype(dt)
            if cl.aop_sigma > 0.0 and len(cl.waves):
                idx = np.nonzero(inside)[0]
                v_n = c_nf.T @ np.stack([vx[idx], vy[idx], vz[idx]]).astype(np.float64)  # (3, M) ENU
                arg = cl.waves @ v_n + cl.phases[:, None]
                rot = cl.aop_sigma * math.sqrt(2.0 / len(cl.phases)) * np.cos(arg).sum(axis=0)
                ex_i, ey_i, ez_i = _rotate_about(ex[idx], ey[idx], ez[idx], vx[idx], vy[idx], vz[idx], rot)
                ex, ey, ez = ex.copy(), ey.copy(), ez.copy()
                ex[idx], ey[idx], ez[idx] = ex_i, ey_i, ez_i
        for so in self.sun_occluders:
            if not so.active(t):
                continue
            near = ((sx * vx + sy * vy + sz * vz) > math.cos(so.radius)) & ~ground
            n_near = int(np.count_nonzero(near))
            if n_near:
                so.hits += n_near
                dop = np.where(near, dop * dt.type(so.dop_scale), dop).astype(dt)
                radiance = np.where(near, radiance * dt.type(so.intensity_scale), radiance).astype(dt)
        if self.occluders:
            east, north = c_nf[:, 0], c_nf[:, 1]
            ve = east[0] * vx + east[1] * vy + east[2] * vz
            vn = north[0] * vx + north[1] * vy + north[2] * vz
            az = np.mod(np.arctan2(ve, vn), 2.0 * math.pi)
            el = np.arcsin(np.clip(vu, -1.0, 1.0))
            for oc in self.occluders:
                if oc.az_min <= oc.az_max:
                    sector = (az >= oc.az_min) & (az <= oc.az_max)
                else:
                    sector = (az >= oc.az_min) | (az <= oc.az_max)
                hit = sector & (el <= oc.el_max) & ~ground
                if np.any(hit):
                    dop = np.where(hit, 0.0, dop).astype(dt)
                    radiance = np.where(hit, dt.type(oc.intensity_scale), radiance).astype(dt)
        return SkyField(dop.astype(dt, copy=False), ex, ey, ez, radiance)

    def evaluate_enu(self, t: float, s_n: np.ndarray, v_n: np.ndarray) -> SkyField:
        """Convenience: rays ``v_n`` (N, 3) and sun ``s_n`` in ENU."""
        v = np.asarray(v_n, dtype=np.float64)
        return self.evaluate(t, np.asarray(s_n, dtype=np.float64), v[:, 0], v[:, 1], v[:, 2], np.eye(3))

    # ------------------------------------------------------------------------------------------
    def _berry(self, s_f: np.ndarray, vx: np.ndarray, vy: np.ndarray, vz: np.ndarray,
               c_nf: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        c_fn = c_nf.T
        v_n = c_fn @ np.stack([vx, vy, vz]).astype(np.float64)  # (3, N)
        s_n = c_fn @ np.asarray(s_f, dtype=np.float64)
        den = 1.0 + v_n[2]
        below = den < 1e-9
        den = np.where(below, 1.0, den)
        zeta = (v_n[0] + 1j * v_n[1]) / den
        zs = (s_n[0] + 1j * s_n[1]) / max(1.0 + s_n[2], 1e-12)
        th_s = 2.0 * math.atan(abs(zs))  # sun zenith angle
        phi_s = math.atan2(zs.imag, zs.real)
        ph = complex(math.cos(phi_s), math.sin(phi_s))
        if self.neutral_points == "pan2023":
            d_below, d_above = (d * DEG for d in pan2023_offsets_deg(90.0 - th_s / DEG))
        else:
            d_below = d_above = self.delta
        if self.model == "realistic" and (th_s < d_above or d_above < 0.0):
            # sun near the zenith: the sun's vertical loses its meaning and, by symmetry, the Babinet and Brewster
            # points close in on the sun (and Arago on the antisun): the pattern tends to the symmetric one
            d_above = 0.5 * th_s
            if self.neutral_points == "symmetric":
                d_below = d_above
        zB = ph * math.tan((th_s + d_below) / 2.0)  # Brewster: below the sun
        zb = ph * math.tan((th_s - d_above) / 2.0)  # Babinet: above the sun
        aB = -1.0 / np.conj(zB)
        ab = -1.0 / np.conj(zb) if zb != 0 else complex(1e300, 0.0)
        w = (-4.0 * (zeta - zB) * (zeta - zb) * (zeta - aB) * (zeta - ab)
             / ((1.0 + np.abs(zeta) ** 2) ** 2 * abs(zB - aB) * abs(zb - ab)))
        aw = np.minimum(np.abs(w), 1.0)
        dop = self.p_max * aw / (2.0 - aw)
        chi = 0.5 * np.angle(w * (ph.conjugate() ** 2))  # the |.| normalisation leaves a 2 phi_sun phase
        cx, cy = np.cos(chi), np.sin(chi)
        x, y = zeta.real, zeta.imag
        rho2 = x * x + y * y
        d = 1.0 + rho2
        d2 = d * d
        # Jacobian of the inverse stereographic projection applied to (cos chi, sin chi)
        e_e = (2.0 / d - 4.0 * x * x / d2) * cx - 4.0 * x * y / d2 * cy
        e_n = -4.0 * x * y / d2 * cx + (2.0 / d - 4.0 * y * y / d2) * cy
        e_u = -4.0 * x / d2 * cx - 4.0 * y / d2 * cy
        e_f = c_nf @ np.stack([e_e, e_n, e_u])
        dt = vx.dtype
        dop = np.where(below, 0.0, dop)
        return dop.astype(dt), e_f[0].astype(dt), e_f[1].astype(dt), e_f[2].astype(dt)


def _any_perpendicular(vx: np.ndarray, vy: np.ndarray, vz: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A unit vector perpendicular to each V (used where E is undefined)."""
    use_x = np.abs(vx) < 0.9
    # V x e_x = (0, vz, -vy);  V x e_y = (-vz, 0, vx)
    ax = np.where(use_x, 0.0, -vz)
    ay = np.where(use_x, vz, 0.0)
    az = np.where(use_x, -vy, vx)
    n = np.sqrt(ax * ax + ay * ay + az * az)
    return (ax / n).astype(vx.dtype), (ay / n).astype(vx.dtype), (az / n).astype(vx.dtype)


def _rotate_about(ex: np.ndarray, ey: np.ndarray, ez: np.ndarray, vx: np.ndarray, vy: np.ndarray, vz: np.ndarray,
                  ang: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Rotate E (⟂ V) about V by ``ang`` (rad): ``E cos a + (V x E) sin a``."""
    c, s = np.cos(ang), np.sin(ang)
    wx = vy * ez - vz * ey
    wy = vz * ex - vx * ez
    wz = vx * ey - vy * ex
    return ((ex * c + wx * s).astype(ex.dtype), (ey * c + wy * s).astype(ex.dtype), (ez * c + wz * s).astype(ex.dtype))


def textured_cloud(rng: np.random.Generator, az: float, el: float, radius: float, dop_scale: float = 0.2,
                   aop_sigma: float = 20.0 * DEG, intensity_scale: float = 1.5, start_s: float = 0.0,
                   end_s: float = math.inf, drift_az_rps: float = 0.0) -> Cloud:
    """A :class:`Cloud` (angles in rad) with its AOP texture drawn from ``rng`` as :func:`sky_from_spec` does."""
    k = 8
    dirs = rng.standard_normal((k, 3))
    dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
    wavelength = rng.uniform(3.0, 10.0, k) * DEG
    waves = dirs * (2.0 * math.pi / wavelength)[:, None]
    return Cloud(az, el, radius, dop_scale, aop_sigma, intensity_scale, start_s, end_s, drift_az_rps, waves,
                 rng.uniform(0, 2 * math.pi, k))


def sky_from_spec(spec: object | None, rng: np.random.Generator | None = None) -> SkyModel:
    """Build a :class:`SkyModel` from ``emulator.scenario.world_schema.SkySpec`` (None: clear Rayleigh sky, P_max 0.7).

    ``rng`` draws the cloud textures (8 plane waves per cloud, wavelengths 3-10 deg).
    """
    if spec is None:
        return SkyModel()
    rng = rng or np.random.default_rng(0)
    clouds = []
    for c in spec.clouds:  # type: ignore[attr-defined]
        k = 8
        dirs = rng.standard_normal((k, 3))
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        wavelength = rng.uniform(3.0, 10.0, k) * DEG
        waves = dirs * (2.0 * math.pi / wavelength)[:, None]
        clouds.append(Cloud(c.az_deg * DEG, c.el_deg * DEG, c.radius_deg * DEG, c.dop_scale, c.aop_sigma_deg * DEG,
                            c.intensity_scale, c.start_s, c.end_s, c.drift_az_dps * DEG, waves,
                            rng.uniform(0, 2 * math.pi, k)))
    occ = [Occluder(o.az_min_deg * DEG, o.az_max_deg * DEG, o.el_max_deg * DEG, o.intensity_scale)
           for o in spec.occluders]  # type: ignore[attr-defined]
    sep = spec.neutral_point_sep_deg  # type: ignore[attr-defined]
    return SkyModel(spec.model, spec.p_max, None if sep is None else sep * DEG, clouds, occ,  # type: ignore[attr-defined]
                    turbidity=spec.turbidity, aerosol_g=spec.aerosol_g,  # type: ignore[attr-defined]
                    neutral_points=getattr(spec, "neutral_points", "symmetric"))
