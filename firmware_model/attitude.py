"""Attitude algebra: quaternions, rotation vectors, direction-cosine matrices, Euler angles.

Conventions (``docs/reference/algorithms.md`` section 0, PSINS):

* n = ENU, b = (x right, y forward, z up).
* ``C_n^b = R_Y(roll) R_X(pitch) R_Z(yaw)``; ``C_b^n`` is its transpose (PSINS ``a2mat``).
* PSINS yaw ``psi`` is counter-clockwise from North; the reported heading (clockwise from true
  North, [0, 360)) is ``-psi``.
* Quaternion ``q = q_b^n`` is Hamilton, scalar first: ``v^n = q (x) v^b (x) q*``.
* Misalignment phi: ``C_b^{n'} = (I - [phi x]) C_b^n``; corrected by ``q <- rv2q(phi) (x) q``.
"""

from __future__ import annotations

import math

import numpy as np

from .arrays import FloatArray

__all__ = [
    "a2mat",
    "att2q",
    "cross3",
    "heading_from_yaw",
    "m2att",
    "mat2q",
    "q2att",
    "q2mat",
    "q2mat_fast",
    "qconj",
    "qmul",
    "qnormalize",
    "rv2q",
    "skew",
    "yaw_from_heading",
]


def cross3(a: FloatArray, b: FloatArray) -> FloatArray:
    """Cross product of two 3-vectors (``numpy.cross`` without its axis handling, ~10x faster)."""
    a0, a1, a2 = a
    b0, b1, b2 = b
    return np.array([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], dtype=np.result_type(a, b))


def skew(v: FloatArray) -> FloatArray:
    """Cross-product matrix ``[v x]`` so that ``skew(a) @ b == cross(a, b)``."""
    x, y, z = v
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]], dtype=np.asarray(v).dtype)


def qmul(p: FloatArray, q: FloatArray) -> FloatArray:
    """Hamilton product ``p (x) q`` (scalar first)."""
    p0, p1, p2, p3 = p
    q0, q1, q2, q3 = q
    return np.array(
        [
            p0 * q0 - p1 * q1 - p2 * q2 - p3 * q3,
            p0 * q1 + p1 * q0 + p2 * q3 - p3 * q2,
            p0 * q2 - p1 * q3 + p2 * q0 + p3 * q1,
            p0 * q3 + p1 * q2 - p2 * q1 + p3 * q0,
        ],
        dtype=np.result_type(p, q),
    )


def qconj(q: FloatArray) -> FloatArray:
    """Conjugate (inverse of a unit quaternion)."""
    return np.array([q[0], -q[1], -q[2], -q[3]], dtype=np.asarray(q).dtype)


def qnormalize(q: FloatArray) -> FloatArray:
    """Unit-norm copy of ``q``."""
    unit: FloatArray = q / np.sqrt(np.dot(q, q))
    return unit


def rv2q(phi: FloatArray) -> FloatArray:
    """Rotation vector (rad) to quaternion ``[cos(|phi|/2), sin(|phi|/2) phi/|phi|]``.

    Uses the series form below 1e-8 rad so tiny increments keep full precision.
    """
    phi = np.asarray(phi)
    n2 = float(np.dot(phi, phi))
    if n2 < 1e-16:
        # cos(n/2) ~ 1 - n^2/8, sin(n/2)/n ~ 1/2 - n^2/48
        c = 1.0 - n2 / 8.0
        s = 0.5 - n2 / 48.0
    else:
        n = math.sqrt(n2)
        c = math.cos(n / 2.0)
        s = math.sin(n / 2.0) / n
    dt = phi.dtype if phi.dtype.kind == "f" else np.float64
    return np.array([c, s * phi[0], s * phi[1], s * phi[2]], dtype=dt)


def q2mat(q: FloatArray) -> FloatArray:
    """Quaternion ``q_b^n`` to DCM ``C_b^n`` (in ``q``'s dtype). The reference; :func:`q2mat_fast` is the same."""
    q0, q1, q2, q3 = q
    return np.array(
        [
            [q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3, 2 * (q1 * q2 - q0 * q3), 2 * (q1 * q3 + q0 * q2)],
            [2 * (q1 * q2 + q0 * q3), q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3, 2 * (q2 * q3 - q0 * q1)],
            [2 * (q1 * q3 - q0 * q2), 2 * (q2 * q3 + q0 * q1), q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3],
        ],
        dtype=np.asarray(q).dtype,
    )


