"""A truth source that does not move and has no gravity: every IMU increment is zero, so what an IMU model outputs
is its own error terms (and any vibration the world adds). Shared by the IMU temperature and vibration tests."""

from __future__ import annotations

import types

import numpy as np


class StillTruth:
    """``imu_increments`` / ``imu_increments_ready`` of a body at rest in a gravity-free world (rad, m/s)."""

    @staticmethod
    def imu_increments(t0: float, t1: float) -> tuple[np.ndarray, np.ndarray]:
        return np.zeros(3), np.zeros(3)

    @staticmethod
    def imu_increments_ready(t0: float, t1: float) -> tuple[np.ndarray, np.ndarray]:
        return np.zeros(3), np.zeros(3)


def still_truth() -> types.SimpleNamespace:
    """The truth source as the ImuTruthTap takes it (a namespace of the two functions)."""
    return types.SimpleNamespace(**vars(StillTruth))
