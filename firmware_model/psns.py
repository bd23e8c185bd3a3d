"""Polarized-skylight solve: Stokes -> DOP/AOP -> E-vectors -> K -> bi-direction solar vector.

Base paper (Liang & Bai), section II.A, with the camera/AOP convention of docs/architecture.md "Conventions"
(:mod:`firmware_model.psns_geometry`):

1. Stokes (Eq. 1): ``S0 = (I0+I45+I90+I135)/2``, ``S1 = I0 - I90``, ``S2 = I45 - I135``;
   DOP (Eq. 2) ``sqrt(S1^2+S2^2)/S0``; image angle ``psi = 1/2 atan2(S2, S1)`` from image +x towards +y.
   The AOP of the paper (Eq. 3/5) and of the wire is measured from image +y towards +x:
   ``AOP = 90 deg - psi`` wrapped to (-90, 90] deg.

   1a. Calibrated polarizer angles (:func:`correct_polarizer`, docs/calibration.md): the camera computes Stokes
   with the nominal angles 0/45/90/135; the firmware undoes that with the calibrated angles before step 2.
2. E-vector (Eq. 5-8 with the sign that makes E perpendicular to the view ray; the paper's Eq. 8 as
   printed has the opposite sign, see docs/decisions/firmware.md D-5.1):
   pinhole ``E^c = (sin AOP, cos AOP, -(X sin AOP + Y cos AOP)/f)``; equidistant fisheye
   ``E_z = -(V_x sin AOP + V_y cos AOP)/V_z``. Each E is normalised, so each point counts by its weight.
3. ``K = sum w_i E_i E_i^T`` (Eq. 14) with ``w_i = DOP_i`` for points above the DOP threshold.
4. ``+-S`` = the eigenvector of the smallest eigenvalue of K (Eq. 14), by the closed-form
   trigonometric solution of the 3x3 symmetric eigenproblem (Smith 1961) and the cross product of two
   rows of ``K - lambda_min I``: no iteration, ~500 cycles on a C674x (docs/reference/c674x-cycles.md section 4).
   Quality figure: ``lambda_min / lambda_mid`` (0 for a perfect Rayleigh sky, ~1 for no information).

Everything runs in the firmware's working precision (float32 by default).
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from protocols.psns import POINT_FIELDS, POINT_STRUCT_FORMAT

from . import c674x
from .arrays import F64Array, FloatArray, FloatDtype
from .calibration import NOMINAL_POLARIZER_DEG
from .psns_geometry import CameraGeometry
from .units import HALF_PI

__all__ = [
    "SolarSolution",
    "aop_from_psi",
    "correct_polarizer",
    "dop_psi",
    "evector_cycles",
    "evectors_camera",
    "evectors_compass",
    "exposure_time_s",
    "mosaic_observations",
    "polarizer_cycles",
    "polarizer_matrix",
    "scatter_matrix",
    "solve_cycles",
    "solve_solar_vector",
    "stokes",
    "superpixel_channels",
    "sym3_eigen_smallest",
]


@dataclass(frozen=True)
class SolarSolution:
    """Result of one solve.

    Attributes
    ----------
    s : (3,) unit bi-direction solar vector ``+-S`` in the frame of the E-vectors (sign arbitrary).
    quality : ``lambda_min / lambda_mid`` of K (smaller is better; 1.0 when invalid).
    n_used : points above the DOP threshold.
    eigenvalues : (3,) ascending eigenvalues of K.
    valid : enough points and a finite, well-separated smallest eigenvalue.
    """

    s: FloatArray
    quality: float
    n_used: int
    eigenvalues: tuple[float, float, float]
    valid: bool


def stokes(i0: FloatArray, i45: FloatArray, i90: FloatArray,
           i135: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Linear Stokes parameters (Eq. 1) from the four polarizer channels (any shape, same units)."""
    return 0.5 * (i0 + i45 + i90 + i135), i0 - i90, i45 - i135


def dop_psi(s0: FloatArray, s1: FloatArray, s2: FloatArray) -> tuple[FloatArray, FloatArray]:
    """DOP (Eq. 2, S3 = 0) and the image angle ``psi = 1/2 atan2(S2, S1)`` (rad, from +x towards +y)."""
    dt = np.result_type(s0, np.float32)
    tiny = dt.type(1e-12) if np.dtype(dt) == np.float64 else dt.type(1e-20)
    dop = np.sqrt(s1 * s1 + s2 * s2) / np.maximum(s0, tiny)
    return dop, dt.type(0.5) * np.arctan2(s2, s1)


