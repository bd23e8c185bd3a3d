"""The GNSS measurement model of the error-state KF: the fix as the loop hands it over (:class:`GnssMeasurement`), the
scale of its sigmas from the receiver's HDOP and GST (:func:`gnss_dop_scale`, :func:`gnss_fix_scale`; D-5.42,
D-5.51), its scalar rows (:func:`gnss_measurement_rows`, Eqs. 23-30) and the augmented Gauss-Markov states of the
receiver's correlated position error (:class:`GnssErrorStates`, D-5.12, D-5.17).

Units and frames: position (lat, lon rad, h m) and its residual in metres (``R_Mh dL``, ``R_Nh cos L dlambda``,
``dh``), velocity ENU m/s, sigmas in m and m/s, R in m^2 and (m/s)^2, the error states ``b = [b_E b_N b_U]`` in m;
times in s on the FPGA time base. Shared by every filter with GNSS updates (the base filter, its variants, the
federated SINS/GNSS sub-filter).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from .. import c674x, earth
from ..arrays import F64Array, FloatArray
from ..config import FirmwareConfig
from ..kf import D_H, D_LAT, D_LON, DV_E, DV_N, DV_U

__all__ = [
    "GnssErrorStates",
    "GnssMeasurement",
    "gnss_corr_sigmas",
    "gnss_dop_scale",
    "gnss_fix_scale",
    "gnss_measurement_rows",
]


@dataclass
class GnssMeasurement:
    """A GNSS fix, time-tagged at its PPS edge (FPGA time base).

    ``pos`` = (lat rad, lon rad, h m) or None; ``vel`` = ENU m/s (3,) or None; ``vel_up`` tells
    whether ``vel[2]`` was measured (UBX NAV-PVT velD) or is absent (NMEA RMC).
    """

    t_fpga_s: float
    pos: tuple[float, float, float] | None = None
    vel: FloatArray | None = None
    vel_up: bool = False
    #: False: a 2-D fix (horizontal position only; ``pos[2]`` is no measurement)
    pos_up: bool = True
    quality: int = 1
    sigma_pos_h_m: float | None = None
    sigma_pos_v_m: float | None = None
    sigma_vel_mps: float | None = None
    #: the receiver's HDOP (GGA / GNS) when it reported one: scales the sigmas (:func:`gnss_dop_scale`, D-5.42)
    hdop: float | None = None
    #: the receiver's own estimate of its horizontal position error per axis (GST latitude and longitude error,
    #: m, 1 sigma) when it sent one: scales the sigmas too (:func:`gnss_fix_scale`, D-5.51)
    reported_sigma_h_m: float | None = None
    #: satellites used (GGA / GNS / NAV-PVT) when reported: 4 or fewer leave no residual (:func:`gnss_fix_scale`)
    num_sats: int | None = None
    #: the receiver's PDOP (NAV-PVT pDOP) when it reported no HDOP: the 4-satellite rule's geometry, an upper bound
    #: of the HDOP (PDOP^2 = HDOP^2 + VDOP^2), so never narrower than the HDOP would give
    pdop: float | None = None


def gnss_dop_scale(cfg: FirmwareConfig, hdop: float | None) -> float:
    """The factor (>= 1) on the GNSS sigmas of a fix whose receiver reports ``hdop`` (D-5.42): ``sigma = DOP x
    UERE`` (Kaplan & Hegarty 2017, ch. 7), so a geometry worse than the one the sheet's figures hold at
    (``cfg.gnss_hdop_ref``) widens position and velocity alike: ``max(1, hdop / hdop_ref)``. The sheet's figures are
    the floor: a better geometry never narrows them. 1 without a reference or without a usable HDOP (a NAV-PVT-only
    stream, an empty field). Cost: one ``divsp`` per fix, charged by the caller."""
    ref = cfg.gnss_hdop_ref
    if ref <= 0.0 or hdop is None or not math.isfinite(hdop) or hdop <= 0.0:
        return 1.0
    return max(1.0, hdop / ref)


def gnss_fix_scale(cfg: FirmwareConfig, meas: GnssMeasurement) -> float:
    """The factor (>= 1) on every GNSS sigma of the fix ``meas`` (D-5.51): the larger of the geometry's
    (:func:`gnss_dop_scale`) and the receiver's own estimate of its horizontal error (GST, per axis) over the sheet's
    horizontal figure, ``reported_sigma_h_m / gnss_pos_sigma_h_m``. A receiver sees its multipath in its
    pseudorange residuals where the HDOP cannot show it (a street canyon); the sheet stays the floor. A fix from 4
    satellites or fewer has no residual to show it: the sheet's ``gnss_unverified_multipath_m`` (a range error)
    through the fix's HDOP is added in quadrature, ``k^2 + (HDOP m / sqrt(2) / sheet)^2`` (a NAV-PVT fix, which
    reports no HDOP, through its PDOP: an upper bound). Cost: one more
    ``divsp`` when the fix carries GST, charged by the caller."""
    k = gnss_dop_scale(cfg, meas.hdop)
    sheet = cfg.gnss_pos_sigma_h_m
    r = meas.reported_sigma_h_m
    if r is not None and math.isfinite(r) and r > 0.0 and sheet > 0.0:
        k = max(k, r / sheet)
    mp, n = cfg.gnss_unverified_multipath_m, meas.num_sats
    hdop = meas.hdop if meas.hdop is not None else meas.pdop  # NAV-PVT: PDOP >= HDOP, the conservative side
    if mp > 0.0 and n is not None and n <= 4 and hdop is not None and math.isfinite(hdop) and hdop > 0.0 \
            and sheet > 0.0:
        # no fifth satellite: the receiver's residuals cannot show its multipath, so the sheet's is assumed
        k = math.sqrt(k * k + (hdop * mp / math.sqrt(2.0) / sheet) ** 2)
    return k


def gnss_corr_sigmas(cfg: FirmwareConfig) -> tuple[float, float]:
    """Sigmas (m, horizontal per axis and vertical) of the time-correlated GNSS position error: the spec's
    total less its white part, in quadrature (D-5.12)."""
    h = math.sqrt(max(cfg.gnss_pos_sigma_h_m**2 - cfg.gnss_pos_white_sigma_h_m**2, 0.0))
    v = math.sqrt(max(cfg.gnss_pos_sigma_v_m**2 - cfg.gnss_pos_white_sigma_v_m**2, 0.0))
    return h, v


class GnssErrorStates:
    """The three augmented Gauss-Markov states of the correlated GNSS position error ``b = [b_E b_N b_U]`` (m) at
    state index ``i`` (docs/decisions/filter-consistency.md D-5.12, D-5.17), declared once for every filter that
    carries them (the base filter, the federated SINS/GNSS sub-filter).

    ``db/dt = -b / tau + w``, ``q = 2 sigma_c^2 / tau`` (sigma_c from :func:`gnss_corr_sigmas`); the position rows
    become ``z = p_INS - p_GNSS = dp - b`` with ``R`` the white part only; P0 correlates the first fix's position
    error with ``b``; a fix after a gap longer than ``gnss_relock_gap_s`` re-draws them. A fix reporting a worse
    geometry scales the error's variance by ``level = k^2`` (:func:`gnss_dop_scale`, D-5.42): its white ``R``, the
    states' process noise and, when the level rises, their variance (:meth:`set_level`)."""

    #: state offset of each position row's error component: E for dlambda, N for dL, U for dh
    ROW_OFFSET: ClassVar[dict[int, int]] = {D_LON: 0, D_LAT: 1, D_H: 2}

    def __init__(self, cfg: FirmwareConfig, i: int) -> None:
        self.cfg = cfg
        self.i = i
        sc_h, sc_v = gnss_corr_sigmas(cfg)
        #: stationary variances (m^2, E N U) and the decay rate (1/s)
        self.var = np.array([sc_h**2, sc_h**2, sc_v**2])
        self.tau = cfg.gnss_pos_corr_time_s
        self.rate = 1.0 / self.tau
        #: FPGA time of the last position fix (s), for the loss-of-lock re-draw
        self.t_last_fix: float | None = None
        #: the variance scale of the receiver's error at the last fix (``k^2`` of :func:`gnss_dop_scale`; 1: the sheet)
        self.level = 1.0

    @property
    def psd(self) -> F64Array:
        """Process-noise PSD (m^2/s) of the three states: ``2 level sigma_c^2 / tau``."""
        return 2.0 * self.level * self.var / self.tau

    def set_level(self, P: FloatArray, level: float, prior: tuple[float, float] | None = None) -> bool:
        """The receiver's error variance is now ``level`` times the sheet's (D-5.42). When it rises, the correlated
        error that the states hold gains the difference ``d = level - old``: ``d var`` on their diagonal (an
        independent addition: ``P`` stays positive semi-definite); when it falls, the states keep their variance and
        decay towards the new stationary level through their smaller process noise. ``prior = (R_Mh, R_Nh cos L)``
        (m) on the first fix after :meth:`set_prior`: the position prior came from a fix of the same geometry (the
        alignment's), so it rises with it as :meth:`set_prior` would have set it at this level: the position
        variance by ``d`` times the sheet's total (``gnss_pos_sigma_*``), its covariance with the states by ``d var``
        (per axis ``[[d s^2, d v], [d v, d v]]``, positive semi-definite since ``s^2 >= v``). True when the level
        changed (the caller updates its process noise from :attr:`psd`)."""
        if level == self.level:
            return False
        d = level - self.level
        if d > 0.0:
            i = self.i
            idx = np.arange(i, i + 3)
            P[idx, idx] += (d * self.var).astype(P.dtype)
            if prior is not None:
                rmh, rnh_cl = prior
                sh, sv = self.cfg.gnss_pos_sigma_h_m, self.cfg.gnss_pos_sigma_v_m
                for pos_idx, off, scale, s in ((D_LON, 0, 1.0 / rnh_cl, sh), (D_LAT, 1, 1.0 / rmh, sh),
                                               (D_H, 2, 1.0, sv)):
                    P[pos_idx, pos_idx] += d * s * s * scale * scale
                    c = d * float(self.var[off]) * scale
                    P[pos_idx, i + off] += c
                    P[i + off, pos_idx] += c
        self.level = level
        return True

    def set_prior(self, P: F64Array, rmh: float, rnh_cl: float) -> None:
        """Stationary variances on the diagonal and the first fix's correlation with the position states:
        the position comes from a fix, ``dp = b + w``, so ``cov(dp, b) = var(b)`` (in the states' units:
        ``dL = dN / R_Mh``, ``dlambda = dE / (R_Nh cos L)``)."""
        i = self.i
        self.level = 1.0
        P[i:i + 3, i:i + 3] = np.diag(self.var)
        for pos_idx, off, scale in ((D_LON, 0, 1.0 / rnh_cl), (D_LAT, 1, 1.0 / rmh), (D_H, 2, 1.0)):
            P[pos_idx, i + off] = P[i + off, pos_idx] = self.var[off] * scale

    def position_row(self, h: FloatArray, idx: int) -> float:
        """Put ``-1`` for the GNSS error of position row ``idx`` into ``h``; the row's R (m^2), the white part."""
        h[self.i + self.ROW_OFFSET[idx]] = -1.0
        w = self.cfg.gnss_pos_white_sigma_v_m if idx == D_H else self.cfg.gnss_pos_white_sigma_h_m
        return w * w * self.level

    def relock(self, x: FloatArray, P: FloatArray, t_fix: float) -> bool:
        """After a loss of lock (no position fix for more than ``gnss_relock_gap_s``) the receiver's correlated error is
        a fresh draw (D-5.17): the states restart from zero with their stationary variance and no correlation with
        the other states (``x``, ``P`` in place). Without this, the Gauss-Markov keeps ``exp(-gap / tau)`` of its
        pre-outage estimate and correlation, and the filter puts the re-acquisition jump into position and vertical
        velocity. True when it re-drew (the caller counts and charges ``6 n`` adds)."""
        gap, last = self.cfg.gnss_relock_gap_s, self.t_last_fix
        self.t_last_fix = t_fix
        if gap <= 0.0 or last is None or t_fix - last <= gap:
            return False
        i = self.i
        x[i:i + 3] = 0.0
        P[i:i + 3, :] = 0.0
        P[:, i:i + 3] = 0.0
        P[i:i + 3, i:i + 3] = np.diag(self.level * self.var).astype(P.dtype)
        return True


