"""Dual-vector switching: polarization-error-vector / sun-error-vector measurements (patent, Guo et al. 2021).

*Inertia/polarization navigation method based on polarization and sun dual-vector switching* (CN, filed
2021-11-22, Guo Lei, Dou Qingfeng, Yang Jian, Wang Yue). The published text lost its equations; the
derivation below rebuilds them from the description (docs/variants.md section 2 has it in full).

Sensors: ``l`` single-direction polarization units (the multi-unit compass, COMPASS frames), unit ``i``
with mounting ``C_i^b`` (its view ray ``r_i^b`` = third column) and wire AOP ``A_i`` (docs/architecture.md
"Conventions": measured in the
unit's x-y plane from +y towards +x).

Step 1 (predicted polarization vector). From the INS attitude ``C_b^{n'}`` at the exposure time and the
ephemeris ``s^n``: ``s^b = C_n^{b'} s^n`` and, by Rayleigh scattering (E perpendicular to the scattering
plane), ``p_i = (s^b x r_i^b) / |s^b x r_i^b|``.

Step 2 (measured polarization vector, error vector). ``p~_i = C_i^b (sin A_i, cos A_i, 0)^T`` (sign
ambiguous: AOP is an axis). The polarization error vector is ``dp_i = p~_i x p_i``; both vectors are
perpendicular to ``r_i``, so ``dp_i = -(z_i / sin gamma_i) r_i`` with ``z_i = s^b . p~_i`` (gamma_i the
scattering angle), its length ``|sin|`` of the angle between measured and predicted vectors.

Step 3 (information-discrimination factor). ``lambda_i = |dp_i| = |p~_i x p_i|`` (independent of the sign
of ``p~_i``); ``q_i = 1`` when ``lambda_i < T_p``, else 0, ``i = 1..l``. A unit the mode manager finds
invalid (DOP below the threshold, missing from the frame, sun within ``min_scattering`` of its ray) has
``q_i = 0`` whatever its factor.

Step 4 (switching), ``k = sum q_i``:

* ``k >= 2``: **sun-error-vector mode**. Two reliable units (the pair with the largest ``|p~_i x p~_j|``;
  the patent says "any two") give the measured sun vector ``s~^b = p~_i x p~_j / |...|`` (Rayleigh: s is
  perpendicular to both E-vectors). With ``a = C_b^{n'} s~^b = (I - [phi x]) s^n`` the sun error vector
  ``Z_ps = (a . s^n)(a x s^n)`` is sign-invariant (``a -> -a`` leaves it unchanged: no direction
  ambiguity) and, dropping the second-order terms in phi,
  ``Z_ps = s^n x (phi x s^n) = (I - s^n s^nT) phi``, ``H_ps = [I - s^n s^nT, 0_{3x12}]``. Its rank is 2
  (rotation about the sun is unobservable); the firmware projects it on two unit vectors ``u_1, u_2``
  perpendicular to ``s^n``: ``z_k = u_k^T Z_ps = u_k^T phi``.
* ``k = 1``: **polarization-error-vector mode** with the reliable unit's vector:
  ``z = s^n . (C_b^{n'} p~^b) = (s^n x p^n)^T phi``, ``H_pp = [(s^n x p^n)^T, 0_{1x12}]``
  (docs/reference/algorithms.md 1.4; ``z = -sin(gamma) (r . dp)``, the error vector's signed length). Flipping the sign
  of ``p~`` flips ``z`` and ``H`` together: the update does not change.
* ``k = 0``: no polarization update (reported as a rejected PSNS update and a ``psns_mode`` event).

Both modes go through a chi-square gate (mode manager) before the Kalman update; GNSS updates and the
time update are the base filter's (the patent's state model is the same 15-state SINS error model).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from protocols.psns import CompassFrame, PsnsStatus

from .. import c674x, sun
from ..arrays import F64Array, FloatArray, FloatDtype
from ..attitude import q2mat_fast, skew
from ..filters.base import BaseFilter
from ..filters.interface import UpdateReport, register_filter
from ..kf import IDX_ATT
from ..nav_state import NavState
from ..psns_geometry import compass_unit_mountings
from ..units import DEG
from .common import cross, plane_basis
from .mode_manager import ModeManager

__all__ = [
    "PSNS_MODE_NONE",
    "PSNS_MODE_POLARIZATION",
    "PSNS_MODE_SUN",
    "DualVectorFilter",
    "discrimination_factors",
    "polarization_error",
    "sun_error_vector",
    "unit_evectors",
]

PSNS_MODE_NONE, PSNS_MODE_POLARIZATION, PSNS_MODE_SUN = 0, 1, 2
MODE_NAMES = {PSNS_MODE_NONE: "none", PSNS_MODE_POLARIZATION: "polarization_error_vector",
              PSNS_MODE_SUN: "sun_error_vector"}


def unit_error_figures(cfg: Any) -> tuple[float, float, float]:
    """The compass units' error figures the firmware's spec sheet states, as the dual-vector update uses them
    (D-5.22): ``aop_sigma * dop_ref`` (rad; the AOP noise is that over the unit's DOP), the calibration's E-vector
    residual variance and the installation residual variance per axis (rad^2). ``firmware.variants.dual_vector``'s
    ``aop_sigma_deg`` / ``dop_ref``, when a scenario sets them, replace the sheet's AOP noise figures."""
    p = cfg.variants.dual_vector
    sigma = p.aop_sigma_deg if p.aop_sigma_deg is not None else cfg.compass_aop_sigma_deg
    dop_ref = p.dop_ref if p.dop_ref is not None else cfg.compass_aop_dop_ref
    return (sigma * DEG * dop_ref, (cfg.compass_aop_residual_deg * DEG) ** 2,
            (cfg.compass_installation_residual_deg * DEG) ** 2)


def unit_evectors(aop: FloatArray, mountings: FloatArray, dtype: FloatDtype = np.float32) -> FloatArray:
    """Measured polarization vectors ``p~_i^b = C_i^b (sin A_i, cos A_i, 0)`` (n, 3) from wire AOPs (rad)."""
    a = np.asarray(aop, dtype=dtype)
    sa, ca = np.sin(a), np.cos(a)
    m = mountings.astype(dtype)
    return m[:, :, 0] * sa[:, None] + m[:, :, 1] * ca[:, None]


def discrimination_factors(p_meas: FloatArray, s_b: FloatArray, rays_b: FloatArray
                           ) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Predicted polarization vectors and information-discrimination factors (Steps 1-3).

    Parameters
    ----------
    p_meas : (n, 3) measured unit polarization vectors in b (sign arbitrary).
    s_b : (3,) unit sun vector in b predicted by the INS.
    rays_b : (n, 3) unit view rays of the units in b.

    Returns
    -------
    p_pred : (n, 3) unit predicted vectors ``(s x r)/|s x r|`` (zero where the sun is on the ray).
    lam : (n,) ``|p~ x p|`` in [0, 1].
    sin_gamma : (n,) ``|s x r|``, sine of the scattering angle.
    """
    sxr = np.stack([s_b[1] * rays_b[:, 2] - s_b[2] * rays_b[:, 1],
                    s_b[2] * rays_b[:, 0] - s_b[0] * rays_b[:, 2],
                    s_b[0] * rays_b[:, 1] - s_b[1] * rays_b[:, 0]], axis=1)
    sin_g = np.sqrt(np.sum(sxr * sxr, axis=1))
    p_pred = sxr / np.maximum(sin_g, 1e-12)[:, None]
    c = np.stack([p_meas[:, 1] * p_pred[:, 2] - p_meas[:, 2] * p_pred[:, 1],
                  p_meas[:, 2] * p_pred[:, 0] - p_meas[:, 0] * p_pred[:, 2],
                  p_meas[:, 0] * p_pred[:, 1] - p_meas[:, 1] * p_pred[:, 0]], axis=1)
    lam = np.sqrt(np.sum(c * c, axis=1))
    return p_pred.astype(p_meas.dtype), lam, sin_g


def sun_error_vector(cbn: FloatArray, s_meas_b: FloatArray, s_n: FloatArray
                     ) -> tuple[FloatArray, tuple[FloatArray, FloatArray]]:
    """Sun-error-vector measurement (Step 4, k >= 2): ``Z_ps = (a . s^n)(a x s^n)``, ``a = C_b^{n'} s~^b``.

    Returns ``Z_ps`` (3,) and the two rows ``u_1, u_2`` (unit, perpendicular to ``s^n``) on which it is used:
    ``u_k^T Z_ps = u_k^T phi`` to first order (``H_ps = I - s s^T``). Invariant to the sign of ``s~^b``.
    """
    a = cbn @ s_meas_b
    z_vec = (a.dtype.type(float(a @ s_n)) * cross(a, s_n)).astype(a.dtype)
    return z_vec, plane_basis(s_n)


def polarization_error(cbn: FloatArray, p_meas_b: FloatArray, s_n: FloatArray) -> tuple[float, FloatArray]:
    """Polarization-error-vector measurement (Step 4, k = 1): ``z = s^n . (C_b^{n'} p~^b)``,
    ``H_pp = (s^n x p^n)^T`` on phi (docs/reference/algorithms.md 1.4); both flip with the sign of ``p~``."""
    p_n = cbn @ p_meas_b
    return float(s_n @ p_n), cross(s_n, p_n)


def pair_bias_covariance(s_b: FloatArray, e_i: FloatArray, e_j: FloatArray, ray_i: FloatArray, ray_j: FloatArray,
                         residual_var: float, installation_var: float) -> F64Array:
    """Covariance (3, 3, rad^2, body frame) of the bias ``mu`` of the sun vector a pair of units measures,
    ``s~ = (I + [mu x]) s`` (D-5.22): the calibration's constants of the two units, an E-vector residual ``a_i``
    (about the unit's ray, variance ``residual_var``) and an installation rotation ``w_i`` (per axis,
    ``installation_var``). As in D-5.19, ``dS . E_i = c_i`` with ``c_i = a_i S.(r_i x E_i) + w_i.(E_i x S)``, of
    variance ``v_i = residual_var sin^2 gamma_i + installation_var``, and ``dS = (c_i E_j x S + c_j S x E_i) / D``,
    ``D = S.(E_i x E_j)``; ``mu = S x dS`` (the part of the rotation that moves ``S``). Unit vectors in."""
    s = np.asarray(s_b, dtype=np.float64)
    ei, ej = np.asarray(e_i, dtype=np.float64), np.asarray(e_j, dtype=np.float64)
    a = cross(ej, s)
    b = cross(s, ei)
    d = float(s @ cross(ei, ej))
    v = [residual_var * float(s @ cross(np.asarray(r, dtype=np.float64), e)) ** 2 + installation_var
         for r, e in ((ray_i, ei), (ray_j, ej))]
    cov_s = (v[0] * np.outer(a, a) + v[1] * np.outer(b, b)) / max(d * d, 1e-12)
    k = skew(s)
    out: F64Array = k @ cov_s @ k.T
    return out


def pair_bias_cycles(c: c674x.KernelCosts) -> int:
    """:func:`pair_bias_covariance` and the reset of three rows and columns of P: four cross products, two outer
    products and two 3x3 products (about 110 MUL, 80 ADD), one division [D]."""
    return c.flops(110, 80) + c.math("div")


def discrimination_cycles(n: int, c: c674x.KernelCosts) -> int:
    """Steps 1-3 for ``n`` units: E-vector (sinsp, cossp, 6 MAC), ``s x r`` and ``p~ x p`` (12 MPY, 6 ADD),
    normalisation and length (rsqrt, sqrt), the threshold compare [S MATHLIB / D section 6]."""
    return n * (c.math("sin") + c.math("cos") + c.math("rsqrt") + c.math("sqrt")) + c.flops(24, 16, iterations=n)


@register_filter("dual_vector")
class DualVectorFilter(BaseFilter):
    """Base filter + the patent's switching polarization measurements (module docstring)."""

    #: the GNSS position-error states of the base filter (its GNSS updates are the base filter's; D-5.22); no
    #: solar-vector bias states (the compass update is not the base filter's solar vector) but three of its own:
    #: the sun-error-vector pair's bias ``mu`` (body rad, :func:`pair_bias_covariance`)
    augmentable = True
    solar_bias_augmentable = False
    own_states = 3

    def __init__(self, cfg: Any, meter: c674x.CycleMeter, dtype: FloatDtype) -> None:
        super().__init__(cfg, meter, dtype)
        self.p = cfg.variants.dual_vector
        self.mm = ModeManager("dual_vector", cfg.variants.mode_manager)
        self.counters = self.mm.counters
        m = cfg.compass_mountings if cfg.compass_mountings is not None else compass_unit_mountings()
        self.mountings = np.asarray(m, dtype=np.float64)
        self.rays_b = self.mountings[:, :, 2].astype(dtype)
        self.n_units = len(self.mountings)
        self.mode = PSNS_MODE_NONE
        self.q_flags = np.zeros(self.n_units, dtype=bool)
        self.lam: FloatArray = np.ones(self.n_units)
        self._aop_ref_rad, self._aop_residual_var, self._install_var = unit_error_figures(cfg)
        #: the pair whose bias the own states hold (None: no sun-error-vector update yet since initialise)
        self.pair: tuple[int, int] | None = None
        assert self.i_own is not None
        self._bias_tau_s = cfg.psns_bias_corr_time_s
        self._aug_rate[self.i_own:self.i_own + 3] = 1.0 / self._bias_tau_s

    def initialise(self, nav: NavState, heading_sigma_rad: float) -> None:
        super().initialise(nav, heading_sigma_rad)
        self.pair = None

    # -- reporting -------------------------------------------------------------------------------
    def drain_events(self) -> list[dict[str, Any]]:
        return self.mm.drain() if self.mm.events else []

    def variant_status(self) -> tuple[int, int, int] | None:
        mask = 0
        for i, qi in enumerate(self.q_flags.tolist()):
            if qi:
                mask |= 1 << i
        return self.mode, self.n_units, mask

    # -- the compass update ------------------------------------------------------------------------
    def update_compass(self, nav: NavState, frame: CompassFrame, t_exposure_s: float) -> UpdateReport | None:
        host = self.host
        assert host is not None
        mm, pm, cost = self.mm, self.mm.params, self.cost
        dt = self.dtype
        t = host.now_s()
        if frame.header.status & PsnsStatus.SUN_BELOW_HORIZON:
            mm.decide(t, "compass", False, "sun_below_horizon")
            return None
        days = host.utc_days(t_exposure_s)
        if days is None:
            mm.decide(t, "compass", False, "no_utc")
            return None
        p_ins, _, q_exp = host.ins_at(t_exposure_s)
        s_n = sun.sun_vector_enu(days, float(p_ins[0]), float(p_ins[1]), dtype=dt)
        self.meter.charge("sun_ephemeris", sun.ephemeris_cycles())
        if float(s_n[2]) < math.sin(pm.min_sun_elevation_deg * DEG):
            mm.decide(t, "compass", False, "sun_low", sun_elevation_deg=math.degrees(math.asin(float(s_n[2]))))
            return None
        cbn = q2mat_fast(q_exp).astype(dt)
        s_b = cbn.T @ s_n
        # per-unit data (units missing from the frame are saturated / not reported)
        n = self.n_units
        aop = np.zeros(n, dtype=dt)
        dop = np.zeros(n, dtype=dt)
        present = np.zeros(n, dtype=bool)
        for u in frame.units:
            if u.unit < n:
                aop[u.unit] = u.aop_cdeg * (0.01 * DEG)
                dop[u.unit] = u.dop * (1.0 / 65535.0)
                present[u.unit] = True
        p_meas = unit_evectors(aop, self.mountings, dt)
        _p_pred, lam, sin_g = discrimination_factors(p_meas, s_b, self.rays_b)
        self.meter.charge("dv_discrimination", discrimination_cycles(n, cost))
        q = np.zeros(n, dtype=bool)
        min_sin_g = math.sin(self.p.min_scattering_deg * DEG)
        for i in range(n):
            ch = f"compass_unit{i}"
            li = float(lam[i])
            if not present[i]:
                mm.decide(t, ch, False, "missing_from_frame")
            elif dop[i] < pm.dop_min:
                mm.decide(t, ch, False, "low_dop", dop=float(dop[i]), dop_min=pm.dop_min)
            elif sin_g[i] < min_sin_g:
                mm.decide(t, ch, False, "sun_near_view_ray", scattering_deg=math.degrees(math.asin(float(sin_g[i]))))
            elif li >= self.p.tp:
                mm.decide(t, ch, False, "discrimination_factor_above_tp", factor=li, tp=self.p.tp)
            else:
                q[i] = mm.decide(t, ch, True, "discrimination_factor_below_tp", factor=li, tp=self.p.tp)
        self.q_flags = q
        self.lam = lam
        k = int(np.count_nonzero(q))
        mm.report(t, "psns_quality", [int(x) for x in q.tolist()], "information_discrimination",
                  factors=[round(float(x), 5) for x in lam.tolist()], tp=self.p.tp, reliable=k)
        mode = PSNS_MODE_SUN if k >= 2 else PSNS_MODE_POLARIZATION if k == 1 else PSNS_MODE_NONE
        reason = {PSNS_MODE_SUN: "two_or_more_reliable_sensors", PSNS_MODE_POLARIZATION: "one_reliable_sensor",
                  PSNS_MODE_NONE: "no_reliable_sensor"}[mode]
        self.mode = mode
        mm.set_mode(t, "psns_mode", MODE_NAMES[mode], reason, q=[int(x) for x in q.tolist()], reliable=k,
                    t_meas_s=t_exposure_s)
        if mode == PSNS_MODE_NONE:
            return UpdateReport("compass", False, 0, 0.0, {"reason": "no_reliable_sensor", "mode": "none"})
        sig = self._unit_sigmas(dop)
        if mode == PSNS_MODE_SUN:
            return self._sun_update(t, cbn, s_n, p_meas, q, sig)
        i = int(np.nonzero(q)[0][0])
        # the calibration's E-vector residual of the unit turns it about its ray like the AOP noise
        sig_aop = math.sqrt(float(sig[i]) ** 2 + self._aop_residual_var)
        return self._polarization_update(t, cbn, s_n, p_meas[i], self.rays_b[i], sig_aop, i)

    def _unit_sigmas(self, dop: FloatArray) -> FloatArray:
        """AOP noise (rad, 1 sigma) per unit from the spec sheet: ``sigma_ref * dop_ref / DOP`` (D-5.22), at least
        ``sigma_floor_deg``. The calibration's residuals are constants, not in here: the pair's bias states carry
        them in the sun-error-vector mode, the polarization mode adds them to its R."""
        sigmas: FloatArray = np.maximum(self._aop_ref_rad / np.maximum(dop, 1e-3), self.p.sigma_floor_deg * DEG)
        return sigmas

    def _pair_prior(self, pair: tuple[int, int], s_b: FloatArray, e_i: FloatArray, e_j: FloatArray) -> None:
        """A new pair: its bias states restart from zero with :func:`pair_bias_covariance` as their prior, uncorrelated
        with the rest, and their process noise that of a Gauss-Markov of ``psns_bias_corr_time_s`` with it."""
        k = self.i_own
        assert k is not None
        cov = pair_bias_covariance(s_b, e_i, e_j, self.rays_b[pair[0]], self.rays_b[pair[1]],
                                   self._aop_residual_var, self._install_var)
        P = self.P
        P[k:k + 3, :] = 0.0
        P[:, k:k + 3] = 0.0
        P[k:k + 3, k:k + 3] = cov.astype(P.dtype)
        self.x[k:k + 3] = 0.0
        q = self.q.copy()
        q[k:k + 3] = 2.0 * float(np.trace(cov)) / 3.0 / self._bias_tau_s
        self.q, self._qk_interval = q, math.nan
        self.pair = pair
        self.meter.charge("dv_pair_bias_prior", pair_bias_cycles(self.cost))

    def _sun_update(self, t: float, cbn: FloatArray, s_n: FloatArray, p_meas: FloatArray, q: FloatArray,
                    sig: FloatArray) -> UpdateReport:
        """Sun-error-vector mode: ``Z = (a.s)(a x s)``, ``a = C_b^{n'} s~^b``, projected on u1, u2 (module doc)."""
        dt = self.dtype
        idx = np.nonzero(q)[0].tolist()
        best = None
        best_n = -1.0
        for a_i in range(len(idx)):
            for b_i in range(a_i + 1, len(idx)):
                i, j = idx[a_i], idx[b_i]
                c = cross(p_meas[i], p_meas[j])
                nn = float(c @ c)
                if nn > best_n:
                    best, best_n = (i, j, c), nn
        assert best is not None
        i, j, c = best
        sin_ij = math.sqrt(best_n)
        n_pairs = len(idx) * (len(idx) - 1) // 2
        self.meter.charge("dv_pair_select", self.cost.flops(6, 3, iterations=n_pairs))
        if sin_ij < self.p.min_pair_sine:
            self.mm.decide(t, "sun_vector", False, "ill_conditioned_pair", pair=[i, j], sine=sin_ij,
                           min_sine=self.p.min_pair_sine)
            return UpdateReport("compass", False, 0, 0.0, {"reason": "ill_conditioned_pair", "mode": "sun"})
        s_meas_b = (c / dt(sin_ij)).astype(dt)
        if (i, j) != self.pair:
            self._pair_prior((i, j), s_meas_b, p_meas[i], p_meas[j])
        z_vec, (u1, u2) = sun_error_vector(cbn, s_meas_b, s_n)
        self.meter.charge("dv_sun_residual", self.cost.flops(40, 30) + self.cost.math("rsqrt", 2))
        # noise of s~ from the two AOP errors through the cross product (perpendicular to s)
        sigma = math.sqrt(float(sig[i]) ** 2 + float(sig[j]) ** 2) / sin_ij
        r = max(sigma, self.p.sigma_floor_deg * DEG) ** 2
        # Z = (I - s s^T)(phi - C_b^n mu) on u1, u2: the attitude and the pair's bias columns, the rest zero
        k = self.i_own
        assert k is not None
        rows = []
        for u in (u1, u2):
            h = np.zeros(self.n, dtype=dt)
            h[IDX_ATT] = u
            h[k:k + 3] = -(u @ cbn)
            rows.append((h, float(u @ z_vec)))
        # the innovation, as the update forms it: the pair's bias states carry their estimate between updates
        nis = sum((zk - float(h @ self.x)) ** 2 / (float(h @ self.P @ h) + r) for h, zk in rows)
        self.meter.charge("dv_gate", self.cost.flops(30, 24))
        resid = math.degrees(math.sqrt(float(z_vec @ z_vec)))
        if not self.mm.gate(t, "sun_vector", nis, 2, pair=[i, j], residual_deg=resid):
            return UpdateReport("compass", False, 0, math.sqrt(nis), {"reason": "chi2_fail", "mode": "sun",
                                                                        "residual_deg": resid})
        innov = [self._scalar(h, zk, r) for h, zk in rows]
        self.meter.charge("kf_update", 2 * self._cyc_update)
        return UpdateReport("compass", True, 2, max(abs(v) for v in innov),
                            {"mode": "sun", "pair": [i, j], "residual_deg": resid})

    def _polarization_update(self, t: float, cbn: FloatArray, s_n: FloatArray, p_b: FloatArray, r_b: FloatArray,
                             sig_aop: float, unit: int) -> UpdateReport:
        """Polarization-error-vector mode: ``z = s^n . (C_b^{n'} p~)``, ``H = [(s^n x p^n)^T, 0]``."""
        dt = self.dtype
        z, hrow = polarization_error(cbn, p_b, s_n)
        p_n = cbn @ p_b
        r_n = cbn @ r_b.astype(dt)
        # AOP error dA turns p~ about the ray: dz = dA s.(r x p); the unit's installation residual w (per axis)
        # turns it about every axis: dz = -s.(w x p) = w.(s x p), variance sigma_w^2 |s x p|^2 (D-5.22)
        sp = cross(s_n, p_n)
        var_z = (sig_aop * float(s_n @ cross(r_n, p_n))) ** 2 + self._install_var * float(sp @ sp)
        r = max(math.sqrt(var_z), 0.1 * self.p.sigma_floor_deg * DEG) ** 2
        Pa = self.P[IDX_ATT, IDX_ATT]
        var = float(hrow @ Pa @ hrow) + r
        nis = z * z / var
        self.meter.charge("dv_pol_residual", self.cost.flops(36, 24) + self.cost.flops(12, 9))
        if not self.mm.gate(t, "polarization_vector", nis, 1, unit=unit, residual=z):
            return UpdateReport("compass", False, 0, math.sqrt(nis), {"reason": "chi2_fail", "mode": "polarization"})
        h = np.zeros(self.n, dtype=dt)
        h[IDX_ATT] = hrow
        nu = self._scalar(h, z, r)
        self.meter.charge("kf_update", self._cyc_update)
        return UpdateReport("compass", True, 1, abs(nu), {"mode": "polarization", "unit": unit})