def aop_from_psi(psi: FloatArray) -> FloatArray:
    """Wire/paper AOP (rad, from image +y towards +x) = 90 deg - psi, wrapped to (-90, 90] deg."""
    a = HALF_PI - np.asarray(psi)
    wrapped: FloatArray = a - np.pi * np.ceil((a - HALF_PI) / np.pi)
    return wrapped


@lru_cache(maxsize=16)
def polarizer_matrix(polarizer_deg: tuple[float, float, float, float]) -> tuple[FloatArray, FloatArray]:
    """``M`` (2, 2) and ``g`` (2,) of the camera's nominal Stokes processing behind polarizers at ``polarizer_deg``.

    Channel ``i`` at ``theta_i`` (deg from image +x towards +y) sees, by Malus with diattenuation ``D``,
    ``I_i = A [1 + v_1 cos 2 theta_i + v_2 sin 2 theta_i]`` with ``v = D DOP (cos 2 psi, sin 2 psi)``. The camera
    forms ``S1 = I0 - I90``, ``S2 = I45 - I135``, ``S0 = (I0 + I45 + I90 + I135) / 2`` as if the angles were
    nominal, so ``(S1, S2) = A M v`` and ``S0 = A (2 + g . v / 2)`` with
    ``M = [[cos 2t0 - cos 2t90, sin 2t0 - sin 2t90], [cos 2t45 - cos 2t135, sin 2t45 - sin 2t135]]`` and
    ``g = (sum cos 2 t_i, sum sin 2 t_i)``. Nominal angles: ``M = 2 I``, ``g = 0``. Cached per angle set (the
    calibration's angles are fixed for a run: computed once, not per frame); the arrays are read-only."""
    t = np.radians(np.asarray(polarizer_deg, dtype=np.float64))
    a, b = np.cos(2.0 * t), np.sin(2.0 * t)
    m = np.array([[a[0] - a[2], b[0] - b[2]], [a[1] - a[3], b[1] - b[3]]])
    g = np.array([a.sum(), b.sum()])
    m.flags.writeable = g.flags.writeable = False
    return m, g


def _diattenuation(extinction_ratio: float | None) -> float:
    if extinction_ratio is None or math.isinf(extinction_ratio):
        return 1.0
    return (extinction_ratio - 1.0) / (extinction_ratio + 1.0)


def correct_polarizer(aop: FloatArray, dop: FloatArray, cam: CameraGeometry,
                      dtype: FloatDtype = np.float32) -> tuple[FloatArray, FloatArray]:
    """Wire AOP/DOP (rad, -) corrected with the calibrated polarizer angles and extinction ratio of ``cam``.

    The camera reports ``psi_w = 1/2 atan2(S2, S1)`` as ``AOP_w = 90 deg - psi_w`` and ``DOP_w = |(S1, S2)| / S0``,
    so ``u = DOP_w (cos 2 psi_w, sin 2 psi_w) = DOP_w (-cos 2 AOP_w, sin 2 AOP_w) = M v / (2 + g . v / 2)``
    (:func:`polarizer_matrix`). Solving for ``v``: ``(M - u g^T / 2) v = 2 u``, a 2x2 system per point,
    ``v = 2 adj(B) u / det(B)`` with ``B = M - u g^T / 2``. Then ``psi = 1/2 atan2(v_2, v_1)`` (sensor plane,
    from image +x towards +y), ``AOP = 90 deg - psi`` wrapped to (-90, 90] deg and ``DOP = |v| / D`` with
    ``D = (ER - 1) / (ER + 1)``. Exact for any angles within the calibration file's range (10 deg of
    nominal); with nominal angles only the DOP scale ``1 / D`` applies. Frames and units as the wire's
    (docs/architecture.md "Conventions"); works in ``dtype``.
    """
    a = np.asarray(aop, dtype=dtype)
    d = np.asarray(dop, dtype=dtype)
    inv_d = dtype(1.0 / _diattenuation(cam.extinction_ratio))
    if tuple(cam.polarizer_deg) == NOMINAL_POLARIZER_DEG:
        return a, (d * inv_d).astype(dtype)
    m, g = polarizer_matrix(cam.polarizer_deg)
    m, g = m.astype(dtype), g.astype(dtype)
    two_a = dtype(2.0) * a
    u1, u2 = -d * np.cos(two_a), d * np.sin(two_a)
    half = dtype(0.5)
    b11, b12 = m[0, 0] - half * u1 * g[0], m[0, 1] - half * u1 * g[1]
    b21, b22 = m[1, 0] - half * u2 * g[0], m[1, 1] - half * u2 * g[1]
    r = dtype(2.0) / (b11 * b22 - b12 * b21)
    v1 = r * (b22 * u1 - b12 * u2)
    v2 = r * (b11 * u2 - b21 * u1)
    psi = half * np.arctan2(v2, v1)
    out_dop = (np.sqrt(v1 * v1 + v2 * v2) * inv_d).astype(dtype)
    return aop_from_psi(psi).astype(dtype), out_dop


