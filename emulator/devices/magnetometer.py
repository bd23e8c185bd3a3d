"""Three-axis magnetometer (heading source of the K-means 3-D attitude variant), sampled by the FPGA.

Local field model: a constant Earth field given by declination ``D`` (east positive), inclination
``I`` (down positive) and total intensity ``F``; in ENU::

    B^n = F [cos I sin D, cos I cos D, -sin I]

The defaults are IGRF-13 for Beijing (39.979 N, 116.339 E, 50 m, 2019-09-18; computed with
``ppigrf``, a test re-checks them): D = -7.13 deg, I = 59.21 deg, F = 54 769 nT.

Sensor model::

    m^b = W (C_n^b B^n) + h + n,      n ~ N(0, sigma^2) per axis (15 nT by default)

with ``W`` the soft-iron matrix (identity plus a symmetric perturbation) and ``h`` the hard-iron
offset (body axes, nT), both constants of the installation. :meth:`Magnetometer.sample` is
called by the FPGA at its trigger like the accelerometers and returns the field words of the
MAG frame (``protocols.imu_frame`` MagFrame: i32 in 0.1 nT, body x, y, z).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from protocols.constants import DEG

from ..world.trajectory import Trajectory

__all__ = ["BEIJING_FIELD", "MAG_LSB_NT", "MagConfig", "Magnetometer", "field_enu"]

#: MAG frame resolution, nT per LSB.
MAG_LSB_NT = 0.1
#: IGRF-13 at 39.979 N, 116.339 E, 50 m, 2019-09-18 (ppigrf): declination, inclination (deg), intensity (nT).
BEIJING_FIELD = (-7.133, 59.215, 54769.0)
I32_MAX = 2**31 - 1


def field_enu(declination_deg: float, inclination_deg: float, intensity_nt: float) -> np.ndarray:
    """Earth field in ENU (nT) from D, I, F."""
    d, i = declination_deg * DEG, inclination_deg * DEG
    return intensity_nt * np.array([math.cos(i) * math.sin(d), math.cos(i) * math.cos(d), -math.sin(i)])


@dataclass
class MagConfig:
    """Magnetometer and local-field parameters (deg, nT)."""

    declination_deg: float = BEIJING_FIELD[0]
    inclination_deg: float = BEIJING_FIELD[1]
    intensity_nt: float = BEIJING_FIELD[2]
    noise_nt: float = 15.0
    hard_iron_nt: tuple[float, float, float] = (0.0, 0.0, 0.0)
    soft_iron: np.ndarray = field(default_factory=lambda: np.eye(3))
    range_nt: float = 800_000.0


class Magnetometer:
    """See module docstring. ``sample(t, t_prev)`` returns the three field words (0.1 nT) and a status byte."""

    def __init__(self, trajectory: Trajectory, rng: np.random.Generator, cfg: MagConfig | None = None) -> None:
        self.traj = trajectory
        self.rng = rng
        self.cfg = cfg or MagConfig()
        c = self.cfg
        self.b_n = field_enu(c.declination_deg, c.inclination_deg, c.intensity_nt)
        self.w = np.asarray(c.soft_iron, dtype=np.float64)
        self.h = np.asarray(c.hard_iron_nt, dtype=np.float64)
        self.samples = 0
        self.last_measured = np.zeros(3)
        self._noise = np.zeros((0, 3))
        self._i = 0

    def field_body(self, t: float) -> np.ndarray:
        """True Earth field in body axes (nT) at ``t``."""
        return self.traj.state(t).c_bn.T @ self.b_n

    def measure(self, t: float) -> np.ndarray:
        """Measured field (nT, body axes) at ``t``."""
        if self._i >= len(self._noise):
            self._noise = self.rng.standard_normal((200, 3)) * self.cfg.noise_nt
            self._i = 0
        n = self._noise[self._i]
        self._i += 1
        return self.w @ self.field_body(t) + self.h + n

    def sample(self, t: float, t_prev: float) -> tuple[tuple[int, int, int], int]:
        """FPGA acquisition at trigger ``t``: field words (0.1 nT) and status (bit 0: over range)."""
        m = self.measure(t)
        self.last_measured = m
        self.samples += 1
        over = bool(np.any(np.abs(m) > self.cfg.range_nt))
        m = np.clip(m, -self.cfg.range_nt, self.cfg.range_nt)
        words = np.clip(np.round(m / MAG_LSB_NT), -I32_MAX - 1, I32_MAX).astype(np.int64)
        return (int(words[0]), int(words[1]), int(words[2])), int(over)


def soft_iron_matrix(scale: tuple[float, float, float] = (1.0, 1.0, 1.0),
                     cross: tuple[float, float, float] = (0.0, 0.0, 0.0)) -> np.ndarray:
    """Symmetric soft-iron matrix from diagonal ``scale`` and off-diagonal ``cross`` = (xy, xz, yz)."""
    sx, sy, sz = scale
    xy, xz, yz = cross
    return np.array([[sx, xy, xz], [xy, sy, yz], [xz, yz, sz]])