def q2mat_fast(q: FloatArray) -> FloatArray:
    """:func:`q2mat`, bit for bit: a float64 array on Python floats (the same double operations without numpy's
    ~0.1 us per scalar operation), any other input by :func:`q2mat`."""
    if type(q) is np.ndarray and q.dtype == np.float64:
        q0, q1, q2, q3 = q.tolist()
        return np.array((
            q0 * q0 + q1 * q1 - q2 * q2 - q3 * q3, 2 * (q1 * q2 - q0 * q3), 2 * (q1 * q3 + q0 * q2),
            2 * (q1 * q2 + q0 * q3), q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3, 2 * (q2 * q3 - q0 * q1),
            2 * (q1 * q3 - q0 * q2), 2 * (q2 * q3 + q0 * q1), q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3,
        )).reshape(3, 3)
    return q2mat(q)


def mat2q(c: FloatArray) -> FloatArray:
    """DCM ``C_b^n`` to quaternion ``q_b^n`` (Shepperd's method, scalar >= 0)."""
    c = np.asarray(c, dtype=np.float64)
    tr = c[0, 0] + c[1, 1] + c[2, 2]
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        q = [0.25 * s, (c[2, 1] - c[1, 2]) / s, (c[0, 2] - c[2, 0]) / s, (c[1, 0] - c[0, 1]) / s]
    elif c[0, 0] > c[1, 1] and c[0, 0] > c[2, 2]:
        s = math.sqrt(1.0 + c[0, 0] - c[1, 1] - c[2, 2]) * 2
        q = [(c[2, 1] - c[1, 2]) / s, 0.25 * s, (c[0, 1] + c[1, 0]) / s, (c[0, 2] + c[2, 0]) / s]
    elif c[1, 1] > c[2, 2]:
        s = math.sqrt(1.0 + c[1, 1] - c[0, 0] - c[2, 2]) * 2
        q = [(c[0, 2] - c[2, 0]) / s, (c[0, 1] + c[1, 0]) / s, 0.25 * s, (c[1, 2] + c[2, 1]) / s]
    else:
        s = math.sqrt(1.0 + c[2, 2] - c[0, 0] - c[1, 1]) * 2
        q = [(c[1, 0] - c[0, 1]) / s, (c[0, 2] + c[2, 0]) / s, (c[1, 2] + c[2, 1]) / s, 0.25 * s]
    qa = np.array(q)
    if qa[0] < 0:
        qa = -qa
    unit: FloatArray = qa / np.linalg.norm(qa)
    return unit


def a2mat(pitch: float, roll: float, yaw: float) -> FloatArray:
    """Euler angles (rad; PSINS yaw, counter-clockwise from North) to ``C_b^n``.

    ``C_b^n = (R_Y(roll) R_X(pitch) R_Z(yaw))^T`` (docs/reference/algorithms.md section 0).
    """
    sp, cp = math.sin(pitch), math.cos(pitch)
    sr, cr = math.sin(roll), math.cos(roll)
    sy, cy = math.sin(yaw), math.cos(yaw)
    return np.array(
        [
            [cr * cy - sp * sr * sy, -cp * sy, sr * cy + sp * cr * sy],
            [cr * sy + sp * sr * cy, cp * cy, sr * sy - sp * cr * cy],
            [-cp * sr, sp, cp * cr],
        ]
    )


def m2att(c: FloatArray) -> tuple[float, float, float]:
    """``C_b^n`` to ``(pitch, roll, yaw)`` in rad (PSINS ``m2att``; yaw counter-clockwise)."""
    pitch = math.asin(max(-1.0, min(1.0, float(c[2, 1]))))
    roll = math.atan2(-float(c[2, 0]), float(c[2, 2]))
    yaw = math.atan2(-float(c[0, 1]), float(c[1, 1]))
    return pitch, roll, yaw


def att2q(pitch: float, roll: float, yaw: float) -> FloatArray:
    """Euler angles (rad) to ``q_b^n``."""
    return mat2q(a2mat(pitch, roll, yaw))


def q2att(q: FloatArray) -> tuple[float, float, float]:
    """``q_b^n`` to ``(pitch, roll, yaw)`` rad."""
    return m2att(q2mat_fast(np.asarray(q, dtype=np.float64)))


def heading_from_yaw(yaw: float) -> float:
    """PSINS yaw (rad, counter-clockwise from North) to heading (rad, clockwise, [0, 2 pi))."""
    return (-yaw) % (2.0 * math.pi)


def yaw_from_heading(heading: float) -> float:
    """Heading (rad, clockwise from North) to PSINS yaw (rad, counter-clockwise, (-pi, pi])."""
    y = -heading
    return math.atan2(math.sin(y), math.cos(y))
