"""The solar-vector measurement model of the error-state KF: the PSNS fix as the loop hands it over
(:class:`SolarObservation`), its noise from the solve's own quality (:func:`solar_noise_variance`), its NIS across
the sun with two degrees of freedom (:data:`SOLAR_VECTOR_DOF`, :func:`solar_fix_nis`; D-5.32) and the augmented
states of the systematic solar-vector error (:class:`SolarBiasStates`, D-5.13, D-5.16, D-5.33).

Units and frames: the solar vector is a unit vector in the body frame (``s_b``) or the local-level ENU frame n
(``S^n``); its residual ``Z = S^n - C_b^{n'} S^b`` and the bias ``mu`` are small angles in rad (local-level n with a
sky figure, else body axes), variances in rad^2 per axis, times in s, heading turns in rad. Shared by every filter
with solar-vector updates (the base filter, its variants, the federated MIMU/polarization sub-filter).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from .. import c674x
from ..arrays import F64Array, FloatArray
from ..config import FirmwareConfig
from ..units import DEG

__all__ = [
    "SOLAR_VECTOR_DOF",
    "SolarBiasStates",
    "SolarObservation",
    "solar_fix_nis",
    "solar_noise_variance",
]


@dataclass
class SolarObservation:
    """A bi-direction solar vector in the body frame at its mid-exposure time."""

    t_exposure_s: float
    s_b: FloatArray
    quality: float
    n_used: int
    source: str  # "camera" (firmware solve) or "sensor" (on-sensor solve)


def solar_noise_variance(cfg: FirmwareConfig, quality: float, n_used: int) -> float:
    """Variance (rad^2 per axis) of a solved solar vector from the solve's own quality (docs/decisions/
    filter-consistency.md): with ``K = sum w E E^T`` and per-point misfit of variance ``sigma_e^2``,
    ``lambda_min ~ W sigma_e^2`` and ``lambda_j ~ W c_j``; first-order perturbation of the smallest eigenvector gives
    ``var_j = sigma_e^2 / (n c_j) = lambda_min / (n lambda_j)`` along the other eigenvectors. ``psns_noise_scale``
    absorbs the points' correlation (neighbouring pixels see the same sky); the spec sheet's floor bounds it below."""
    floor = (cfg.psns_sigma_deg * DEG) ** 2
    if n_used <= 0 or not math.isfinite(quality):
        return floor
    return max(floor, cfg.psns_noise_scale * max(quality, 0.0) / n_used)


#: degrees of freedom of one solar-vector fix: the residual of two unit vectors ``Z = S^n - C_b^{n'} S^b`` has no
#: first-order part along ``S^n`` (``(S^n)^T [S^n x] = 0``), so its three rows carry two (D-5.32)
SOLAR_VECTOR_DOF = 2


def solar_fix_nis(norm_innovs: Sequence[float], z_along_sun: float, r: float) -> float:
    """NIS of one solar-vector fix in the plane across the sun (``SOLAR_VECTOR_DOF`` = 2 dof; D-5.32) from its three
    sequential scalar rows of noise ``r`` (rad^2 each, ``R = r I``).

    The rows' normalised innovations ``nu_i / sqrt(s_i)`` sum in squares to ``nu^T S^-1 nu`` with
    ``S = H P H^T + r I`` (sequential scalar updates with a diagonal R). Every row of ``H`` is orthogonal to ``S^n``
    (the attitude columns ``-[S^n x]``, the solar-bias columns ``[S^n x]`` or ``[S^n x] C_b^n``), so ``S S^n = r S^n``
    and the NIS splits into the part along the sun, ``(nu . S^n)^2 / r = (Z . S^n)^2 / r``, and the part across it,
    chi-square with 2 dof for a consistent filter. The part along the sun is no noise: for unit vectors
    ``Z . S^n = 1 - cos(err)`` is second order in the angle ``err`` between them (1 deg between the two vectors gives
    a NIS of 3 along the sun at ``r`` = (0.005 deg)^2, the ``field`` sheet's floor), and it changes no state
    (``H^T S^n = 0``). Returns ``sum (nu_i^2 / s_i) - (Z . S^n)^2 / r`` (>= 0)."""
    total = math.fsum(v * v for v in norm_innovs)
    along = z_along_sun * z_along_sun / r if r > 0.0 else 0.0
    return max(total - along, 0.0)


class SolarBiasStates:
    """The three augmented states of the systematic solar-vector error ``mu`` (rad) at state index ``i``
    (docs/decisions/filter-consistency.md D-5.13, D-5.16), declared once for every filter that carries them (the base
    filter, the federated MIMU/polarization sub-filter).

    With a sky figure (``psns_sky_bias_deg`` > 0) ``mu`` is the solved sun's rotation in the local-level frame,
    ``S^n measured = (I + [mu x]) S^n``, ``Z = -[S^n x] phi + [S^n x] mu``, of stationary covariance
    ``(m^2 + s^2) I + (s_el^2 - s^2) u u^T`` with ``u = z x S^n / |z x S^n|`` across the solar meridian (set at the
    first solar update, :meth:`set_axis`); without, a body-frame rotation ``s_b measured = (I + [mu x]) s_b``,
    ``Z = -[S^n x] phi + [S^n x] C_b^n mu``, isotropic. First-order Gauss-Markov of ``psns_bias_corr_time_s``
    (local-level: ``psns_sky_corr_time_s`` when stated, and in the heading turned, D-5.33)."""

    def __init__(self, cfg: FirmwareConfig, i: int) -> None:
        self.cfg = cfg
        self.i = i
        self.sigma2 = (cfg.psns_bias_sigma_deg * DEG) ** 2
        sky2 = (cfg.psns_sky_bias_deg * DEG) ** 2
        #: the sky's variance (rad^2 per axis across the sun) and the isotropic rest (camera mount)
        self.sky2 = sky2
        #: the sky's variance along the solar meridian (rad^2): the elevation figure, or D-5.16's ``2 s^2``
        self.sky_el2 = (cfg.psns_sky_bias_el_deg * DEG) ** 2 if cfg.psns_sky_bias_el_deg > 0 else 2.0 * sky2
        self.iso2 = max(self.sigma2 - sky2, 0.0)
        #: correlation time (s): the local-level sky figure when the states are shaped and it is stated (D-5.33)
        self.tau = (cfg.psns_sky_corr_time_s if sky2 > 0.0 and cfg.psns_sky_corr_time_s > 0.0
                    else cfg.psns_bias_corr_time_s)
        self.rate = 1.0 / self.tau
        #: the local-level states' decorrelation per radian of heading turned (1/rad; 0: none), across the solar
        #: meridian and along it (the elevation): a turn shows the camera another part of the sky (D-5.33)
        self.turn_rate = 1.0 / (cfg.psns_sky_turn_corr_deg * DEG) if cfg.psns_sky_turn_corr_deg > 0 else 0.0
        el_deg = cfg.psns_sky_turn_corr_el_deg or cfg.psns_sky_turn_corr_deg
        self.turn_rate_el = 1.0 / (el_deg * DEG) if el_deg > 0 else 0.0
        #: the body x axis's azimuth at the last :meth:`turn` (rad; None until the first)
        self.heading: float | None = None
        #: horizontal n-frame axis across the solar meridian (z x s_n, from the last solar update; None until the first)
        self.axis_n: F64Array | None = None

    @property
    def psd(self) -> F64Array:
        """Isotropic process-noise PSD (rad^2/s) of the three states: ``2 sigma^2 / tau``."""
        return np.full(3, 2.0 * self.sigma2 / self.tau)

    def cov(self) -> F64Array:
        """Stationary covariance (rad^2, local-level frame): ``(m^2 + s^2) I + (s_el^2 - s^2) u u^T`` (D-5.16,
        D-5.33; ``s_el^2 = 2 s^2`` when the sheet states no elevation figure)."""
        u = self.axis_n
        assert u is not None
        return (self.iso2 + self.sky2) * np.eye(3) + (self.sky_el2 - self.sky2) * np.outer(u, u)

    def reset(self, P: FloatArray) -> None:
        """The states before the first solar update, set at every (re)initialisation of the filter that carries
        them: the isotropic prior ``sigma^2 I`` in ``P``'s block, no solar-meridian axis yet (:meth:`set_axis`), no
        heading for :meth:`turn`."""
        i = self.i
        P[i:i + 3, i:i + 3] = np.diag(np.full(3, self.sigma2))
        self.axis_n = None
        self.heading = None

    def noise_block(self, Tk: float, turn_rad: float = 0.0) -> F64Array:
        """Q_k block (3, 3) over ``Tk`` s and a heading turn of ``turn_rad`` once the sun is known: ``2 T_k / tau``
        times :meth:`cov`, plus, for a turn, ``2 |d psi| / psi_c`` times the covariance's part across the meridian
        and ``2 |d psi| / psi_c,el`` times its part along ``u`` (a Gauss-Markov in time and in the angle turned,
        each axis with its own turn figure, D-5.33; :meth:`decay_block` is its ``Phi``). Cost: 9 multiplies and
        6 adds (``kf_sun_bias_noise``), 15 and 12 with a turn."""
        q = (2.0 * Tk / self.tau) * self.cov()
        if turn_rad > 0.0:
            u = self.axis_n
            assert u is not None
            uu = np.outer(u, u)
            q += 2.0 * turn_rad * (self.turn_rate * (self.iso2 + self.sky2) * (np.eye(3) - uu)
                                   + self.turn_rate_el * (self.iso2 + self.sky_el2) * uu)
        return q

    def decay_block(self, turn_rad: float) -> F64Array:
        """The decay over a heading turn of ``turn_rad`` (3, 3), subtracted from the states' diagonal block of
        ``Phi``: ``|d psi| (I / psi_c + (1 / psi_c,el - 1 / psi_c) u u^T)`` (``u`` unknown before the first solar
        update: isotropic)."""
        d = turn_rad * self.turn_rate * np.eye(3)
        if self.axis_n is not None:
            d += turn_rad * (self.turn_rate_el - self.turn_rate) * np.outer(self.axis_n, self.axis_n)
        return d

    def turn(self, cbn: FloatArray) -> float:
        """The heading turned (rad, >= 0) since the last call: the change of the body x axis's azimuth in the
        local-level frame, ``atan2(C_b^n[0, 0], C_b^n[1, 0])``, wrapped (0 at the first call, and always without a
        turn figure). Its decay (:meth:`decay_block`) joins ``T_k / tau`` on the states' diagonal of ``Phi``."""
        if self.turn_rate == 0.0:
            return 0.0
        h = math.atan2(float(cbn[0, 0]), float(cbn[1, 0]))
        last, self.heading = self.heading, h
        if last is None:
            return 0.0
        return abs((h - last + math.pi) % (2.0 * math.pi) - math.pi)

    def decay_over_turn(self, Phi: FloatArray, cbn: FloatArray, meter: c674x.CycleMeter,
                        cost: c674x.KernelCosts) -> float:
        """Subtract the decay over the heading turned since the last call (:meth:`turn`, :meth:`decay_block`) from
        the states' diagonal block of ``Phi`` in place, when the sky's error is shaped and has a turn figure (D-5.33);
        return the turn (rad; 0 otherwise), which the states' Q (:meth:`noise_block`) takes too. Cost: an ``atan2``
        and 12 multiplies, 12 adds (``solar_bias_turn``)."""
        if not (self.shaped and self.turn_rate > 0.0):
            return 0.0
        turn = self.turn(cbn)
        i = self.i
        Phi[i:i + 3, i:i + 3] -= self.decay_block(turn).astype(Phi.dtype)
        meter.charge("solar_bias_turn", cost.math("atan2") + c674x.flops(12, 12))
        return turn

    @property
    def shaped(self) -> bool:
        """True when the sky's error is modelled across the solar meridian (local-level states, a sky figure)."""
        return self.sky2 > 0.0

    def set_axis(self, s_n: FloatArray, P: FloatArray) -> bool:
        """Keep the n-frame axis across the solar meridian; at the first solar update give the states their prior in
        that shape in ``P`` (until then the states are uncorrelated with every other state, so this is the P0 the
        filter would have set knowing the sun; a federated sub-filter does not share it by ``1 / beta``, D-5.32). False
        (nothing done) with the sun at the zenith. Cost: 4 multiplies, 2 adds, a reciprocal square root
        (``solar_bias_axis``)."""
        e, nn = float(s_n[0]), float(s_n[1])
        norm = math.hypot(e, nn)
        if norm < 1e-3:  # sun at the zenith: no meridian
            return False
        first = self.axis_n is None
        self.axis_n = np.array([-nn / norm, e / norm, 0.0])
        if first:
            i = self.i
            P[i:i + 3, i:i + 3] = self.cov().astype(P.dtype)
        return True

    def rows(self, H: FloatArray, h_att: FloatArray, cbn: FloatArray) -> None:
        """Fill the states' columns of the solar rows ``H`` (3, n) from their attitude columns ``h_att = -[S^n x]``:
        ``[S^n x]`` (local-level states) or ``[S^n x] C_b^n`` (body states)."""
        if self.shaped:
            H[:, self.i:self.i + 3] = -h_att
        else:
            H[:, self.i:self.i + 3] = -h_att @ cbn
