"""15-state error-state Kalman filter in ENU (base paper, Liang & Bai, Eqs. 15-20, 44-49).

State order (Eq. 15)::

    x = [phi_E phi_N phi_U | dv_E dv_N dv_U | dL dlambda dh | eps_x eps_y eps_z | nab_x nab_y nab_z]

phi in rad (misalignment, ``C_b^{n'} = (I - [phi x]) C_b^n``), dv in m/s, dL and dlambda in
rad, dh in m, gyro drift eps in rad/s (body), accelerometer bias nabla in m/s^2 (body).
Errors are "computed minus true".

F follows the element list of ``docs/reference/algorithms.md`` section 1.3 (PSINS ``etm``,
checked there against numerical Jacobians); the base paper's F_S block (Eq. 18) is
``[[-C_b^n, 0], [0, C_b^n], [0, 0]]`` in this sign convention. Discretisation
``Phi = I + F T`` (PSINS ``kffk``), ``Q_k = Q_t T``.

Measurement updates are processed one scalar at a time (sequential processing of the rows of
Eqs. 43/46-49, valid because R is diagonal) in the Joseph form, evaluated in O(n^2) without
forming ``I - K h``: with ``a = P h``, ``s = h a + r``, ``K = a / s``::

    B  = P - K a^T                 = (I - K h) P
    P' = B - (B h) K^T + r K K^T   = (I - K h) P (I - K h)^T + r K K^T

``B h`` is computed from ``B`` (not replaced by its exact-arithmetic value ``a r / s``), so the
rounding of the first step is corrected by the second, as in the full Joseph form; the result is
symmetrised. The paper's Eq. 49 ``P = (I - K H) P`` loses symmetry and definiteness in float32 over
long runs; this form kept P positive definite over a 1 h float32 run
(``tests/firmware_model/test_kf.py``).

Solar-vector measurement (Eqs. 31-42): ``Z = S^n - C_b^{n'} (+-S^b)`` with the sign that gives the
smaller ``|Z|`` (Eq. 38 remark), and ``H_s = [-[S^n x], 0_{3x12}]``. Derivation (the printed Eq. 41
has typos; docs/decisions/firmware.md D-5.1): ``C_b^{n'} = (I - [phi x]) C_b^n`` and ``S^n = C_b^n S^b``, so
``C_b^{n'} S^b = S^n - phi x S^n`` and ``Z = phi x S^n = -[S^n x] phi``.
"""

from __future__ import annotations

import math

import numpy as np

from . import earth
from .arrays import FloatArray, FloatDtype

__all__ = [
    "DV_E",
    "DV_N",
    "DV_U",
    "D_H",
    "D_LAT",
    "D_LON",
    "IDX_ACC",
    "IDX_ATT",
    "IDX_GYRO",
    "IDX_POS",
    "IDX_VEL",
    "N_NAV_ERRORS",
    "N_STATES",
    "PHI_E",
    "PHI_N",
    "PHI_U",
    "error_transition_matrix",
    "kf_predict",
    "kf_update_scalar",
    "process_noise_psd",
    "solar_vector_residual",
    "solar_vector_rows",
]

#: The error state's layout (Eq. 15), named once: groups as slices, the navigation components as indices.
N_STATES = 15
IDX_ATT = slice(0, 3)  # phi_E phi_N phi_U, rad
IDX_VEL = slice(3, 6)  # dv_E dv_N dv_U, m/s
IDX_POS = slice(6, 9)  # dL dlambda (rad) dh (m)
IDX_GYRO = slice(9, 12)  # eps_x eps_y eps_z, rad/s (body)
IDX_ACC = slice(12, 15)  # nab_x nab_y nab_z, m/s^2 (body)
PHI_E, PHI_N, PHI_U = 0, 1, 2
DV_E, DV_N, DV_U = 3, 4, 5
D_LAT, D_LON, D_H = 6, 7, 8
#: the navigation errors (attitude, velocity, position) come first: ``P[:N_NAV_ERRORS]`` gives the output sigmas
N_NAV_ERRORS = 9


