"""The world's own attitude conventions, on :class:`scipy.spatial.transform.Rotation`.

The project's frames (docs/reference/algorithms.md section 0): n = ENU, b = (x right, y forward, z up);
``C_b^n`` rotates body vectors into ENU and is the intrinsic z-x'-y'' sequence (yaw, then pitch, then roll)
``R_z(yaw) R_x(pitch) R_y(roll)``, where yaw is counter-clockwise from north and the reported heading is
clockwise from north (``heading = -yaw``). The world never uses the firmware's Euler kernels
(docs/architecture.md, the independence rule); a test compares the two.
"""

from __future__ import annotations

import math

import numpy as np
from scipy.spatial.transform import Rotation

__all__ = ["cbn_from_euler", "euler_from_cbn", "heading_from_yaw", "rotvec_matrix", "yaw_from_heading"]

_SEQ = "ZXY"  # intrinsic yaw, pitch, roll


def _axis_rotation(angle: np.ndarray, i: int, j: int) -> np.ndarray:
    """(..., 3, 3) right-handed rotations by ``angle`` (rad) in the ``(i, j)`` coordinate plane (the third axis
    fixed): ``R[i, i] = R[j, j] = cos``, ``R[j, i] = sin``, ``R[i, j] = -sin``."""
    c, s = np.cos(angle), np.sin(angle)
    r = np.zeros((*np.shape(angle), 3, 3))
    r[..., 3 - i - j, 3 - i - j] = 1.0
    r[..., i, i] = c
    r[..., j, j] = c
    r[..., j, i] = s
    r[..., i, j] = -s
    return r


def _scalar_rotation(angle: float, i: int, j: int) -> np.ndarray:
    """:func:`_axis_rotation` of one angle, (3, 3)."""
    c, s = math.cos(angle), math.sin(angle)
    r = [[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]
    r[3 - i - j][3 - i - j] = 1.0
    r[i][i] = r[j][j] = c
    r[j][i] = s
    r[i][j] = -s
    return np.array(r)


def cbn_from_euler(pitch: np.ndarray | float, roll: np.ndarray | float, yaw: np.ndarray | float) -> np.ndarray:
    """``C_b^n`` of Euler angles (rad): floats -> (3, 3); (N,) arrays -> (N, 3, 3).

    The product of the three axis rotations ``R_z(yaw) R_x(pitch) R_y(roll)`` (the definition, module docstring),
    which is scipy's intrinsic ``Rotation.from_euler("ZXY", (yaw, pitch, roll))`` to a few 1e-16 (a test checks);
    computed here directly because scipy's path through quaternions costs ~2 us per angle triple, and the truth
    evaluates ~800 triples per 200 IMU intervals (docs/performance.md)."""
    if np.ndim(pitch) == 0 and np.ndim(roll) == 0 and np.ndim(yaw) == 0:  # one triple: the same matrices, built
        return _scalar_rotation(float(yaw), 0, 1) @ _scalar_rotation(float(pitch), 1, 2) @ _scalar_rotation(
            float(roll), 2, 0)  # without the array machinery
    y, p, r = np.broadcast_arrays(np.asarray(yaw, dtype=np.float64), np.asarray(pitch, dtype=np.float64),
                                  np.asarray(roll, dtype=np.float64))
    m: np.ndarray = _axis_rotation(y, 0, 1) @ _axis_rotation(p, 1, 2) @ _axis_rotation(r, 2, 0)
    return m


def euler_from_cbn(c_bn: np.ndarray) -> tuple[float, float, float]:
    """Euler angles ``(pitch, roll, yaw)`` (rad) of one ``C_b^n``; pitch in [-pi/2, pi/2]."""
    yaw, pitch, roll = Rotation.from_matrix(np.asarray(c_bn, dtype=np.float64)).as_euler(_SEQ)
    return float(pitch), float(roll), float(yaw)


def heading_from_yaw(yaw: float) -> float:
    """Heading (clockwise from true north, [0, 2 pi)) of a counter-clockwise yaw, rad."""
    return (-yaw) % (2.0 * math.pi)


def yaw_from_heading(heading: float) -> float:
    """Counter-clockwise yaw in (-pi, pi] of a clockwise heading, rad."""
    y = (-heading) % (2.0 * math.pi)
    return y - 2.0 * math.pi if y > math.pi else y


def rotvec_matrix(rv: np.ndarray) -> np.ndarray:
    """Rotation matrix of a rotation vector (rad)."""
    m: np.ndarray = Rotation.from_rotvec(np.asarray(rv, dtype=np.float64)).as_matrix()
    return m