def polarizer_cycles(n: int, cam: CameraGeometry, c: c674x.KernelCosts | None = None) -> int:
    """C674x cycles of :func:`correct_polarizer` on ``n`` points [D].

    Nominal angles: one MPYSP per point (the DOP scale), software-pipelined. Otherwise vector MATHLIB per element
    [S, R2 "Vector"]: sinsp + cossp 9 + 9, recipsp 4, sqrtsp 8, atan2sp 29 (double: 44 + 45, 16, 30, 444), plus
    18 MPY + 12 ADD per point for ``u``, ``B``, its determinant, ``v``, ``|v|`` and the wrap.
    """
    c = c or c674x.KernelCosts()
    if tuple(cam.polarizer_deg) == NOMINAL_POLARIZER_DEG:
        return c.flops(1, 0, iterations=n)
    per = (44 + 45 + 16 + 30 + 444) if c.double else (9 + 9 + 4 + 8 + 29)
    return n * per + c.flops(18, 12, iterations=n, overhead=3 * c674x.CALL_OVERHEAD)


def superpixel_channels(raw: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray]:
    """Split an IMX250MZR mosaic into its four channels at half resolution (no interpolation).

    Layout per 2x2 super-pixel (the conventions, what polanalyser expects): (row 0, col 0) = 90 deg,
    (0, 1) = 45, (1, 0) = 135, (1, 1) = 0. Returns ``(I0, I45, I90, I135)``, each (ny/2, nx/2).
    """
    return raw[1::2, 1::2], raw[0::2, 1::2], raw[0::2, 0::2], raw[1::2, 0::2]


def mosaic_observations(
    raw: FloatArray, dtype: FloatDtype = np.float32
) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
    """Observation points of a raw mosaic: one per super-pixel.

    Returns ``(x_px, y_px, aop, dop, s0)`` flattened: super-pixel centres in 1-based pixel coordinates
    (half-integers: the centre of pixels 2c+1 and 2c+2), AOP (rad, wire convention), DOP, S0 (DN).
    """
    i0, i45, i90, i135 = (c.astype(dtype) for c in superpixel_channels(raw))
    s0, s1, s2 = stokes(i0, i45, i90, i135)
    dop, psi = dop_psi(s0, s1, s2)
    ny2, nx2 = s0.shape
    yy, xx = np.meshgrid(np.arange(ny2) * 2 + 1.5, np.arange(nx2) * 2 + 1.5, indexing="ij")
    return xx.ravel(), yy.ravel(), aop_from_psi(psi).ravel(), dop.ravel(), s0.ravel()