def error_transition_matrix(
    cbn: FloatArray, v_enu: FloatArray, pos: FloatArray, f_n: FloatArray, dtype: FloatDtype = np.float32
) -> FloatArray:
    """Continuous-time error dynamics F (15x15), docs/reference/algorithms.md 1.3 element list.

    Parameters
    ----------
    cbn : (3, 3) ``C_b^n``.
    v_enu : (3,) ENU velocity, m/s.
    pos : (3,) ``[L rad, lambda rad, h m]``.
    f_n : (3,) specific force in n, m/s^2.
    """
    lat, _, h = np.asarray(pos, dtype=np.float64).tolist()
    ve, vn, vu = np.asarray(v_enu).tolist()  # exact doubles of float32 or float64 values
    fe, fn, fu = np.asarray(f_n).tolist()
    s, c = math.sin(lat), math.cos(lat)
    t = s / c
    sec = 1.0 / c
    W = earth.OMEGA_IE
    rm, rn = earth.radii(lat)
    rmh, rnh = rm + h, rn + h
    # (row, column) -> value, the element list of docs/reference/algorithms.md 1.3 in its order; written into F in one
    # call
    rs, rs2, rm2 = ve * t / rnh, rnh**2, rmh**2
    elements = (
        # attitude rows (1-3)
        (PHI_E, PHI_N, W * s + rs),
        (PHI_E, PHI_U, -(W * c + ve / rnh)),
        (PHI_E, DV_N, -1.0 / rmh),
        (PHI_E, D_H, vn / rm2),
        (PHI_N, PHI_E, -(W * s + rs)),
        (PHI_N, PHI_U, -vn / rmh),
        (PHI_N, DV_E, 1.0 / rnh),
        (PHI_N, D_LAT, -W * s),
        (PHI_N, D_H, -ve / rs2),
        (PHI_U, PHI_E, W * c + ve / rnh),
        (PHI_U, PHI_N, vn / rmh),
        (PHI_U, DV_E, t / rnh),
        (PHI_U, D_LAT, W * c + ve * sec**2 / rnh),
        (PHI_U, D_H, -ve * t / rs2),
        # velocity rows (4-6)
        (DV_E, PHI_N, -fu),
        (DV_E, PHI_U, fn),
        (DV_N, PHI_E, fu),
        (DV_N, PHI_U, -fe),
        (DV_U, PHI_E, -fn),
        (DV_U, PHI_N, fe),
        (DV_E, DV_E, (vn * t - vu) / rnh),
        (DV_E, DV_N, 2 * W * s + rs),
        (DV_E, DV_U, -(2 * W * c + ve / rnh)),
        (DV_E, D_LAT, 2 * W * (vu * s + vn * c) + ve * vn * sec**2 / rnh),
        (DV_E, D_H, ve * (vu - vn * t) / rs2),
        (DV_N, DV_E, -2 * (W * s + rs)),
        (DV_N, DV_N, -vu / rmh),
        (DV_N, DV_U, -vn / rmh),
        (DV_N, D_LAT, -2 * W * ve * c - ve**2 * sec**2 / rnh),
        (DV_N, D_H, vu * vn / rm2 + ve**2 * t / rs2),
        (DV_U, DV_E, 2 * (W * c + ve / rnh)),
        (DV_U, DV_N, 2 * vn / rmh),
        (DV_U, D_LAT, -2 * W * ve * s - earth.G0 * (2 * 5.27094e-3 + 4 * 2.32718e-5 * s * s) * s * c),
        (DV_U, D_H, -(vn**2) / rm2 - ve**2 / rs2 + 3.086e-6),
        # position rows (7-9)
        (D_LAT, DV_N, 1.0 / rmh),
        (D_LAT, D_H, -vn / rm2),
        (D_LON, DV_E, sec / rnh),
        (D_LON, D_LAT, ve * t * sec / rnh),
        (D_LON, D_H, -ve * sec / rs2),
        (D_H, DV_U, 1.0),
    )
    F = np.zeros((N_STATES, N_STATES), dtype=np.float64)
    F.flat[[N_STATES * i + j for i, j, _ in elements]] = [v for _, _, v in elements]
    F[IDX_ATT, IDX_GYRO] = -cbn  # gyro drift into attitude
    F[IDX_VEL, IDX_ACC] = cbn  # accelerometer bias into velocity
    return F.astype(dtype)


