"""Sun-elevation positioning with a multi-unit polarization compass and a Sage-Husa adaptive KF.

Zhang, Yang, Huang, Liu, Wang, Guo, *Bionic Integrated Positioning Mechanism Based on Bioinspired
Polarization Compass and Inertial Navigation System*, Sensors 21(4):1055, 2021 (section 3.2).

Per COMPASS frame (9 units, the geometry of the conventions,
:func:`firmware_model.psns_geometry.compass_unit_mountings`):

1. The two units with the highest DOP (paper Eq. 4: ``D_max >= D_i >= D_j >= D_k``) give
   ``E_i^b = C_i^b (sin A_i, cos A_i, 0)``, ``E_j^b`` likewise (paper Eqs. 3, 5 in the AOP convention of
   docs/architecture.md "Conventions");
   the Rayleigh E-vector is perpendicular to the Sun, so ``S^b = E_i^b x E_j^b / sin<E_i, E_j>`` (Eq. 6). When
   the pair is ill-conditioned (``|E_i x E_j| < min_pair_sine``: the two rays are nearly coplanar with the
   Sun) the next pair in DOP order is taken (a decision the mode manager logs).
2. Sun elevation in b, ``H_b = asin(s_z^b)`` (Eqs. 7-8), and in n: ``H_n = asin((C_b^{n'} S^b)_U)``; the
   sign of ``S^b`` is the one that puts the Sun above the horizon.
3. The INS elevation ``sin H_c = sin L sin Dec + cos L cos Dec cos LHA`` with ``LHA = GHA + lambda`` (Eqs. 9-10,
   Grena ephemeris, :mod:`firmware_model.sun`).
4. Measurement (Eqs. 11-14): ``z = sin H_c - sin H_n = H x + v`` with
   ``H = [0 0 0 0 0 0  cos(H_c) alpha  cos(H_c) beta  0 ... 0]``, where (docs/reference/algorithms.md 1.4)
   ``alpha = dh/dL = (cos L sin Dec - sin L cos Dec cos LHA) / cos h`` and
   ``beta = dh/dlambda = -cos L cos Dec sin LHA / cos h``: ``cos(h) alpha`` and ``cos(h) beta`` are the
   paper's printed coefficients of ``d(sin h)``. States ``dL, dlambda`` in rad, "computed minus true".
   The paper's H has no attitude columns. But ``H_n`` is computed with the INS attitude, so
   ``sin H_n = sin H - phi_E S_N + phi_N S_E`` to first order (``C_b^{n'} S^b = S^n - phi x S^n``), and
   ``attitude_coupling`` (docs/decisions/filter-consistency.md D-5.21) puts those terms in H:
   ``H[phi_E] = S_N``, ``H[phi_N] = -S_E``. Since ``cos(h) alpha = S_N`` and ``cos(h) beta = S_E cos L``, the
   row is ``z = S_N (dL + phi_E) + S_E (cos L dlambda - phi_N)``: the tilt of the INS level against the vertical
   of its computed position (the psi-angle) along the Sun, not the position alone. Without the tilt columns (the
   paper's H, ``attitude_coupling: false``) the INS tilt (0.1 deg in 20 static minutes is 11 km) is taken for
   position along the azimuth; with them, the filter doubles its latitude / longitude MAE in the paper's like-for-like
   set-up (1 deg of tilt, no fine alignment; D-5.21). The defaults (``attitude_coupling`` and ``attitude_aiding``
   off) are the paper's filter exactly.
5. **Sage-Husa adaptive R** (docs/reference/algorithms.md 5.1, PSINS ``kfupdate`` adaptive form): with the innovation
   ``r_k`` and ``ry = r_k^2 - H P H^T`` clamped to ``[R_min, R_max]``, ``R <- (1 - d) R + d ry``,
   ``d <- d / (d + b)`` (``d_k = (1-b)/(1-b^{k+1})``, b the forgetting factor); the measurement then updates
   with the adapted R. Before that, the mode manager's chi-square gate (1 dof) with the current R. The nominal R0
   Sage-Husa starts from (and its clamps scale with) is, per measurement, the variance of ``sin H_n`` that the
   spec sheet's compass figures give through the chosen pair's geometry (:func:`elevation_noise_variance`,
   docs/decisions/filter-consistency.md D-5.19); ``elevation_sigma_deg`` fixes it instead (``(cos H_c sigma)^2``).

6. **Attitude aiding** (``attitude_aiding``, off by default; not in the paper's model): the same frame's
   E-vectors of all valid units give ``+-S^b`` by the base paper's eigen-solution (Eq. 14), used as the base
   filter's solar-vector measurement. Without it the INS tilt drifts with the gyro bias and enters the
   measured ``H_n`` unmodelled (``d H_n = -phi_E S_N + phi_N S_E``): the paper's H then turns tilt drift into
   position error, and the direction perpendicular to the Sun's azimuth is not observed at all. With the
   aiding the tilt perpendicular to the Sun is held, but the rotation about the Sun stays unobserved
   and its tilt part drives the cross-azimuth position error all the same; docs/variants.md compares them.

7. ``elevation_update`` off: the frames are still measured (and logged as ``elevation_update_off``), nothing
   reaches the state. It is the paper's pure-SINS baseline on the same world and seed
   (``scenarios/sun_elevation_paper_like_for_like.yaml``, docs/variants.md 6.4).

No GNSS is needed after the initial fix that gives position and UTC (the paper uses GPS for the initial
position and as the reference only).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from protocols.psns import CompassFrame, PsnsStatus

from .. import c674x, psns, sun
from ..arrays import FloatArray, FloatDtype
from ..attitude import q2mat_fast
from ..config import FirmwareConfig
from ..filters.base import BaseFilter
from ..filters.interface import UpdateReport, register_filter
from ..filters.solar import SolarObservation
from ..kf import D_LAT, D_LON, N_STATES, PHI_E, PHI_N
from ..nav_state import NavState
from ..psns_geometry import compass_unit_mountings
from ..units import DEG
from .common import cross
from .dual_vector import unit_evectors
from .mode_manager import ModeManager

__all__ = ["SageHusaR", "SunElevationFilter", "elevation_noise_cycles", "elevation_noise_variance",
           "sun_elevation_partials", "sun_vector_from_two_evectors"]


def sun_elevation_partials(lat: float, sin_dec: float, cos_dec: float, lha: float) -> tuple[float, float, float]:
    """``(sin h, alpha, beta)``: the sun elevation's sine and ``alpha = dh/dL``, ``beta = dh/dlambda`` (rad/rad).

    ``sin h = sin L sin Dec + cos L cos Dec cos t``;
    ``alpha = (cos L sin Dec - sin L cos Dec cos t) / cos h`` (= cos Az);
    ``beta = -cos L cos Dec sin t / cos h`` (= cos L sin Az), t the local hour angle (docs/reference/algorithms.md 1.4).
    """
    sl, cl = math.sin(lat), math.cos(lat)
    st, ct = math.sin(lha), math.cos(lha)
    sin_h = sl * sin_dec + cl * cos_dec * ct
    cos_h = math.sqrt(max(1e-12, 1.0 - sin_h * sin_h))
    alpha = (cl * sin_dec - sl * cos_dec * ct) / cos_h
    beta = -cl * cos_dec * st / cos_h
    return sin_h, alpha, beta


def sun_vector_from_two_evectors(e_i: FloatArray, e_j: FloatArray) -> tuple[FloatArray, float]:
    """``S = E_i x E_j / |E_i x E_j|`` (paper Eq. 6) and ``|E_i x E_j|`` (the sine of their angle, for unit E)."""
    c = cross(e_i, e_j)
    n = math.sqrt(float(c @ c))
    return (c / max(n, 1e-12)).astype(e_i.dtype), n


def elevation_noise_variance(cfg: FirmwareConfig, e_i: FloatArray, e_j: FloatArray, s_b: FloatArray,
                             ray_i: FloatArray, ray_j: FloatArray, dop_i: float, dop_j: float,
                             up_b: FloatArray) -> float:
    """Variance of the measured ``sin H_n = up^b . S^b`` (sine units) from the two units' errors as the spec sheet
    states them (docs/decisions/filter-consistency.md D-5.19); body frame, unit vectors.

    ``S`` satisfies ``S . E_i = S . E_j = 0``. A unit's E-vector error is a rotation about its ray by its AOP error
    ``a_i`` (noise ``aop_sigma * dop_ref / DOP_i``, and the calibration's E-vector residual), ``dE_i = -a_i r_i x E_i``,
    plus its installation residual, a rotation ``w_i`` (per axis), ``dE_i = -w_i x E_i``. The constraint
    ``S . dE_i + dS . E_i = 0`` makes ``dS . E_i = c_i`` with ``c_i = a_i S.(r_i x E_i) + w_i.(E_i x S)``, of
    variance ``v_i = sigma_a,i^2 sin^2 gamma_i + sigma_w^2`` (``|S.(r_i x E_i)| = sin gamma_i``, gamma the
    scattering angle, since E_i is along ``r_i x S``; ``|E_i x S| = 1``). With E_i, E_j in the plane normal to S,
    ``dS = (c_i E_j x S + c_j S x E_i) / D``, ``D = S . (E_i x E_j)``, so

        var(d sin H_n) = [v_i (up . E_j x S)^2 + v_j (up . S x E_i)^2] / D^2.

    ``up_b`` is the local vertical in the body frame (``C_b^n`` third row). Independent of the sign of ``S``. Cost:
    :func:`elevation_noise_cycles`."""
    aop_ref = cfg.compass_aop_sigma_deg * DEG * cfg.compass_aop_dop_ref
    res2 = (cfg.compass_aop_residual_deg * DEG) ** 2
    w2 = (cfg.compass_installation_residual_deg * DEG) ** 2
    a_j = cross(e_j, s_b)  # E_j x S
    b_i = cross(s_b, e_i)  # S x E_i
    d = float(s_b @ cross(e_i, e_j))
    out = 0.0
    for e, ray, dop, g in ((e_i, ray_i, dop_i, a_j), (e_j, ray_j, dop_j, b_i)):
        sin_g = float(s_b @ cross(ray, e))
        sig_a2 = (aop_ref / max(dop, 1e-3)) ** 2 + res2
        out += (sig_a2 * sin_g * sin_g + w2) * float(up_b @ g) ** 2
    return out / max(d * d, 1e-12)


def elevation_noise_cycles(c: c674x.KernelCosts) -> int:
    """:func:`elevation_noise_variance`: five cross products (30 MUL, 15 ADD), five dot products (15, 10), per unit
    six MUL / three ADD, two divisions (the DOPs) and one for ``/ D^2`` [D]."""
    return c.flops(57, 31) + 3 * c.math("div")


class SageHusaR:
    """Scalar Sage-Husa measurement-noise adaptation (docs/reference/algorithms.md 5.1; PSINS ``kfupdate`` adaptive =
    1)."""

    def __init__(self, r0: float, forgetting: float, r_min_factor: float, r_max_factor: float) -> None:
        self.r0 = r0
        self.r = r0
        self.b = forgetting
        self.beta = 1.0
        self.r_min = r_min_factor * r0
        self.r_max = r_max_factor * r0
        self.k = 0

    def rescale(self, r0: float) -> None:
        """A new nominal R (the elevation's cos(h) factor changed): keep the adapted ratio."""
        ratio = self.r / self.r0
        self.r_min *= r0 / self.r0
        self.r_max *= r0 / self.r0
        self.r0 = r0
        self.r = ratio * r0

    def adapt(self, innov: float, hph: float) -> float:
        """One step: ``ry = r_k^2 - H P H^T`` clamped; ``R = (1-d) R + d ry``; ``d <- d/(d+b)``. Returns R."""
        ry = innov * innov - hph
        if ry < self.r_min:
            ry = self.r_min
        if ry > self.r_max:
            self.r = self.r_max
        else:
            self.r = (1.0 - self.beta) * self.r + self.beta * ry
        self.beta = self.beta / (self.beta + self.b)
        self.k += 1
        return self.r


@register_filter("sun_elevation")
class SunElevationFilter(BaseFilter):
    """Base 15-state filter with the sun-elevation position measurement and adaptive R (module docstring)."""

    #: 15 states only: this variant's own updates build 15-wide rows (the augmented GNSS / solar-bias states are
    #: the base filter's; docs/variants.md "Consistency")
    augmentable = False

    def __init__(self, cfg: Any, meter: c674x.CycleMeter, dtype: FloatDtype) -> None:
        super().__init__(cfg, meter, dtype)
        self.p = cfg.variants.sun_elevation
        self.mm = ModeManager("sun_elevation", cfg.variants.mode_manager)
        self.counters = self.mm.counters
        m = cfg.compass_mountings if cfg.compass_mountings is not None else compass_unit_mountings()
        self.mountings = np.asarray(m, dtype=np.float64)
        self.n_units = len(self.mountings)
        # the nominal R until the first measurement sets it from the pair (only the adapted ratio carries over)
        fixed = self.p.elevation_sigma_deg
        sig = (fixed if fixed is not None else cfg.compass_aop_sigma_deg) * DEG
        self.adaptive = SageHusaR(sig * sig, self.p.forgetting, self.p.r_min_factor, self.p.r_max_factor)
        self.state = 0
        self.pair_mask = 0
        self._frames = 0
        self.last: dict[str, float] = {}

    def drain_events(self) -> list[dict[str, Any]]:
        return self.mm.drain() if self.mm.events else []

    def variant_status(self) -> tuple[int, int, int] | None:
        return self.state, self.n_units, self.pair_mask

    def update_compass(self, nav: NavState, frame: CompassFrame, t_exposure_s: float) -> UpdateReport | None:
        host = self.host
        assert host is not None
        mm, pm, p, cost = self.mm, self.mm.params, self.p, self.cost
        dt = self.dtype
        t = host.now_s()
        self._frames += 1
        if p.update_every > 1 and self._frames % p.update_every:
            return None
        if frame.header.status & PsnsStatus.SUN_BELOW_HORIZON:
            mm.decide(t, "sun_elevation", False, "sun_below_horizon")
            return None
        days = host.utc_days(t_exposure_s)
        if days is None:
            mm.decide(t, "sun_elevation", False, "no_utc")
            return None
        # units by DOP, highest first (paper Eq. 4)
        units = [(u.dop, u.unit, u.aop_cdeg) for u in frame.units if u.unit < self.n_units]
        units.sort(reverse=True)
        good = [u for u in units if u[0] * (1.0 / 65535.0) >= pm.dop_min]
        self.meter.charge("se_sort", cost.flops(0, 2 * len(units) * max(1, len(units).bit_length())))
        if len(good) < 2:
            self.state = 2
            mm.decide(t, "sun_elevation", False, "fewer_than_two_units_above_dop_min", units=len(good))
            return UpdateReport("sun_elevation", False, 0, 0.0, {"reason": "low_dop"})
        aop = np.array([u[2] for u in good[:4]], dtype=dt) * dt(0.01 * DEG)
        e = unit_evectors(aop, self.mountings[[u[1] for u in good[:4]]], dt)
        pair: tuple[int, int] | None = None
        for a, b in ((0, 1), (0, 2), (1, 2), (0, 3), (1, 3), (2, 3)):
            if b >= len(e):
                continue
            s_b, sine = sun_vector_from_two_evectors(e[a], e[b])
            if sine >= p.min_pair_sine:
                pair = (a, b)
                break
        self.meter.charge("se_sun_vector", 4 * (cost.math("sin") + cost.math("cos")) + cost.flops(24, 12)
                          + cost.math("rsqrt"))
        if pair is None:
            self.state = 2
            mm.decide(t, "sun_elevation", False, "ill_conditioned_pairs", min_sine=p.min_pair_sine)
            return UpdateReport("sun_elevation", False, 0, 0.0, {"reason": "ill_conditioned"})
        ui, uj = good[pair[0]][1], good[pair[1]][1]
        p_ins, _, q_exp = host.ins_at(t_exposure_s)
        cbn = q2mat_fast(q_exp).astype(dt)
        if p.attitude_aiding:
            self._attitude_update(nav, t, t_exposure_s, days, p_ins, cbn, good)
        s_n_meas = cbn @ s_b
        if float(s_n_meas[2]) < 0:  # the sign that puts the Sun above the horizon
            s_b, s_n_meas = -s_b, -s_n_meas
        sin_hn = float(s_n_meas[2])
        # INS elevation and its partials from Dec, L, LHA (Eqs. 9-14)
        sin_d, cos_d, gha = sun.sun_equatorial(days, dt)
        lat, lon = float(p_ins[0]), float(p_ins[1])
        lha = gha + lon
        sin_hc, alpha, beta = sun_elevation_partials(lat, sin_d, cos_d, lha)
        self.meter.charge("sun_ephemeris", sun.ephemeris_cycles())
        self.meter.charge("se_partials", c674x.mathlib("sindp", 2) + c674x.mathlib("cosdp", 2) + c674x.mathlib("sqrtdp")
                          + c674x.mathlib("divdp") + c674x.dp_flops(10, 6))
        if sin_hc < math.sin(pm.min_sun_elevation_deg * DEG):
            mm.decide(t, "sun_elevation", False, "sun_low", elevation_deg=math.degrees(math.asin(sin_hc)))
            return None
        cos_hc = math.sqrt(1.0 - sin_hc * sin_hc)
        z = sin_hc - sin_hn
        h = np.zeros(N_STATES, dtype=dt)
        h[D_LAT] = cos_hc * alpha
        h[D_LON] = cos_hc * beta
        if p.attitude_coupling:
            h[PHI_E] = float(s_n_meas[1])
            h[PHI_N] = -float(s_n_meas[0])
        if p.elevation_sigma_deg is not None:
            r0 = (cos_hc * p.elevation_sigma_deg * DEG) ** 2
        else:  # from the spec sheet's compass figures through this pair's geometry (D-5.19)
            mi, mj = self.mountings[ui], self.mountings[uj]
            r0 = elevation_noise_variance(self.cfg, e[pair[0]].astype(np.float64), e[pair[1]].astype(np.float64),
                                          s_b.astype(np.float64), mi[:, 2], mj[:, 2],
                                          good[pair[0]][0] * (1.0 / 65535.0), good[pair[1]][0] * (1.0 / 65535.0),
                                          cbn[2, :].astype(np.float64))
            self.meter.charge("se_elevation_noise", elevation_noise_cycles(cost))
        self.adaptive.rescale(r0)
        ph = self.P @ h
        hph = float(h @ ph)
        innov = z - float(h @ self.x)
        nis = innov * innov / (hph + self.adaptive.r)
        self.meter.charge("se_gate", cost.flops(2 * 225, 2 * 225))
        self.pair_mask = (1 << ui) | (1 << uj)
        self.last = {"t": t_exposure_s, "sin_hc": sin_hc, "sin_hn": sin_hn, "alpha": alpha, "beta": beta,
                     "h_b_deg": math.degrees(math.asin(max(-1.0, min(1.0, float(s_b[2]))))), "nis": nis}
        if not p.elevation_update:  # the paper's pure-SINS baseline: measured, logged, not used
            mm.decide(t, "sun_elevation", False, "elevation_update_off")
            return None
        if not mm.gate(t, "sun_elevation", nis, 1, units=[ui, uj], residual_deg=math.degrees(innov / cos_hc)):
            self.state = 2
            return UpdateReport("sun_elevation", False, 0, math.sqrt(nis), {"reason": "chi2_fail"})
        r = self.adaptive.adapt(innov, hph)
        mm.report(t, "adaptive_r", round(math.log2(r / self.adaptive.r0)), "sage_husa",
                  r_over_r0=r / self.adaptive.r0, sigma_deg=math.degrees(math.sqrt(r) / cos_hc))
        self.meter.charge("se_sage_husa", cost.flops(6, 6) + cost.math("div"))
        nu = self._scalar(h, z, r)
        self.meter.charge("kf_update", self._cyc_update)
        self.state = 1
        return UpdateReport("sun_elevation", True, 1, abs(nu), {"units": [ui, uj]})

    def _attitude_update(self, nav: NavState, t: float, t_exp: float, days: float, p_ins: FloatArray,
                         cbn: FloatArray, good: list[tuple[int, int, int]]) -> None:
        """Step 6: ``+-S^b`` from all valid units' E-vectors (Eq. 14) -> the base solar-vector update."""
        dt = self.dtype
        if len(good) < 3:
            self.mm.decide(t, "solar_vector", False, "fewer_than_three_units", units=len(good))
            return
        aop = np.array([u[2] for u in good], dtype=dt) * dt(0.01 * DEG)
        dop = np.array([u[0] for u in good], dtype=dt) * dt(1.0 / 65535.0)
        e = unit_evectors(aop, self.mountings[[u[1] for u in good]], dt)
        sol = psns.solve_solar_vector(e, dop, self.mm.params.dop_min, max_quality=self.cfg.psns_quality_max)
        self.meter.charge("psns_evectors", len(good) * (self.cost.math("sin") + self.cost.math("cos"))
                          + self.cost.flops(6, 3, iterations=len(good)))
        self.meter.charge("psns_solve", psns.solve_cycles(len(good), self.cost))
        if not sol.valid:
            self.mm.decide(t, "solar_vector", False, "poor_eigen_solution", quality=sol.quality)
            return
        s_n = sun.sun_vector_enu(days, float(p_ins[0]), float(p_ins[1]), dtype=dt)
        self.meter.charge("sun_ephemeris", sun.ephemeris_cycles())
        rep = self.update_solar(nav, SolarObservation(t_exp, sol.s, sol.quality, sol.n_used, "compass"), s_n, cbn)
        self.mm.decide(t, "solar_vector", rep.accepted, "chi2_pass" if rep.accepted else "chi2_fail",
                       norm_innov=rep.max_norm_innov)