def evectors_camera(x_px: FloatArray, y_px: FloatArray, aop: FloatArray, cam: CameraGeometry,
                    dtype: FloatDtype = np.float32) -> FloatArray:
    """Unit E-vectors in the camera frame (N, 3) from pixel positions and AOP (rad) (Eq. 5-8).

    With a calibrated lens (:attr:`CameraGeometry.paper_lens` False) the measured in-plane direction is split
    into its radial and azimuthal parts about the principal point and carried back through the lens by the
    meridional-plane rule (docs/sensors.md, "Polarization camera"): ``E_s = a_phi``, ``E_p = a_rho / cos(theta')``
    with ``theta'`` the chief-ray angle of the calibrated exit pupil, ``E = E_s e_phi + E_p p``."""
    if not cam.paper_lens:
        return _evectors_calibrated(x_px, y_px, aop, cam, dtype)
    X, Y = cam.focal_plane(x_px, y_px)
    X, Y = X.astype(dtype), Y.astype(dtype)
    a = np.asarray(aop, dtype=dtype)
    sa, ca = np.sin(a), np.cos(a)
    if cam.projection == "pinhole":
        ez = -(X * sa + Y * ca) / dtype(cam.focal_m)
    else:
        v = cam.view_rays(x_px, y_px).astype(dtype)
        ez = -(v[:, 0] * sa + v[:, 1] * ca) / v[:, 2]
    e = np.stack([sa, ca, ez], axis=-1)
    unit: FloatArray = e / np.sqrt(np.sum(e * e, axis=-1, keepdims=True))
    return unit


class _PointGeometryCache:
    """The per-point lens terms of :func:`_evectors_calibrated` for the last few (camera, dtype, pixel list)
    combinations. They depend on the calibration and the pixel positions only, and the camera reports the same
    observation points frame after frame: computed once per point set (as the DSP keeps a table per point
    grid), not per frame. Entries are read-only; the camera object is held so its identity stays valid."""

    SIZE = 8

    def __init__(self) -> None:
        self._entries: dict[tuple[int, str, bytes, bytes], tuple[CameraGeometry, tuple[FloatArray, ...]]] = {}

    def get(self, x_px: FloatArray, y_px: FloatArray, cam: CameraGeometry,
            dtype: FloatDtype) -> tuple[FloatArray, ...]:
        xa = np.ascontiguousarray(x_px, dtype=np.float64)
        ya = np.ascontiguousarray(y_px, dtype=np.float64)
        key = (id(cam), np.dtype(dtype).str, xa.tobytes(), ya.tobytes())
        hit = self._entries.get(key)
        if hit is not None and hit[0] is cam:
            return hit[1]
        terms = _point_geometry(xa, ya, cam, dtype)
        for t in terms:
            t.flags.writeable = False
        if len(self._entries) >= self.SIZE:
            self._entries.pop(next(iter(self._entries)))
        self._entries[key] = (cam, terms)
        return terms


def _point_geometry(x_px: FloatArray, y_px: FloatArray, cam: CameraGeometry,
                    dtype: FloatDtype) -> tuple[FloatArray, ...]:
    """``(cos alpha, sin alpha, cos theta, sin theta, cos theta')`` of the points (azimuth about the principal
    point, field angle, chief-ray angle), in ``dtype``."""
    X, Y = cam.focal_plane(x_px, y_px)
    r = np.hypot(X, Y)
    th = cam.field_angle(r)
    safe = np.where(r > 0.0, r, 1.0)
    cal = np.where(r > 0.0, X / safe, 1.0).astype(dtype)
    sal = np.where(r > 0.0, Y / safe, 0.0).astype(dtype)
    ct, st = np.cos(th).astype(dtype), np.sin(th).astype(dtype)
    if cam.exit_pupil_m is None:
        ccra = ct
    else:
        q = (r / cam.exit_pupil_m).astype(dtype)
        ccra = (1.0 / np.sqrt(1.0 + q * q)).astype(dtype)
    return cal, sal, ct, st, ccra


_POINT_GEOMETRY = _PointGeometryCache()


def _evectors_calibrated(x_px: FloatArray, y_px: FloatArray, aop: FloatArray, cam: CameraGeometry,
                         dtype: FloatDtype) -> FloatArray:
    cal, sal, ct, st, ccra = _POINT_GEOMETRY.get(x_px, y_px, cam, dtype)
    a = np.asarray(aop, dtype=dtype)
    ax, ay = np.sin(a), np.cos(a)  # AOP from image +y towards +x
    a_rho = ax * cal + ay * sal
    e_s = -ax * sal + ay * cal
    e_p = a_rho / ccra
    e = np.stack([e_p * ct * cal - e_s * sal, e_p * ct * sal + e_s * cal, -e_p * st], axis=-1)
    unit: FloatArray = e / np.sqrt(np.sum(e * e, axis=-1, keepdims=True))
    return unit


