"""K-means sun finding + 3-D attitude (Yang, Wang, Wang, Hu 2020, *Laser & Optoelectronics Progress* 57(22)).

Pipeline on each POLARIZATION_OBS frame of an all-sky (fisheye) camera:

1. **View rays** of the observation points (camera model of docs/architecture.md "Conventions"), the sky mask: points
   whose ray is below
   ``horizon_mask`` elevation according to the INS tilt are left out (the ground is unpolarized and would
   join the low-DOP cluster), as are points below ``dop_min`` for the E-vector solve.
2. **K-means on the DOP values** (paper Eqs. 8-9; docs/reference/algorithms.md 2.4): ``k`` clusters (default 3) in 1-D,
   Lloyd iterations from centres spread evenly between the lowest and highest DOP, a fixed number of
   iterations (deterministic cycle cost). The Sun is at the **lowest-DOP cluster** (Rayleigh DOP vanishes
   towards the Sun, paper Eq. 6); the normalised mean view ray of its members is the coarse sun direction.
3. **Refinement** with the E-vector eigen-solution (base paper Eq. 14, :func:`firmware_model.psns.solve_solar_vector`):
   ``+-S`` from ``K = sum DOP E E^T``, the sign taken from the low-DOP cluster: Rayleigh's DOP is symmetric
   about the sun/anti-sun axis, so the cluster may also hold the sky around the anti-sun (above the horizon
   when the Sun is low); the Sun is on the side whose nearest cluster member is nearer to the axis (the
   anti-sun is below the horizon). The coarse (paper) sun direction is the mean ray of the members on
   that side.
4. **Refusal** instead of a wrong answer: no distinct low-DOP cluster, a poor eigen solution, K-means and
   eigen directions that disagree, or a refined Sun outside (or within ``fov_margin`` of the edge of) the
   observed field of view. The paper's own field test shows K-means fails when the blob is cut by the lens's
   field of view; the firmware says so (event ``kmeans_refused`` with its reason, PSNS status "rejected",
   VARIANT mode 2) and leaves the attitude to the INS.
5. **Heading from the magnetometer** (the MAG frames on UART1 sampled within ``mag_half_window`` of the
   exposure time, averaged),
   tilt-compensated with the current pitch/roll: with ``m^h = R_X(theta)^T R_Y(gamma)^T m^b``,
   ``yaw = atan2(m^h_x, m^h_y) - D`` (D the declination, east positive; yaw counter-clockwise, PSINS).
6. **Pitch and roll from the sun vector** with the heading known, in the paper's rotation order
   ``A->B = R_Y(roll) R_X(pitch) R_Z(heading)`` (Eqs. 1-5): with ``u = R_Z(yaw) s^n`` and
   ``S^b = R_Y(gamma) R_X(theta) u``: the y row gives ``u_y cos theta + u_z sin theta = S^b_y``, so
   ``theta = atan2(u_z, u_y) +- acos(S^b_y / hypot(u_y, u_z))`` (the root nearer the INS pitch); then
   ``w = R_X(theta) u`` and ``gamma = atan2(w_x S_z - w_z S_x, w_x S_x + w_z S_z)``. This is the paper's
   zenith-point construction (Eqs. 10-13: ``C_Y = sin P'``, ``tan R = -C_X/C_Z``) written for an arbitrary
   sun azimuth instead of first rotating the Sun onto the Y axis. Heading and tilt are iterated
   to self-consistency (Newton steps on the yaw, ``attitude_iterations``) because the tilt compensation needs
   the tilt: a plain alternation diverges at tens of degrees of tilt.
7. The attitude fix ``(theta, gamma, yaw)`` is a measurement of the 15-state filter:
   ``Z = phi`` from ``C_b^{n'} (C_b^n_fix)^T = I - [phi x]``, ``H = [I_3, 0]``, chi-square gated.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from protocols.psns import PolarizationObs, PolarizationObsPacked, PsnsStatus

from .. import c674x, psns, sun
from ..arrays import BoolArray, F64Array, FloatArray, FloatDtype, IntArray
from ..attitude import a2mat, heading_from_yaw, m2att, q2mat_fast
from ..filters.base import BaseFilter
from ..filters.interface import UpdateReport, register_filter
from ..filters.solar import solar_noise_variance
from ..kf import IDX_ATT
from ..nav_state import NavState
from ..psns_geometry import CameraGeometry
from ..units import DEG
from .common import misalignment_between
from .mode_manager import ModeManager

__all__ = [
    "Kmeans3dFilter",
    "KmeansAttitude",
    "SunFinding",
    "find_sun",
    "heading_from_mag",
    "kmeans_1d",
    "kmeans_attitude",
    "kmeans_cycles",
    "mag_heading_axis",
    "pitch_roll_from_sun",
]

HORIZON_MASK = 2.0 * DEG


def kmeans_1d(x: FloatArray, k: int, iterations: int) -> tuple[FloatArray, IntArray]:
    """Lloyd's K-means on scalar data (paper Eqs. 8-9), fixed iterations, deterministic start.

    Parameters
    ----------
    x : (n,) values (the DOP of the observation points).
    k : clusters; iterations : Lloyd steps (assign to the nearest centre, move each centre to its mean).

    Returns
    -------
    centres (k,) ascending at the start (an empty cluster keeps its centre), labels (n,) int.
    """
    x = np.asarray(x)
    lo, hi = float(x.min()), float(x.max())
    centres = (lo + (np.arange(k) + 0.5) * ((hi - lo) / k)).astype(x.dtype)
    labels = np.zeros(len(x), dtype=np.int64)
    for _ in range(iterations):
        labels = np.argmin(np.abs(x[:, None] - centres[None, :]), axis=1)
        sums = np.bincount(labels, weights=x, minlength=k)
        counts = np.bincount(labels, minlength=k)
        nz = counts > 0
        centres = np.where(nz, sums / np.maximum(counts, 1), centres).astype(x.dtype)
    return centres, labels


def kmeans_cycles(n: int, k: int, iterations: int, c: c674x.KernelCosts) -> int:
    """Per iteration: ``n k`` distances (SUB, ABS) and compares, ``n`` accumulations, ``k`` reciprocals [D]."""
    per_iter = c.flops(k, 3 * k + 1, iterations=n) + k * c.math("recip")
    return iterations * per_iter + c.flops(2, 2, iterations=n)  # min/max for the start


def pitch_roll_from_sun(s_b: FloatArray, s_n: FloatArray, yaw: float, pitch_prior: float = 0.0
                        ) -> tuple[float, float] | None:
    """Pitch and roll (rad) from the body sun vector with the yaw known (module docstring, step 6).

    ``s_b`` (3,) unit sun vector in b, ``s_n`` (3,) in ENU, ``yaw`` PSINS yaw (rad, counter-clockwise).
    Of the two pitch roots the one nearer ``pitch_prior`` is kept; None when the geometry is degenerate
    (the Sun along the body x axis after the yaw turn, ``hypot(u_y, u_z) < 0.05``).
    """
    cy, sy = math.cos(yaw), math.sin(yaw)
    ux = cy * s_n[0] + sy * s_n[1]
    uy = -sy * s_n[0] + cy * s_n[1]
    uz = float(s_n[2])
    rho = math.hypot(uy, uz)
    if rho < 0.05:
        return None
    alpha = math.atan2(uz, uy)
    d = math.acos(max(-1.0, min(1.0, float(s_b[1]) / rho)))
    cands = [alpha + d, alpha - d]
    cands = [math.atan2(math.sin(c), math.cos(c)) for c in cands]
    cands = [c for c in cands if abs(c) <= 0.5 * math.pi] or cands
    theta = min(cands, key=lambda c: abs(c - pitch_prior))
    ct, st = math.cos(theta), math.sin(theta)
    wx = ux
    wz = -st * uy + ct * uz
    sx, sz = float(s_b[0]), float(s_b[2])
    gamma = math.atan2(wx * sz - wz * sx, wx * sx + wz * sz)
    return theta, gamma


def mag_heading_axis(declination: float, inclination: float) -> F64Array:
    """The magnetometer fix's heading axis ``c_m = (tan I sin D, tan I cos D, 1)`` (ENU, rad; D-5.31).

    A fix whose yaw is the tilt-compensated magnetometer heading computed with the fix's own pitch and roll errs by
    ``c_m . phi_fix = dpsi`` (``dpsi`` the magnetometer's own heading error, about up), not by ``c . phi_fix``
    (:func:`fix_measurement`): the compensation turns the fix's level error into heading. Derivation (PSINS
    ``C_b^n = R_Z(yaw) R_X(pitch) R_Y(roll)``, ``C' = (I - [phi x]) C``): the Euler errors of a misalignment are
    ``dpitch = -(cos y, sin y, 0) . phi``, ``droll = (sin y, -cos y, 0) . phi / cos p``, ``dyaw = -c . phi`` with
    ``c = (tan p sin y, -tan p cos y, 1)``. The compensation (:func:`heading_from_mag`,
    ``h = R_X(p)^T R_Y(r)^T m^b``, ``yaw = atan2(h_x, h_y) - D``) has the partials ``d yaw / d p = h_x h_z / h_H^2``
    and ``d yaw / d r = -sin p + cos p h_y h_z / h_H^2``; at the solution ``h = B (cos I sin(y + D),
    cos I cos(y + D), -sin I)``, so ``d yaw / d p = -tan I sin(y + D)``, ``d yaw / d r = -sin p - cos p tan I
    cos(y + D)``. The fix's yaw error is the magnetometer's ``w`` plus the partials times the fix's own level error:
    ``-c . phi_fix = (d yaw / d p) dpitch + (d yaw / d r) droll + w``, i.e.
    ``(c + (d yaw / d p) (-(cos y, sin y, 0)) + (d yaw / d r) (sin y, -cos y, 0) / cos p) . phi_fix = -w = dpsi``;
    the pitch-dependent parts cancel and the sum is ``c_m``, whatever the attitude. ``c_m`` is normal to the field
    ``b = (cos I sin D, cos I cos D, -sin I)`` and to the horizontal across it: only a rotation that moves the field's
    azimuth moves the heading. ``declination`` east positive, ``inclination`` down positive (the sheet's field
    model, not the measured vector)."""
    ti = math.tan(inclination)
    return np.array([ti * math.sin(declination), ti * math.cos(declination), 1.0])


def fix_measurement(s_n: FloatArray, pitch: float, yaw: float, sun_var: float, heading_var: float | None, n: int,
                    i_sun: int | None, cbn: FloatArray | None, i_heading: int | None = None,
                    heading_axis: FloatArray | None = None) -> tuple[F64Array, F64Array]:
    """Rows ``H`` (3, n) and noise ``R`` (3, 3) of the attitude fix ``Z = phi - phi_fix`` (D-5.23), ENU, rad.

    The fix turns the measured sun onto the ephemeris ``s`` with its yaw given. Its error ``phi_fix``
    (``C_fix = (I - [phi_fix x]) C_b^n``) moves the sun as the sun's error does, ``phi_fix = mu + eps + lambda s``,
    and its yaw as the heading's error does: a misalignment ``phi`` turns the PSINS yaw by ``-c . phi``,
    ``c = (tan(pitch) sin(yaw), -tan(pitch) cos(yaw), 1)``, so ``c . phi_fix = dpsi`` (the heading error as a
    rotation about up, ``-dyaw``). Hence ``phi_fix = G (mu + eps) + s dpsi / (c . s)``, ``G = I - s c^T / (c . s)``
    (``G s = 0``, ``c^T G = 0``), with ``eps`` the solve's noise (``sun_var`` per axis, :func:`solar_noise_variance`),
    ``mu`` the solar-vector bias states (local-level; body with ``cbn`` given, ``mu^n = C_b^n mu``) and ``dpsi`` the
    magnetometer's (``heading_var``): ``H = [I3, 0 .., -G (C_b^n)]``,
    ``R = sun_var G G^T + heading_var s s^T / (c . s)^2``. Without a heading (None) the fix keeps the INS's yaw
    (``dpsi = c . phi``): ``Z = G phi - G mu - G eps``, ``H = [G, 0 .., -G (C_b^n)]``, ``R = sun_var G G^T``, of
    which the first two rows are used (rank 2). ``i_heading``: a state holding the heading's constant error ``b``
    (``dpsi = b + w``, ``heading_var`` then the white part's): its column ``-s / (c . s)``.

    ``heading_axis``: the heading's constraint when the yaw is not an independent measurement of the yaw but the
    tilt-compensated magnetometer's, computed with the fix's own tilt: ``c_m . phi_fix = dpsi``
    (:func:`mag_heading_axis`, D-5.31); ``c`` is replaced by it in ``G``, ``R`` and the columns, so every sun error
    ``e`` also turns the fix about ``s`` by ``-(c_m . e) / (c_m . s)`` through the compensation: ``sun_var G G^T``
    carries that share of the heading and its cross terms with the level.
    Without a heading (``heading_var`` None) it is ignored: the INS yaw carries no tilt compensation."""
    s = np.asarray(s_n, dtype=np.float64)
    if heading_axis is not None and heading_var is not None:
        c = np.asarray(heading_axis, dtype=np.float64)
    else:
        tp = math.tan(pitch)
        c = np.array([tp * math.sin(yaw), -tp * math.cos(yaw), 1.0])
    cs = float(c @ s)
    cs = math.copysign(max(abs(cs), 1e-3), cs)
    g = np.eye(3) - np.outer(s, c) / cs
    H = np.zeros((3, n))
    H[:, IDX_ATT] = np.eye(3) if heading_var is not None else g
    if i_sun is not None:
        H[:, i_sun:i_sun + 3] = -g if cbn is None else -g @ np.asarray(cbn, dtype=np.float64)
    if i_heading is not None:
        H[:, i_heading] = -s / cs
    R = sun_var * (g @ g.T)
    if heading_var is not None:
        R += heading_var * np.outer(s, s) / (cs * cs)
    return H, R


def fix_measurement_cycles(c: c674x.KernelCosts) -> int:
    """:func:`fix_measurement`, the 3x3 innovation covariance, its solve and the whitening (Cholesky of R, two
    triangular solves on z and on H's nonzero columns): about 200 MUL, 170 ADD, 3 square roots and 6 divisions [D]."""
    return c.flops(200, 170) + 3 * c.math("sqrt") + 6 * c.math("div")


def heading_from_mag(m_b: FloatArray, pitch: float, roll: float, declination: float) -> float:
    """PSINS yaw (rad, counter-clockwise from North) from a magnetometer vector in b and the tilt (step 5)."""
    cr, sr = math.cos(roll), math.sin(roll)
    cp, sp = math.cos(pitch), math.sin(pitch)
    mx, my, mz = (float(v) for v in m_b)
    # R_Y(roll)^T m
    x1 = cr * mx + sr * mz
    y1 = my
    z1 = -sr * mx + cr * mz
    # R_X(pitch)^T
    hx = x1
    hy = cp * y1 - sp * z1
    return math.atan2(hx, hy) - declination


def attitude_cycles(iterations: int, c: c674x.KernelCosts) -> int:
    """Per evaluation of ``g``: heading (2 sincos, atan2, 10 MAC) and pitch/roll (atan2 x 2, acos, 2 sincos)."""
    per = (c.math("sin", 4) + c.math("cos", 4) + 3 * c.math("atan2") + c.math("acos") + c.math("sqrt")
           + c.flops(30, 20))
    return iterations * per


class SunFinding:
    """Result of :func:`find_sun` (camera frame)."""

    __slots__ = (
        "centres",
        "cluster_n",
        "coarse_c",
        "disagreement",
        "fov_theta",
        "n_points",
        "n_used",
        "ok",
        "quality",
        "reason",
        "s_c",
        "sun_theta",
    )
    ok: bool
    reason: str
    s_c: FloatArray | None  # the solar vector (camera), set from the eigen step on
    coarse_c: FloatArray | None
    cluster_n: int | None
    centres: FloatArray | None
    quality: float | None
    sun_theta: float | None
    fov_theta: float | None
    disagreement: float | None
    n_points: int | None
    #: points in the eigen solve (above the DOP threshold, in the sky)
    n_used: int | None

    def __init__(self, ok: bool, reason: str, **kw: Any) -> None:
        self.ok = ok
        self.reason = reason
        for k in self.__slots__:
            if k not in ("ok", "reason"):
                setattr(self, k, kw.get(k))

    def fields(self) -> dict[str, Any]:
        """Numbers behind the decision, for the event (degrees)."""
        out: dict[str, Any] = {"cluster_points": self.cluster_n, "points": self.n_points}
        if self.centres is not None:
            out["centres"] = [round(float(v), 4) for v in self.centres]
        for k in ("sun_theta", "fov_theta", "disagreement"):
            v = getattr(self, k)
            if v is not None:
                out[f"{k}_deg"] = round(math.degrees(v), 4)
        if self.quality is not None:
            out["quality"] = self.quality
        return out


def find_sun(x_px: FloatArray, y_px: FloatArray, aop: FloatArray, dop: FloatArray, cam: CameraGeometry,
             sky_mask: BoolArray | None, params: Any, dop_min: float, dtype: FloatDtype = np.float32) -> SunFinding:
    """Steps 1-4 of the module docstring on one frame's points (pixel coordinates 1-based, AOP rad).

    Rayleigh's DOP is symmetric about the sun/anti-sun axis, so the lowest-DOP cluster can hold two blobs:
    around the Sun and, above the horizon, around the anti-sun. The eigen-solution gives the axis ``+-S``
    exactly; the cluster decides the sign: the Sun is on the side whose nearest cluster member is closer to
    the axis (the anti-sun is below the horizon, at least one sun elevation away from every sky point). The
    K-means sun direction (the paper's cluster centre) is the mean ray of the members on that side.
    """
    v = cam.view_rays(x_px, y_px).astype(dtype)
    theta = np.arccos(np.clip(v[:, 2], -1.0, 1.0))
    fov = float(theta.max()) if len(theta) else 0.0
    use = np.ones(len(dop), dtype=bool) if sky_mask is None else sky_mask
    n = int(np.count_nonzero(use))
    if n < max(params.clusters, 3) * 2:
        return SunFinding(False, "too_few_points", n_points=n)
    d = dop[use].astype(dtype)
    vu = v[use]
    centres, labels = kmeans_1d(d, params.clusters, params.iterations)
    order = np.argsort(centres)
    low = int(order[0])
    members = labels == low
    nlow = int(np.count_nonzero(members))
    hi_c = float(centres[order[-1]])
    if nlow < params.min_cluster_points:
        return SunFinding(False, "low_dop_cluster_too_small", cluster_n=nlow, centres=centres, n_points=n)
    if not float(centres[low]) < params.max_centre_ratio * hi_c:
        return SunFinding(False, "no_low_dop_cluster", cluster_n=nlow, centres=centres, n_points=n)
    # refinement: eigen-solution of all valid E-vectors
    e = psns.evectors_camera(x_px[use], y_px[use], aop[use], cam, dtype=dtype)
    sol = psns.solve_solar_vector(e, d, dop_min, max_quality=params.max_quality)
    if not sol.valid:
        return SunFinding(False, "poor_eigen_solution", cluster_n=nlow, centres=centres, quality=sol.quality,
                          n_points=n)
    # sign from the cluster: the side with the cluster member nearest to the axis
    cos_m = vu[members] @ sol.s
    s = sol.s if float(cos_m.max()) >= float(-cos_m.min()) else -sol.s
    side = members.copy()
    side[members] = (vu[members] @ s) > 0.0
    vm = vu[side].sum(axis=0)
    coarse = (vm / np.sqrt(float(vm @ vm))).astype(dtype)
    gap = math.acos(max(-1.0, min(1.0, float((vu[side] @ s).max()))))
    dis = math.acos(max(-1.0, min(1.0, float(s @ coarse))))
    sun_theta = math.acos(max(-1.0, min(1.0, float(s[2]))))
    common = dict(cluster_n=nlow, centres=centres, quality=sol.quality, coarse_c=coarse, sun_theta=sun_theta,
                  fov_theta=fov, disagreement=dis, n_points=n, n_used=sol.n_used)
    if sun_theta > fov - params.fov_margin_deg * DEG or not _inside_image(s, cam, x_px, y_px):
        return SunFinding(False, "sun_outside_fov", s_c=s, **common)
    if gap > params.max_gap_deg * DEG:
        return SunFinding(False, "low_dop_cluster_away_from_sun", s_c=s, **common)
    if dis > params.max_disagreement_deg * DEG:
        return SunFinding(False, "kmeans_eigen_disagree", s_c=s, **common)
    return SunFinding(True, "sun_in_fov", s_c=s.astype(dtype), **common)


def _inside_image(s_c: FloatArray, cam: CameraGeometry, x_px: FloatArray, y_px: FloatArray) -> bool:
    """Whether the sun's image lies inside the bounding box of the observed points (the calibrated projection:
    principal point and radial distortion of the camera model)."""
    sx, sy, sz = (float(v) for v in s_c)
    al = math.atan2(sy, sx)
    if cam.projection == "pinhole":
        if sz <= 0:
            return False
        u = math.hypot(sx, sy) / sz
    else:
        u = math.acos(max(-1.0, min(1.0, sz)))
    rho = u * (1.0 + cam.k1 * u * u + cam.k2 * u ** 4)
    X, Y = cam.focal_m * rho * math.cos(al), cam.focal_m * rho * math.sin(al)
    cx = (cam.nx + 1) / 2.0 if cam.cx_px is None else cam.cx_px
    cy = (cam.ny + 1) / 2.0 if cam.cy_px is None else cam.cy_px
    x = X / cam.dx_m + cx
    y = Y / cam.dy_m + cy
    return float(x_px.min()) <= x <= float(x_px.max()) and float(y_px.min()) <= y <= float(y_px.max())


class KmeansAttitude:
    """An attitude fix: pitch, roll, yaw (rad, PSINS) and how it was made."""

    __slots__ = ("finding", "heading_source", "pitch", "roll", "yaw")

    def __init__(self, pitch: float, roll: float, yaw: float, heading_source: str, finding: SunFinding) -> None:
        self.pitch, self.roll, self.yaw = pitch, roll, yaw
        self.heading_source = heading_source
        self.finding = finding


def mag_field_enu(declination: float, inclination: float) -> FloatArray:
    """Unit Earth-field direction in ENU from declination (east +) and inclination (down +), rad."""
    ci = math.cos(inclination)
    return np.array([ci * math.sin(declination), ci * math.cos(declination), -math.sin(inclination)])


def kmeans_attitude(finding: SunFinding, c_c_b: FloatArray, s_n: FloatArray, m_b: FloatArray | None,
                    declination: float, prior: tuple[float, float, float], iterations: int,
                    inclination: float | None = None) -> KmeansAttitude | None:
    """Steps 5-6: heading from the magnetometer (or the prior yaw without one) and pitch/roll from the Sun.

    The magnetometer heading needs the tilt and the tilt from the Sun needs the heading; a plain
    alternation diverges for tilts of tens of degrees (the heading's tilt sensitivity is ``tan I`` = 1.7 at
    Beijing), so the self-consistent yaw is found as the root of
    ``g(yaw) = yaw_mag(tilt_sun(yaw)) - yaw`` by Newton steps (``iterations``, numerical derivative),
    started from the TRIAD attitude of the sun and field vectors when ``inclination`` is known, else from
    the prior yaw. ``prior`` = (pitch, roll, yaw) of the INS: also picks the pitch root.
    """
    assert finding.s_c is not None  # a finding with the Sun in the field
    s_b = (c_c_b @ finding.s_c.astype(np.float64))
    if m_b is None:
        tilt = pitch_roll_from_sun(s_b, s_n, prior[2], prior[0])
        if tilt is None:
            return None
        return KmeansAttitude(tilt[0], tilt[1], prior[2], "ins", finding)
    yaw = prior[2]
    pitch_prior = prior[0]
    if inclination is not None:
        try:
            from ..alignment import triad

            p0, _, y0 = m2att(triad(s_b, m_b, s_n, mag_field_enu(declination, inclination)))
            yaw, pitch_prior = y0, p0
        except ValueError:
            pass

    def g(y: float) -> tuple[float, tuple[float, float]] | None:
        pr = pitch_roll_from_sun(s_b, s_n, y, pitch_prior)
        if pr is None:
            return None
        d = heading_from_mag(m_b, pr[0], pr[1], declination) - y
        return math.atan2(math.sin(d), math.cos(d)), pr

    step = 1e-5
    for _ in range(max(1, iterations)):
        r0, r1 = g(yaw), g(yaw + step)
        if r0 is None or r1 is None:
            return None
        slope = (r1[0] - r0[0]) / step - 0.0
        denom = slope if abs(slope) > 1e-6 else -1.0
        yaw = yaw - r0[0] / denom
    res = g(yaw)
    if res is None:
        return None
    pitch, roll = res[1]
    yaw = heading_from_mag(m_b, pitch, roll, declination)
    return KmeansAttitude(pitch, roll, yaw, "magnetometer", finding)


@register_filter("kmeans_3d")
class Kmeans3dFilter(BaseFilter):
    """Base filter fed with the K-means/sun/magnetometer attitude fix (module docstring)."""

    #: the base filter's GNSS position-error states (its GNSS updates are the base filter's) and its solar-vector
    #: bias states (the fix's sun carries the same sky and mount error as the base filter's solve), and one of its
    #: own: the magnetometer heading's constant error (rad, about up; D-5.23)
    augmentable = True
    own_states = 1

    raw_polarization_obs = True

    def __init__(self, cfg: Any, meter: c674x.CycleMeter, dtype: FloatDtype) -> None:
        super().__init__(cfg, meter, dtype)
        self.p = cfg.variants.kmeans_3d
        # the heading bias: a Gauss-Markov of psns_bias_corr_time_s (hard/soft-iron residuals turn with the attitude)
        assert self.i_own is not None
        self._heading_bias_var = (self.p.heading_sigma_deg * DEG) ** 2
        self._aug_rate[self.i_own] = 1.0 / cfg.psns_bias_corr_time_s
        self.q[self.i_own] = 2.0 * self._heading_bias_var / cfg.psns_bias_corr_time_s
        self.mm = ModeManager("kmeans_3d", cfg.variants.mode_manager)
        self.counters = self.mm.counters
        self.state = 0  # VARIANT mode: 0 none yet, 1 fix used, 2 refused
        self._state_key: tuple[str, str] | None = None
        self.last_fix: KmeansAttitude | None = None
        self.last_fix_t: float | None = None
        self.last_finding: SunFinding | None = None
        from ..alignment import triad_cycles

        self._cyc_triad = triad_cycles(self.cost)
        # the magnetometer fix's heading axis (D-5.31): a constant of the sheet's field model, computed once here
        self._mag_axis = mag_heading_axis(self.p.mag_declination_deg * DEG, self.p.mag_inclination_deg * DEG)

    def initialise(self, nav: NavState, heading_sigma_rad: float) -> None:
        super().initialise(nav, heading_sigma_rad)
        i = self.i_own
        assert i is not None
        self.P[i, i] = self._heading_bias_var

    def drain_events(self) -> list[dict[str, Any]]:
        return self.mm.drain() if self.mm.events else []

    def variant_status(self) -> tuple[int, int, int] | None:
        return self.state, 1, 1 if self.state == 1 else 0

    def _set_state(self, t: float, ok: bool, reason: str, **fields: Any) -> None:
        self.state = 1 if ok else 2
        key = ("solved" if ok else "refused", reason)
        if key != self._state_key:
            self._state_key = key
            self.mm.event(t, "kmeans_solved" if ok else "kmeans_refused", reason, **fields)

    def update_polarization_obs(self, nav: NavState, frame: PolarizationObs | PolarizationObsPacked,
                                t_exposure_s: float) -> UpdateReport | None:
        host = self.host
        assert host is not None
        mm, pm, cost = self.mm, self.mm.params, self.cost
        dt = self.dtype
        t = host.now_s()
        h = frame.header
        if not h.status & PsnsStatus.VALID or h.status & PsnsStatus.SUN_BELOW_HORIZON:
            mm.decide(t, "camera", False, "frame_not_valid", status=int(h.status))
            return UpdateReport("kmeans", False, 0, 0.0, {"reason": "frame_not_valid"})
        days = host.utc_days(t_exposure_s)
        if days is None:
            mm.decide(t, "camera", False, "no_utc")
            return None
        n = frame.n_points
        if n < 3:
            mm.decide(t, "camera", False, "too_few_points", points=n)
            return UpdateReport("kmeans", False, 0, 0.0, {"reason": "too_few_points"})
        pts = psns.obs_points_array(frame.point_bytes)
        aop = (pts[:, 2] * (0.01 * DEG)).astype(dt)
        dop = (pts[:, 3] * (1.0 / 65535.0)).astype(dt)
        cam = self.cfg.camera
        aop, dop = psns.correct_polarizer(aop, dop, cam, dtype=dt)
        self.meter.charge("psns_polarizer", psns.polarizer_cycles(n, cam, cost))
        p_ins, _, q_exp = host.ins_at(t_exposure_s)
        cbn = q2mat_fast(q_exp)
        # sky mask from the INS tilt: rays below the horizon see the (unpolarized) ground
        v_c = cam.view_rays(pts[:, 0], pts[:, 1])
        up_c = (cam.c_c_b.T @ cbn.T)[:, 2]
        sky = (v_c @ up_c) > math.sin(HORIZON_MASK)
        self.meter.charge("km_rays", n * (9 + 9 + 6 + 24) + cost.flops(6, 6, iterations=n))
        finding = find_sun(pts[:, 0], pts[:, 1], aop, dop, cam, sky, self.p, pm.dop_min, dt)
        nsky = int(np.count_nonzero(sky))
        self.meter.charge("km_kmeans", kmeans_cycles(nsky, self.p.clusters, self.p.iterations, cost))
        self.meter.charge("psns_evectors", psns.evector_cycles(nsky, cost))
        self.meter.charge("psns_solve", psns.solve_cycles(nsky, cost))
        self.last_finding = finding
        if not finding.ok:
            mm.decide(t, "camera", False, finding.reason, **finding.fields())
            self._set_state(t, False, finding.reason, **finding.fields())
            return UpdateReport("kmeans", False, 0, 0.0, {"reason": finding.reason})
        s_n64 = sun.sun_vector_enu(days, float(p_ins[0]), float(p_ins[1]), dtype=np.float64)
        self.meter.charge("sun_ephemeris", sun.ephemeris_cycles())
        if float(s_n64[2]) < math.sin(pm.min_sun_elevation_deg * DEG):
            mm.decide(t, "camera", False, "sun_low")
            return None
        mag = host.mag_mean_nt(t_exposure_s, self.p.mag_half_window_s)
        prior = m2att(cbn)
        fix = kmeans_attitude(finding, cam.c_c_b, s_n64, None if mag is None else mag[0],
                              self.p.mag_declination_deg * DEG, prior, self.p.attitude_iterations,
                              self.p.mag_inclination_deg * DEG)
        self.meter.charge("km_attitude", attitude_cycles(2 * self.p.attitude_iterations + 2, cost)
                          + self._cyc_triad)
        if fix is None:
            mm.decide(t, "camera", False, "degenerate_sun_geometry")
            self._set_state(t, False, "degenerate_sun_geometry")
            return UpdateReport("kmeans", False, 0, 0.0, {"reason": "degenerate_sun_geometry"})
        self.last_fix, self.last_fix_t = fix, t_exposure_s
        if self.p.fix_events:  # the single fix itself, before the filter weighs it (the paper's field table)
            # the exposure time also in whole microseconds: event floats keep 6 significant digits (1 ms at 300 s)
            mm.event(t, "kmeans_fix", fix.heading_source, t_meas_s=t_exposure_s,
                     t_meas_us=round(t_exposure_s * 1e6), pitch_deg=fix.pitch / DEG,
                     roll_deg=fix.roll / DEG, heading_deg=heading_from_yaw(fix.yaw) / DEG)
        # the fix as a measurement: Z = phi - phi_fix, H = [I3 0 .. -G on the solar-bias states] (D-5.23)
        cbn_fix = a2mat(fix.pitch, fix.roll, fix.yaw)
        z = misalignment_between(cbn, cbn_fix).astype(np.float64)
        with_heading = fix.heading_source == "magnetometer"
        sol_var = solar_noise_variance(self.cfg, float(finding.quality if finding.quality is not None else math.nan),
                                       int(finding.n_used or 0))
        sun_st = self.sun_states
        if sun_st is not None and sun_st.shaped and sun_st.set_axis(s_n64, self.P):
            self.meter.charge("solar_bias_axis", cost.flops(4, 2) + cost.math("rsqrt"))
        H, R = fix_measurement(s_n64, fix.pitch, fix.yaw, sol_var,
                               (self.p.heading_noise_deg * DEG) ** 2 if with_heading else None,
                               self.n, None if sun_st is None else sun_st.i,
                               cbn if sun_st is not None and not sun_st.shaped else None,
                               self.i_own if with_heading else None, self._mag_axis)
        m = 3 if with_heading else 2  # without a heading Z has rank 2: its first two rows
        nu = (z - H @ self.x.astype(np.float64))[:m]
        S = H[:m] @ self.P.astype(np.float64) @ H[:m].T + R[:m, :m]
        nis = float(nu @ np.linalg.solve(S, nu))
        self.meter.charge("km_residual", cost.flops(45, 36) + fix_measurement_cycles(cost))
        fields = dict(pitch_deg=fix.pitch / DEG, roll_deg=fix.roll / DEG,
                      heading_deg=heading_from_yaw(fix.yaw) / DEG, heading_source=fix.heading_source,
                      **finding.fields())
        self._set_state(t, True, "sun_in_fov", **fields)
        if not mm.gate(t, "attitude_fix", nis, m, residual_deg=[round(float(v) / DEG, 4) for v in z]):
            return UpdateReport("kmeans", False, 0, math.sqrt(nis), {"reason": "chi2_fail"})
        mm.decide(t, "camera", True, "attitude_fix", heading_source=fix.heading_source)
        # R is full: whitened by its Cholesky factor, the rows are three (two without a heading) scalar updates
        L = np.linalg.cholesky(R[:m, :m])
        zw = np.linalg.solve(L, z[:m])
        Hw = np.linalg.solve(L, H[:m])
        innov = [self._scalar(Hw[i].astype(dt), float(zw[i]), 1.0) for i in range(m)]
        self.meter.charge("kf_update", len(innov) * self._cyc_update)
        return UpdateReport("kmeans", True, len(innov), max(abs(v) for v in innov), {"mode": "attitude_fix"})
