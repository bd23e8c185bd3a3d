"""Overlapping Allan deviation (IEEE Std 952), to check the error models' noise terms."""

from __future__ import annotations

import numpy as np

__all__ = ["allan_deviation"]


def allan_deviation(y: np.ndarray, dt: float, taus: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Overlapping Allan deviation of rate samples ``y`` (n,) or (n, k) taken every ``dt``.

    Returns the cluster times actually used (multiples of ``dt``) and the deviations.
    """
    y = np.asarray(y, dtype=np.float64)
    theta = np.concatenate([np.zeros((1, *y.shape[1:])), np.cumsum(y, axis=0) * dt])
    n = len(y)
    ms = np.unique(np.maximum(1, np.round(np.asarray(taus) / dt).astype(int)))
    ms = ms[ms < n // 2]
    out = []
    for m in ms:
        d = theta[2 * m:] - 2 * theta[m:-m] + theta[:-2 * m]
        out.append(np.sqrt(np.mean(d * d, axis=0) / (2.0 * (m * dt) ** 2)))
    return ms * dt, np.array(out)