def evectors_compass(aop: FloatArray, mountings: FloatArray, dtype: FloatDtype = np.float32) -> FloatArray:
    """Body-frame E-vectors (n, 3) of single-direction units: ``E^b = C_u^b (sin AOP, cos AOP, 0)``."""
    a = np.asarray(aop, dtype=dtype)
    e_u = np.stack([np.sin(a), np.cos(a), np.zeros_like(a)], axis=-1)
    e_b: FloatArray = np.einsum("nij,nj->ni", mountings.astype(dtype), e_u)
    return e_b


def scatter_matrix(e: FloatArray, w: FloatArray) -> FloatArray:
    """``K = sum_i w_i E_i E_i^T`` (Eq. 14), (3, 3), six unique sums."""
    we = e * w[:, None]
    return we.T @ e


def sym3_eigen_smallest(K: FloatArray) -> tuple[FloatArray, tuple[float, float, float]]:
    """Smallest eigenvector and ascending eigenvalues of a symmetric 3x3 matrix, closed form.

    Eigenvalues by the trigonometric solution of the characteristic cubic (Smith 1961):
    ``m = tr/3``, ``B = K - m I``, ``p = sqrt(|B|_F^2 / 6)``, ``r = det(B) / (2 p^3)``,
    ``phi = acos(r) / 3``; ``lambda = m + 2 p cos(phi + 2 pi k / 3)``. The eigenvector of the smallest
    one is the largest of the three cross products of the rows of ``K - lambda_min I``.
    Works in the dtype of ``K``.
    """
    dt = K.dtype.type
    a00, a01, a02 = K[0]
    a11, a12, a22 = K[1, 1], K[1, 2], K[2, 2]
    m = (a00 + a11 + a22) / dt(3.0)
    b00, b11, b22 = a00 - m, a11 - m, a22 - m
    p2 = (b00 * b00 + b11 * b11 + b22 * b22 + dt(2.0) * (a01 * a01 + a02 * a02 + a12 * a12)) / dt(6.0)
    if not p2 > 0:  # isotropic: every vector is an eigenvector
        return np.array([0.0, 0.0, 1.0], dtype=K.dtype), (float(m), float(m), float(m))
    p = dt(math.sqrt(float(p2)))
    det_b = (b00 * (b11 * b22 - a12 * a12) - a01 * (a01 * b22 - a12 * a02) + a02 * (a01 * a12 - b11 * a02))
    r = float(det_b / (dt(2.0) * p2 * p))
    phi = math.acos(max(-1.0, min(1.0, r))) / 3.0
    l_max = m + dt(2.0) * p * dt(math.cos(phi))
    l_min = m + dt(2.0) * p * dt(math.cos(phi + 2.0 * math.pi / 3.0))
    l_mid = dt(3.0) * m - l_max - l_min
    r0 = np.array([a00 - l_min, a01, a02], dtype=K.dtype)
    r1 = np.array([a01, a11 - l_min, a12], dtype=K.dtype)
    r2 = np.array([a02, a12, a22 - l_min], dtype=K.dtype)
    best = None
    best_n = -1.0
    for u, v in ((r0, r1), (r0, r2), (r1, r2)):
        c = np.array([u[1] * v[2] - u[2] * v[1], u[2] * v[0] - u[0] * v[2], u[0] * v[1] - u[1] * v[0]], dtype=K.dtype)
        n = float(c @ c)
        if n > best_n:
            best, best_n = c, n
    assert best is not None
    if best_n <= 0.0:
        return np.array([0.0, 0.0, 1.0], dtype=K.dtype), (float(l_min), float(l_mid), float(l_max))
    return (best / dt(math.sqrt(best_n))).astype(K.dtype), (float(l_min), float(l_mid), float(l_max))


#: one POLARIZATION_OBS point record as a numpy dtype, from its ``struct`` layout (protocols.psns.POINT_SPEC)
_POINT_DTYPE = np.dtype([(name, POINT_STRUCT_FORMAT[0] + ch) for name, ch in zip(POINT_FIELDS, POINT_STRUCT_FORMAT[1:],
                                                                                    strict=True)])
if _POINT_DTYPE.itemsize != struct.calcsize(POINT_STRUCT_FORMAT):  # pragma: no cover - a field that is not one item
    raise AssertionError("POINT_STRUCT_FORMAT does not map one item per point field")


