"""Vehicle truth: position, velocity, attitude, and the IMU quantities consistent with them.

A :class:`Trajectory` answers, at any scenario time ``t`` (s):

* :meth:`Trajectory.state` -- position ``[L, lambda, h]`` (rad, rad, m), ENU velocity (m/s),
  attitude ``C_b^n`` and Euler angles (DESIGN.md section 5 conventions);
* :meth:`Trajectory.angular_rate` and :meth:`Trajectory.specific_force` -- body-frame
  ``omega_ib^b`` (rad/s) and ``f^b`` (m/s^2), consistent with WGS-84 normal gravity
  (:mod:`firmware_model.earth`, the same model the firmware uses) and Earth rotation;
* :meth:`Trajectory.imu_increments` -- the exact integrals of both over ``[t0, t1]``.

:class:`StaticTrajectory` is the closed-form case (vehicle at rest on the rotating Earth).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from firmware_model import earth
from firmware_model.attitude import a2mat, heading_from_yaw, m2att, yaw_from_heading

__all__ = ["TruthState", "Trajectory", "StaticTrajectory"]

DEG = math.pi / 180.0


@dataclass(frozen=True)
class TruthState:
    """Truth at one instant (SI units, radians)."""

    t: float
    pos: np.ndarray  # [L rad, lambda rad, h m]
    v_enu: np.ndarray  # m/s
    c_bn: np.ndarray  # C_b^n
    pitch: float
    roll: float
    heading: float  # clockwise from true north, [0, 2 pi)


class Trajectory(ABC):
    """Source of truth for one scenario (see module docstring)."""

    duration: float

    @abstractmethod
    def state(self, t: float) -> TruthState: ...

    @abstractmethod
    def angular_rate(self, t: float) -> np.ndarray:
        """``omega_ib^b`` at ``t``, rad/s."""

    @abstractmethod
    def specific_force(self, t: float) -> np.ndarray:
        """``f^b`` at ``t``, m/s^2."""

    @abstractmethod
    def imu_increments(self, t0: float, t1: float) -> tuple[np.ndarray, np.ndarray]:
        """Exact body-frame angle (rad) and velocity (m/s) increments over ``[t0, t1]``."""


class StaticTrajectory(Trajectory):
    """A vehicle at rest at ``lat, lon, h`` with fixed attitude.

    Then ``omega_ib^b = C_n^b omega_ie^n`` and ``f^b = C_n^b [0, 0, g(L, h)]``, both constant,
    so the increments over ``[t0, t1]`` are exactly those times ``t1 - t0``.

    Parameters
    ----------
    lat_deg, lon_deg, h_m : position (deg, deg, m ellipsoidal).
    heading_deg, pitch_deg, roll_deg : attitude (deg; heading clockwise from north).
    duration : s.
    """

    def __init__(self, lat_deg: float, lon_deg: float, h_m: float, heading_deg: float = 0.0,
                 pitch_deg: float = 0.0, roll_deg: float = 0.0, duration: float = math.inf) -> None:
        self.duration = duration
        self.pos = np.array([lat_deg * DEG, lon_deg * DEG, h_m])
        yaw = yaw_from_heading(heading_deg * DEG)
        self.c_bn = a2mat(pitch_deg * DEG, roll_deg * DEG, yaw)
        p, r, y = m2att(self.c_bn)
        self._state = (p, r, heading_from_yaw(y))
        c_nb = self.c_bn.T
        lat, h = self.pos[0], self.pos[2]
        self._w = c_nb @ earth.omega_ie_n(lat)
        self._f = c_nb @ np.array([0.0, 0.0, earth.gravity(lat, h)])

    def state(self, t: float) -> TruthState:
        p, r, hd = self._state
        return TruthState(t, self.pos.copy(), np.zeros(3), self.c_bn.copy(), p, r, hd)

    def angular_rate(self, t: float) -> np.ndarray:
        return self._w.copy()

    def specific_force(self, t: float) -> np.ndarray:
        return self._f.copy()

    def imu_increments(self, t0: float, t1: float) -> tuple[np.ndarray, np.ndarray]:
        dt = t1 - t0
        return self._w * dt, self._f * dt
