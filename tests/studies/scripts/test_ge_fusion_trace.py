"""``studies.scripts.ge_fusion_trace``'s split of the fused heading against the MIMU/polarization
sub-filter's (D-5.36)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from firmware_model.variants.federated import fuse_common_states
from studies.scripts.ge_fusion_trace import heading_split


def _spd(rng: np.random.Generator, scale: np.ndarray) -> np.ndarray:
    a = rng.normal(size=(6, 6))
    return (a @ a.T + 6 * np.eye(6)) * np.outer(scale, scale)


def _record(seed: int, p1_scale: float = 1.0) -> dict:
    """Two sub-filters' common states ``[phi, eps]`` (rad, rad/s), fused by the firmware's master."""
    rng = np.random.default_rng(seed)
    scale = np.array([1e-2, 1e-2, 2e-2, 1e-4, 1e-4, 1e-4])
    p1, p2 = _spd(rng, scale) * p1_scale, _spd(rng, scale)
    x1, x2 = rng.normal(size=6) * scale, rng.normal(size=6) * scale
    xg, pg = fuse_common_states([(x1, p1), (x2, p2)])
    az = rng.uniform(0, 2 * math.pi)
    return {"x1": x1, "x2": x2, "xg": xg, "P1": p1, "Pg": pg, "u": np.array([math.cos(az), math.sin(az), 0.0])}


@pytest.mark.parametrize("seed", range(5))
def test_the_parts_add_up_to_the_fused_heading_less_sub_filter_2s(seed):
    r = _record(seed)
    parts = heading_split(r)
    # heading = -yaw: the fused heading less sub-filter 2's is -(x_g - x_2)_U, deg
    assert float(parts.sum()) == pytest.approx(-(r["xg"][2] - r["x2"][2]) * 180 / math.pi, rel=1e-9, abs=1e-12)
    assert np.count_nonzero(np.abs(parts) > 1e-9) >= 3  # spread over the components, not one lump


def test_sub_filters_that_agree_give_no_parts():
    r = _record(7)
    r["x1"] = r["x2"].copy()
    assert np.allclose(heading_split(r), 0.0, atol=1e-12)


def test_a_sub_filter_1_that_knows_nothing_pulls_nothing():
    r = _record(3, p1_scale=1e8)
    assert abs(float(heading_split(r).sum())) < 1e-5