def obs_points_array(point_bytes: bytes) -> F64Array:
    """The observation points of a POLARIZATION_OBS frame as the ``(n, 4)`` float64 array ``x_px, y_px, aop_cdeg,
    dop`` (C order), from their wire bytes (``frame.point_bytes``: :class:`protocols.psns.PolarizationObsPacked` as
    the loop's decoder gives it, or :class:`protocols.psns.PolarizationObs`)."""
    rec = np.frombuffer(point_bytes, dtype=_POINT_DTYPE)
    pts: F64Array = np.empty((len(rec), 4), dtype=np.float64)
    pts[:, 0] = rec["x_px"]
    pts[:, 1] = rec["y_px"]
    pts[:, 2] = rec["aop_cdeg"]
    pts[:, 3] = rec["dop"]
    return pts


def solve_solar_vector(e: FloatArray, dop: FloatArray, dop_min: float = 0.05, min_points: int = 3,
                       max_quality: float = 0.5) -> SolarSolution:
    """Bi-direction solar vector from E-vectors (N, 3) and their DOP (N,) (Eq. 9-14).

    Points with ``DOP < dop_min`` are dropped (unreliable AOP near the sun and in clouds); the
    weights are the DOP (paper: "proportional to the DOP").
    """
    keep = dop >= dop_min
    n = int(np.count_nonzero(keep))
    dt = e.dtype
    if n < min_points:
        return SolarSolution(np.zeros(3, dtype=dt), 1.0, n, (0.0, 0.0, 0.0), False)
    K = scatter_matrix(e[keep], dop[keep].astype(dt))
    s, lam = sym3_eigen_smallest(K)
    quality = lam[0] / lam[1] if lam[1] > 0 else 1.0
    return SolarSolution(s, float(quality), n, lam, bool(quality <= max_quality and np.all(np.isfinite(s))))


def exposure_time_s(t_rx_s: float, frame_len: int, baud: float, latency_us: int, bits_per_byte: int = 10) -> float:
    """Mid-exposure time of a PSNS frame (docs/architecture.md "Conventions"): ``t_rx - len * bits / baud - latency``.

    ``t_rx_s`` is the reception time of the frame's last byte (s, FPGA time base).
    """
    return t_rx_s - frame_len * bits_per_byte / baud - latency_us * 1e-6


def evector_cycles(n: int, c: c674x.KernelCosts | None = None) -> int:
    """C674x cycles to build ``n`` unit E-vectors from (x, y, AOP) [D].

    Single precision: MATHLIB vector sinsp/cossp 9 + 9 cycles/element, rsqrtsp 6 cycles/element
    [S, R2 "Vector"]; double precision: sindp/cosdp 44 + 45, rsqrtdp 28 [S, R2 "Vector"]. Plus the
    focal-plane terms and the normalisation, 8 MPY + 5 ADD per point, software-pipelined (section 6
    fallback), plus 3 loop prologs.
    """
    c = c or c674x.KernelCosts()
    per = (44 + 45 + 28) if c.double else (9 + 9 + 6)
    return n * per + c.flops(8, 5, iterations=n, overhead=3 * c674x.CALL_OVERHEAD)


def solve_cycles(n: int, c: c674x.KernelCosts | None = None) -> int:
    """C674x cycles of threshold + ``K`` accumulation over ``n`` points + the closed-form eigen solve [D/E].

    K: 9 MPYSP + 6 ADDSP per point, bound by the 2 .M units: 5 n + 40 (docs/reference/c674x-cycles.md section 4).
    Threshold/compaction: 1 cycle/point. Eigen: sqrt + recip + acos + 2 cos + rsqrt (316 cycles in
    single precision, MATHLIB inline [S]) + ~80 FLOPs and the 3 cross products (~150 cycles) [E].
    In double precision the accumulation is MPYDP-bound: 9 MPYDP per point at 0.5/cycle = 18 n [D].
    """
    c = c or c674x.KernelCosts()
    acc = (18 * n + 40) if c.double else (5 * n + 40)
    return acc + n + c.math("sqrt") + c.math("recip") + c.math("acos") + c.math("cos", 2) + c.math("rsqrt") \
        + c.flops(60, 60)
