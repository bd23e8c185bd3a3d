"""Sky polarization: Rayleigh geometry, Berry's neutral points, clouds, occluders, frames."""

from __future__ import annotations

import math

import numpy as np
import pytest

from emulator.scenario.world_schema import SkySpec
from emulator.world.sky import SkyModel, sky_from_spec
from protocols.constants import DEG

S_BEIJING = np.array([-0.876416, -0.282797, 0.389770])
S_BEIJING = S_BEIJING / np.linalg.norm(S_BEIJING)


def upper_rays(n, seed=1):
    v = np.random.default_rng(seed).standard_normal((n, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    v[:, 2] = np.abs(v[:, 2])
    return v


def e_of(f):
    return np.stack([f.ex, f.ey, f.ez], axis=1)


def test_rayleigh_e_vectors_are_perpendicular_to_sun_and_view():
    v = upper_rays(5000)
    f = SkyModel("rayleigh", p_max=0.7).evaluate_enu(0.0, S_BEIJING, v)
    e = e_of(f)
    assert np.allclose(np.linalg.norm(e, axis=1), 1.0, atol=1e-12)
    assert np.max(np.abs(e @ S_BEIJING)) < 1e-12
    assert np.max(np.abs(np.sum(e * v, axis=1))) < 1e-12
    cg = v @ S_BEIJING
    assert np.allclose(f.dop, 0.7 * (1 - cg**2) / (1 + cg**2), atol=1e-15)


def test_rayleigh_dop_extremes():
    sky = SkyModel("rayleigh", p_max=0.7)
    s = np.array([0.0, 0.0, 1.0])
    v = np.array([[1.0, 0.0, 0.0], [0.0, math.sin(0.01), math.cos(0.01)]])
    f = sky.evaluate_enu(0.0, s, v)
    assert math.isclose(f.dop[0], 0.7, abs_tol=1e-15)
    assert f.dop[1] < 1e-4
    f = sky.evaluate_enu(0.0, s, np.array([[0.0, 0.0, 1.0]]))  # the sun itself: unpolarized, E still ⟂ V
    assert f.dop[0] == 0.0 and abs(f.ez[0]) < 1e-12


def test_berry_without_separation_is_rayleigh():
    v = upper_rays(3000)
    for s in (S_BEIJING, np.array([0.532125, -0.757852, 0.377496]) / 0.9999999):
        s = s / np.linalg.norm(s)
        r = SkyModel("rayleigh").evaluate_enu(0.0, s, v)
        b = SkyModel("berry", neutral_point_sep=0.0).evaluate_enu(0.0, s, v)
        assert np.allclose(r.dop, b.dop, atol=1e-12)
        assert np.max(np.abs(np.abs(np.sum(e_of(r) * e_of(b), axis=1)) - 1.0)) < 1e-9


def test_berry_neutral_points_sit_on_the_sun_vertical():
    sep = 20.0 * DEG
    sky = SkyModel("berry", p_max=0.7, neutral_point_sep=sep)
    az_s, el_s = 200.0 * DEG, 35.0 * DEG

    def ray(az, el):
        return np.array([math.sin(az) * math.cos(el), math.cos(az) * math.cos(el), math.sin(el)])

    s = ray(az_s, el_s)
    pts = np.array([ray(az_s, el_s + sep / 2), ray(az_s, el_s - sep / 2), ray(az_s, el_s),
                    ray(az_s + math.pi, 30 * DEG)])
    f = sky.evaluate_enu(0.0, s, pts)
    assert f.dop[0] < 1e-9 and f.dop[1] < 1e-9  # Babinet above, Brewster below
    assert f.dop[2] > 0.01  # the sun itself is no longer a neutral point
    v = upper_rays(500)
    fb = sky.evaluate_enu(0.0, s, v)
    assert np.max(np.abs(np.sum(e_of(fb) * v, axis=1))) < 1e-12
    # far from the sun Berry's E-vectors stay close to Rayleigh's
    fr = SkyModel("rayleigh").evaluate_enu(0.0, s, v)
    far = v @ s < math.cos(90 * DEG)
    dots = np.abs(np.sum(e_of(fb)[far] * e_of(fr)[far], axis=1))
    assert np.median(np.degrees(np.arccos(np.clip(dots, 0, 1)))) < 5.0


def test_clouds_lower_dop_and_scramble_aop():
    spec = SkySpec(model="rayleigh", clouds=[{"az_deg": 0.0, "el_deg": 60.0, "radius_deg": 15.0, "dop_scale": 0.25,
                            "aop_sigma_deg": 20.0}])
    sky = sky_from_spec(spec, np.random.default_rng(5))
    clear = SkyModel()
    centre = np.array([0.0, math.cos(60 * DEG), math.sin(60 * DEG)])
    v = upper_rays(20000, seed=2)
    inside = v @ centre > math.cos(15 * DEG)
    assert inside.sum() > 200
    fc, f0 = sky.evaluate_enu(10.0, S_BEIJING, v), clear.evaluate_enu(10.0, S_BEIJING, v)
    assert np.allclose(fc.dop[inside], 0.25 * f0.dop[inside])
    assert np.allclose(fc.dop[~inside], f0.dop[~inside])
    ang = np.degrees(np.arccos(np.clip(np.abs(np.sum(e_of(fc) * e_of(f0), axis=1)), 0, 1)))
    assert np.all(ang[~inside] < 1e-5)  # arccos resolution near 1
    rms = math.sqrt(np.mean(ang[inside] ** 2))
    assert 10.0 < rms < 30.0  # ~ aop_sigma (angles folded into [0, 90])
    assert np.max(np.abs(np.sum(e_of(fc) * v, axis=1))) < 1e-9
    # deterministic: the same cloud twice
    again = sky.evaluate_enu(10.0, S_BEIJING, v)
    assert np.array_equal(again.ex, fc.ex)
    # the time window
    spec2 = SkySpec(model="rayleigh", clouds=[{"az_deg": 0.0, "el_deg": 60.0, "radius_deg": 15.0, "start_s": 100.0}])
    f_before = sky_from_spec(spec2).evaluate_enu(10.0, S_BEIJING, v)
    assert np.allclose(f_before.dop, f0.dop)


def test_occluders_and_ground_are_unpolarized():
    spec = SkySpec(model="rayleigh", occluders=[{"az_min_deg": 350.0, "az_max_deg": 20.0, "el_max_deg": 30.0}])
    sky = sky_from_spec(spec)
    def enu(az_deg: float, el_deg: float) -> list[float]:
        az, el = az_deg * DEG, el_deg * DEG
        return [math.sin(az) * math.cos(el), math.cos(az) * math.cos(el), math.sin(el)]

    v = np.array([enu(5, 10), enu(355, 20), enu(40, 10), [0.6, 0.0, -0.8]])
    f = sky.evaluate_enu(0.0, S_BEIJING, v)
    assert f.dop[0] == 0.0 and f.dop[1] == 0.0 and f.dop[2] > 0.1 and f.dop[3] == 0.0
    assert f.radiance[0] == pytest.approx(0.3) and f.radiance[2] == 1.0


def test_any_frame_gives_the_rotated_field():
    from firmware_model.attitude import a2mat

    c_bn = a2mat(0.2, -0.3, 1.1)
    c_nb = c_bn.T
    v_n = upper_rays(1000)
    v_b = v_n @ c_nb.T
    for model in ("rayleigh", "berry"):
        sky = SkyModel(model)
        fn = sky.evaluate_enu(0.0, S_BEIJING, v_n)
        fb = sky.evaluate(0.0, c_nb @ S_BEIJING, v_b[:, 0], v_b[:, 1], v_b[:, 2], c_nb)
        assert np.allclose(fn.dop, fb.dop, atol=1e-12)
        e_back = e_of(fb) @ c_bn.T
        assert np.max(np.abs(np.abs(np.sum(e_back * e_of(fn), axis=1)) - 1)) < 1e-9


def _vertical_rays(sun_el_deg, n=721):
    """Rays along the sun's vertical (az 0 side = the sun), elevation -0..180 through the zenith."""
    a = np.linspace(0.5, 179.5, n) * DEG  # angle from the horizon below the sun, over the zenith
    return np.stack([np.zeros(n), np.cos(a), np.sin(a)], axis=1), a


def test_realistic_sky_max_dop_falls_with_turbidity():
    """Aerosol (unpolarized, Henyey-Greenstein) dilutes the molecular DOP: ~0.7 at T=2, ~0.55 at T=3, ~0.4 at T=5
    (clear skies rarely exceed 0.75: Zhang et al. 2021; hazy skies fall to ~0.3-0.4)."""
    s = np.array([0.0, math.cos(40 * DEG), math.sin(40 * DEG)])
    v = upper_rays(20000)
    top = [float(SkyModel("realistic", turbidity=t).evaluate_enu(0, s, v).dop.max()) for t in (1.0, 2.0, 3.0, 5.0)]
    assert top[0] == pytest.approx(0.946, abs=0.005)  # molecules only: the depolarization factor of air
    assert top[0] > top[1] > top[2] > top[3]
    assert 0.62 < top[1] < 0.75 and 0.5 < top[2] < 0.62 and 0.33 < top[3] < 0.46


def test_realistic_sky_has_neutral_points_and_an_unpolarized_aureole():
    sky = SkyModel("realistic", neutral_point_sep=40 * DEG, turbidity=3.0)
    # Babinet 20 deg above the sun, Brewster 20 deg below it, Arago 20 deg above the antisun (visible when the sun
    # is lower than 20 deg); angles along the sun's vertical from the horizon under the sun, over the zenith
    for s_el, centres in ((35.0, (55.0, 15.0)), (10.0, (30.0, 170.0))):
        s = np.array([0.0, math.cos(s_el * DEG), math.sin(s_el * DEG)])
        v, a = _vertical_rays(s_el)
        f = sky.evaluate_enu(0, s, v)
        ang = np.degrees(a)
        for centre in centres:
            win = np.abs(ang - centre) < 3.0
            assert f.dop[win].min() < 0.01, (s_el, centre)
        far = np.abs(ang - 90.0 - s_el) < 20.0  # the DOP maximum, 90 deg from the sun, stays polarized
        assert f.dop[far].max() > 0.4
    # the aureole: within 10 deg of the sun the sky is brighter than anywhere 60+ deg away and nearly unpolarized
    s = np.array([0.0, math.cos(35 * DEG), math.sin(35 * DEG)])
    v = upper_rays(20000)
    f = sky.evaluate_enu(0, s, v)
    gam = np.degrees(np.arccos(np.clip(v @ s, -1, 1)))
    assert f.radiance[gam < 10].min() > 3.0 * np.median(f.radiance[gam > 60])
    assert f.dop[gam < 10].max() < 0.1


def test_realistic_sky_with_the_sun_at_the_zenith_is_finite_and_symmetric():
    s = np.array([0.0, 0.0, 1.0])
    v = upper_rays(4000)
    f = SkyModel("realistic").evaluate_enu(0, s, v)
    for x in (f.dop, f.ex, f.ey, f.ez, f.radiance):
        assert np.all(np.isfinite(x))
    e = e_of(f)
    assert np.allclose(np.einsum("ij,ij->i", e, v), 0.0, atol=1e-9)
    # E-vectors are tangent to circles round the zenith (perpendicular to the sun and the ray)
    horiz = v[:, 2] < 0.9
    assert np.allclose(e[horiz, 2], 0.0, atol=1e-6)


def test_realistic_is_the_scenario_default_and_validates_its_range():
    from pydantic import ValidationError

    assert SkySpec().model == "realistic"
    assert sky_from_spec(SkySpec()).delta == pytest.approx(20.0 * DEG)
    with pytest.raises(ValidationError):
        SkySpec(turbidity=0.5)