def kf_predict(
    x: FloatArray, P: FloatArray, Phi: FloatArray, Qk: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Time update (Eqs. 45, 48): ``x = Phi x``, ``P = Phi P Phi^T + Q_k``, symmetrised.

    Shapes: x (n,), P (n, n), Phi (n, n), Qk (n, n) or (n,) diagonal.
    """
    x = Phi @ x
    P = Phi @ P @ Phi.T
    if Qk.ndim == 1:
        P.flat[:: P.shape[0] + 1] += Qk  # the diagonal (a strided view: no index arrays)
    else:
        P = P + Qk
    P = 0.5 * (P + P.T)
    return x, P


def kf_update_scalar(
    x: FloatArray, P: FloatArray, h: FloatArray, z: float, r: float
) -> tuple[FloatArray, FloatArray, float, float]:
    """One scalar measurement update in O(n^2) Joseph form (Eqs. 46, 47, 49; module docstring).

    Parameters
    ----------
    h : (n,) measurement row; z : measurement; r : its noise variance (same units squared).

    Returns
    -------
    x, P (new arrays, dtype of P), innovation ``z - h x``, innovation variance ``s = h P h^T + r``.
    """
    dt = P.dtype.type
    a = P @ h
    s = float(h @ a) + r
    innov = float(z - h @ x)
    K = a / dt(s)
    x = x + K * dt(innov)
    Kc = K[:, None]  # outer products by broadcasting (what np.outer computes, without its Python wrapper)
    B = P - Kc * a
    c = B @ h
    P = B - c[:, None] * K + dt(r) * (Kc * K)
    P = dt(0.5) * (P + P.T)
    return x, P, innov, s


def solar_vector_residual(s_n: FloatArray, cbn: FloatArray, s_b: FloatArray) -> tuple[FloatArray, int]:
    """Bi-direction solar-vector measurement ``Z = S^n - C_b^{n'} (+-S^b)`` (Eqs. 38, 40).

    Parameters
    ----------
    s_n : (3,) unit sun vector in ENU from the ephemeris.
    cbn : (3, 3) computed ``C_b^{n'}`` at the exposure time.
    s_b : (3,) unit bi-direction solar vector measured in the body frame (sign unknown).

    Returns
    -------
    Z (3,) and the sign (+1 or -1) that makes ``|Z|`` the smaller (the paper's rule).
    """
    a = cbn @ s_b
    zp = s_n - a
    zm = s_n + a
    if float(zp @ zp) <= float(zm @ zm):
        return zp, 1
    return zm, -1


def solar_vector_rows(s_n: FloatArray, dtype: FloatDtype = np.float32, n_states: int = N_STATES) -> FloatArray:
    """``H_s = [-[S^n x], 0_{3x12}]`` (3, n_states) (Eq. 41 as derived in the module docstring; the columns of
    augmented states beyond the 15 are zero here)."""
    e, n, u = (float(v) for v in s_n)
    H = np.zeros((3, n_states), dtype=dtype)
    H[0, PHI_N], H[0, PHI_U] = u, -n
    H[1, PHI_E], H[1, PHI_U] = -u, e
    H[2, PHI_E], H[2, PHI_N] = n, -e
    return H


def process_noise_psd(gyro_arw_rad_rt_s: float, accel_vrw_mps2_rt_hz: float, gyro_bias_rw: float,
                      accel_bias_rw: float) -> FloatArray:
    """Diagonal continuous process-noise PSD ``q`` (15,) in the state order (Eq. 48 with Gamma = I).

    ARW^2 on the phi rows, VRW^2 on the dv rows, 0 on position, and the bias random-walk densities
    (rad^2/s^3, m^2/s^5) on the bias rows. ``Q_k = q T_k`` (PSINS ``kffk``).
    """
    q = np.zeros(N_STATES)
    q[IDX_ATT] = gyro_arw_rad_rt_s**2
    q[IDX_VEL] = accel_vrw_mps2_rt_hz**2
    q[IDX_GYRO] = gyro_bias_rw
    q[IDX_ACC] = accel_bias_rw
    return q