def gnss_measurement_rows(cfg: FirmwareConfig, meter: c674x.CycleMeter, meas: GnssMeasurement,
                          p_ins: FloatArray, v_ins: FloatArray) -> list[tuple[int, float, float, float]]:
    """The scalar rows of a GNSS update: ``(state index, H value, z, R)`` per measured component.

    Position (Eq. 23-24): ``Z_p = [R_Mh dL, R_Nh cosL dlambda, dh]`` (m), ``H_p = [0 diag(R_Mh, R_Nh cosL, 1) 0]``,
    charging the residual's cycles on ``meter``; velocity (Eq. 28-30): ``Z_v = v_INS - v_GNSS`` (ENU m/s),
    ``H_v = [0 I 0]``, the vertical only when measured (UBX velD). ``p_ins`` = (lat rad, lon rad, h m) and
    ``v_ins`` (ENU m/s) are the INS at the fix's time of validity. Shared by every filter with GNSS updates.
    Every R is the sheet's times ``k^2``, ``k`` from the fix's HDOP and GST (:func:`gnss_fix_scale`, D-5.42, D-5.51).
    """
    rows: list[tuple[int, float, float, float]] = []
    k2 = gnss_fix_scale(cfg, meas) ** 2
    if cfg.gnss_hdop_ref > 0.0 and meas.hdop is not None:
        meter.charge("gnss_dop_scale", c674x.mathlib("divsp") + c674x.flops(1, 0))
    if meas.reported_sigma_h_m is not None:
        meter.charge("gnss_reported_scale", c674x.mathlib("divsp") + c674x.flops(1, 0))
    if meas.pos is not None:
        lat = float(p_ins[0])
        rm, rn = earth.radii(lat)
        rmh, rnh = rm + float(p_ins[2]), rn + float(p_ins[2])
        cl = math.cos(lat)
        sh = meas.sigma_pos_h_m or cfg.gnss_pos_sigma_h_m
        sv = meas.sigma_pos_v_m or cfg.gnss_pos_sigma_v_m
        rows += [
            (D_LAT, rmh, (float(p_ins[0]) - meas.pos[0]) * rmh, sh**2 * k2),
            (D_LON, rnh * cl, (float(p_ins[1]) - meas.pos[1]) * rnh * cl, sh**2 * k2),
        ]
        if meas.pos_up:
            rows.append((D_H, 1.0, float(p_ins[2]) - meas.pos[2], sv**2 * k2))
        meter.charge("gnss_residual", c674x.dp_flops(8, 6) + c674x.mathlib("cosdp") + c674x.mathlib("sqrtdp")
                     + c674x.mathlib("divdp"))
    if meas.vel is not None:
        svh = meas.sigma_vel_mps or cfg.gnss_vel_sigma_h_mps
        rows.append((DV_E, 1.0, float(v_ins[0]) - float(meas.vel[0]), svh**2 * k2))
        rows.append((DV_N, 1.0, float(v_ins[1]) - float(meas.vel[1]), svh**2 * k2))
        if meas.vel_up:
            rows.append((DV_U, 1.0, float(v_ins[2]) - float(meas.vel[2]), cfg.gnss_vel_sigma_v_mps**2 * k2))
    return rows
