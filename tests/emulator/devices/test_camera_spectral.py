"""The wire-grid extinction ratio over wavelength and the effective ratio of the monochrome sensor under a blue sky."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from emulator.devices.camera.spectral import WireGrid, effective_extinction_ratio, skylight_weights
from emulator.devices.sensors import camera_config
from emulator.testing import load_test_scenario

SCENARIOS = Path(__file__).resolve().parents[3] / "scenarios"
LAM = np.arange(400.0, 1000.5, 1.0)


def test_wire_grid_ratio_is_the_waveguide_closed_form_and_falls_towards_the_blue():
    g = WireGrid(er_ref=300.0, ref_nm=525.0, gap_nm=75.0, height_nm=150.0)
    assert g.extinction_ratio(np.array([525.0]))[0] == pytest.approx(300.0, rel=1e-14)

    def kappa(lam):
        return 2 * math.pi * math.sqrt(1 / 150.0**2 - 1 / lam**2)

    for lam in (400.0, 450.0, 650.0, 900.0):
        want = 300.0 * math.exp(2 * 150.0 * (kappa(lam) - kappa(525.0)))
        assert g.extinction_ratio(np.array([lam]))[0] == pytest.approx(want, rel=1e-12)
    er = g.extinction_ratio(LAM)
    assert np.all(np.diff(er) > 0)  # monotonic: the blue leaks most
    assert er[0] < 0.7 * 300.0 < 300.0 < er[-1]
    with pytest.raises(ValueError, match="not below half"):
        WireGrid(gap_nm=210.0).extinction_ratio(LAM)  # cut-off 420 nm inside the band


def test_effective_ratio_is_broadband_malus():
    """Integrate Malus' law over wavelength for the four channels, each with its own ER(lambda), and recover the
    DOP the sensor reports: it is the true DOP times D_eff = (ER_eff - 1)/(ER_eff + 1), exactly."""
    g = WireGrid()
    w = skylight_weights(LAM)
    er = g.extinction_ratio(LAM)
    t_max, t_min = np.ones_like(er), 1.0 / er
    dop, aop = 0.6, math.radians(23.0)
    s0, s1, s2 = 1.0, dop * math.cos(2 * aop), dop * math.sin(2 * aop)
    i = {th: float(np.sum(w * 0.5 * ((t_max + t_min) * s0 + (t_max - t_min) * (s1 * math.cos(2 * math.radians(th))
                                                                              + s2 * math.sin(2 * math.radians(th))))))
         for th in (0, 45, 90, 135)}
    m_s0 = (i[0] + i[45] + i[90] + i[135]) / 2
    m_dop = math.hypot(i[0] - i[90], i[45] - i[135]) / m_s0
    m_aop = 0.5 * math.atan2(i[45] - i[135], i[0] - i[90])
    er_eff = effective_extinction_ratio(g, LAM, w)
    assert m_dop == pytest.approx(dop * (er_eff - 1) / (er_eff + 1), rel=1e-12)
    assert m_aop == pytest.approx(aop, abs=1e-12)  # the extinction ratio scales the DOP only


def test_sky_spectrum_lowers_the_ratio_and_a_bluer_sky_lowers_it_more():
    g = WireGrid()
    er_sky = effective_extinction_ratio(g)
    assert er_sky == pytest.approx(281.4, abs=0.5)  # the figure docs/sensors.md gives
    # a single wavelength gives that wavelength's ratio; a sky weighted further to the blue gives less
    delta = np.zeros_like(LAM)
    delta[LAM == 525.0] = 1.0
    assert effective_extinction_ratio(g, LAM, delta) == pytest.approx(300.0, rel=1e-12)
    bluer = skylight_weights(LAM) * (LAM / 525.0) ** -4
    assert effective_extinction_ratio(g, LAM, bluer) < er_sky
    # harmonic mean: below the plain weighted mean of ER, within the band's extremes
    w = skylight_weights(LAM)
    er = g.extinction_ratio(LAM)
    assert er.min() < er_sky < float(np.sum(w * er)) < er.max()
    # Rayleigh: the skylight's weights fall faster than the sun's towards the red
    assert w[LAM == 450.0][0] > w[LAM == 700.0][0]


def test_camera_uses_the_effective_ratio_unless_the_scenario_overrides_it():
    scn = load_test_scenario(SCENARIOS / "static_psns_camera.yaml")
    assert camera_config(scn).extinction_ratio == pytest.approx(effective_extinction_ratio(WireGrid()), rel=1e-12)
    scn2 = load_test_scenario(SCENARIOS / "static_psns_camera.yaml", {"sensors.camera.extinction_ratio": 150.0})
    assert camera_config(scn2).extinction_ratio == 150.0
    ideal = load_test_scenario(SCENARIOS / "static_psns_camera.yaml", {"sensors.camera.preset": "ideal"})
    assert camera_config(ideal).extinction_ratio == 1e12
