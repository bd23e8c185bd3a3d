"""benchmarks.solar_vector_error: the sky test's statistics (D-5.33) on series of known correlation, and one real
logged series."""

from __future__ import annotations

import math

import numpy as np
import pytest

from benchmarks.solar_vector_error import series, series_statistics


def _gauss_markov(rng: np.random.Generator, shape: tuple[int, ...], n_t: int, rho: float) -> np.ndarray:
    """(..., n_t) stationary first-order Gauss-Markov of unit variance and one-step correlation ``rho``."""
    x = np.empty((*shape, n_t))
    x[..., 0] = rng.standard_normal(shape)
    for k in range(1, n_t):
        x[..., k] = rho * x[..., k - 1] + math.sqrt(1 - rho * rho) * rng.standard_normal(shape)
    return x


def test_statistics_recover_a_known_correlation_time_spread_and_heading_correlation():
    """A Gauss-Markov of tau = 60 min logged every 10 min (rho = exp(-1/6)) on 40 units: the first lag's slope and
    the 1/e lag give about 60 min (the slope reads ``L / (1 - rho)`` = 65 min, the first-order fit); the rms is the
    series' sigma. Headings: the along axis is common to every heading (correlation 1), the across axis independent
    per heading (about 0); the per-separation table has one row per separation, and psi from the first."""
    rng = np.random.default_rng(7)
    rho = math.exp(-10.0 / 60.0)
    n_u, n_t = 40, 400
    across = 0.1 * _gauss_markov(rng, (n_u, 3), n_t, rho)  # independent per heading
    along = 0.8 * _gauss_markov(rng, (n_u, 1), n_t, rho).repeat(3, axis=1)  # the same at every heading
    err = np.stack([across, along], axis=-1)
    err[0, 0, :5] = np.nan  # invalid solves are left out
    st = series_statistics(err, 10.0, [0.0, 45.0, 90.0])
    np.testing.assert_allclose(st["rms"], [0.1, 0.8], rtol=0.05)
    np.testing.assert_allclose(st["rho_time"][0], [rho, rho], atol=0.02)
    assert st["tau_slope_min"] == pytest.approx([10.0 / (1 - rho)] * 2, rel=0.15)
    np.testing.assert_allclose(st["tau_e_min"], [60.0, 60.0], atol=10.0)
    assert abs(st["rho_heading"][0]) < 0.05 and st["rho_heading"][1] == pytest.approx(1.0)
    np.testing.assert_array_equal(st["heading_sep_deg"], [45.0, 90.0])
    assert st["psi_slope_deg"][1] > 1e6 and st["psi_slope_deg"][0] == pytest.approx(45.0, rel=0.06)


def test_a_logged_clear_sky_series_is_the_calibration_residual_and_the_realistic_sky_is_elevation():
    """One unit at one heading, every 2 h over the day: on the clear Rayleigh sky both local-level parts are the
    calibration's (below 0.15 deg); under the realistic sky the elevation part is several times the across part
    (docs/sensors.md, "The sky test in the local-level frame")."""
    clear = series("reference", "residuals", 1, [30.0], 120.0, "rayleigh")
    real = series("reference", "residuals", 1, [30.0], 120.0, "realistic")
    assert clear.shape == (1, 1, 6, 2) and np.isfinite(clear).all()
    assert np.sqrt(np.nanmean(clear ** 2, axis=(0, 1, 2))).max() < 0.15
    rms = np.sqrt(np.nanmean(real ** 2, axis=(0, 1, 2)))
    assert rms[1] > 3.0 * rms[0] and rms[1] > 0.3
