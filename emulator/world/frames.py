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


def cbn_from_euler(pitch: np.ndarray | float, roll: np.ndarray | float, yaw: np.ndarray | float) -> np.ndarray:
    """``C_b^n`` of Euler angles (rad): floats -> (3, 3); (N,) arrays -> (N, 3, 3)."""
    ang = np.stack(np.broadcast_arrays(np.asarray(yaw, dtype=np.float64), np.asarray(pitch, dtype=np.float64),
                                       np.asarray(roll, dtype=np.float64)), axis=-1)
    m: np.ndarray = Rotation.from_euler(_SEQ, ang).as_matrix()
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
