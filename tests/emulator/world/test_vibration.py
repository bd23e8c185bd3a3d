"""The world's vibration: the drawn signal has the profile's PSD (Welch) and RMS (the closed-form integral),
and the accelerometers' rectification shifts their mean by vre g_rms^2."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.signal import welch

from emulator.devices.imu import AccelErrors, AnalogAccelerometers, ImuTruthTap
from emulator.scenario.presets import preset
from emulator.world.vibration import VibrationModel, psd_at, psd_integral
from protocols.constants import G_STD
from tests.emulator.still_truth import still_truth

FS = 200.0
FIELD = preset("imu", "field")["vibration"]
#: a profile with a rising, a flat and a falling segment (slope -1 too: the closed form's special case)
PROFILE = [(5.0, 0.001), (20.0, 0.02), (50.0, 0.02), (90.0, 0.02 * 50.0 / 90.0)]


@pytest.mark.parametrize("points", [PROFILE, [tuple(p) for p in FIELD["psd"]]])
def test_closed_form_integral_matches_numerical_quadrature(points):
    fp = [p[0] for p in points]
    num = sum(quad(lambda f: float(psd_at(points, np.array([f]))[0]), a, b, epsabs=0, epsrel=1e-10)[0]
              for a, b in itertools.pairwise(fp))
    assert psd_integral(points) == pytest.approx(num, rel=1e-8)


def test_filter_energy_is_the_psd_integral_and_draws_are_seeded():
    v = VibrationModel(PROFILE, (1.0, 0.5, 0.25), FS, np.random.default_rng(3))
    assert float(np.sum(v.taps**2)) == pytest.approx(psd_integral(PROFILE), rel=1e-12)
    assert v.g_rms == pytest.approx(np.sqrt(psd_integral(PROFILE) * np.array([1.0, 0.5, 0.25])), rel=1e-12)
    w = VibrationModel(PROFILE, (1.0, 0.5, 0.25), FS, np.random.default_rng(3))
    a = v.samples(np.arange(0, 5000))
    # one by one, out of order within the held history, and by time: the same samples
    assert np.array_equal(w.sample(4999), a[4999]) and np.array_equal(w.sample(4000), a[4000])
    assert np.array_equal(w.at(4321 / FS), a[4321])
    other = VibrationModel(PROFILE, (1.0, 0.5, 0.25), FS, np.random.default_rng(4)).samples(np.arange(0, 5000))
    assert not np.allclose(other, a)
    # drawn in one go or block by block: the same samples
    assert np.array_equal(VibrationModel(PROFILE, (1.0, 0.5, 0.25), FS, np.random.default_rng(3)).samples(
        np.arange(0, 5000)), a)
    parts = VibrationModel(PROFILE, (1.0, 0.5, 0.25), FS, np.random.default_rng(3))
    assert np.array_equal(np.concatenate([parts.samples(np.arange(i, i + 100)) for i in range(0, 5000, 100)]), a)
    w.sample(20000)
    with pytest.raises(ValueError, match="no longer held"):
        w.samples(np.arange(0, 10))  # long gone: an error, never a wrapped index
    with pytest.raises(ValueError, match="no longer held"):
        w.sample(3)


def test_drawn_signal_has_the_profile_psd_and_rms():
    axes = np.array([1.0, 0.5, 0.25])
    v = VibrationModel(PROFILE, axes, FS, np.random.default_rng(11))
    n = 1 << 17
    x = v.samples(np.arange(0, n)) / G_STD  # g
    # RMS: the PSD integral (the closed form), per axis
    rms = np.sqrt(np.mean(x * x, axis=0))
    assert rms == pytest.approx(np.sqrt(psd_integral(PROFILE) * axes), rel=0.02)
    assert abs(float(np.mean(x[:, 0]))) < 0.01 * rms[0]  # no DC in the profile
    # Welch: in the profile's band the estimate follows the log-log PSD, below it there is (almost) nothing
    f, pxx = welch(x, fs=FS, nperseg=1024, axis=0)
    ref = psd_at(PROFILE, f)[:, None] * axes[None, :]
    for lo, hi in ((7.0, 18.0), (22.0, 48.0), (52.0, 88.0)):
        band = (f >= lo) & (f <= hi)
        ratio = pxx[band] / ref[band]
        assert np.all(np.abs(ratio - 1.0) < 0.3), (lo, hi, ratio.min(), ratio.max())
        assert np.mean(ratio, axis=0) == pytest.approx(np.ones(3), abs=0.06)
    low = f < 3.0
    assert np.all(pxx[low] < 0.02 * PROFILE[0][1] * axes[None, :])
    high = f > 95.0  # beyond the last breakpoint: the filter's skirt only
    assert np.all(pxx[high] < 0.2 * PROFILE[-1][1] * axes[None, :])


def _vibration() -> VibrationModel:
    return VibrationModel(FIELD["psd"], [4 * a for a in FIELD["axes"]], FS, np.random.default_rng(21))


def _accel_mean(vre: float, n: int, look_ahead: bool = True) -> tuple[np.ndarray, np.ndarray]:
    vib = _vibration()
    tap = ImuTruthTap(still_truth(), vib)  # type: ignore[arg-type]
    e = AccelErrors(bias_repeatability_mg=(0, 0, 0), bias_instability_mg=(0, 0, 0), noise_ug_rt_hz=0,
                    scale_factor_ppm=(0, 0, 0), scale_error_ppm=(0, 0, 0), misalignment_mrad=0,
                    vre_ug_per_g2=(vre, vre, vre))
    acc = AnalogAccelerometers(tap, np.random.default_rng(1), e)
    acc._look_ahead = look_ahead
    out = np.empty((n, 3))
    for k in range(1, n + 1):
        acc.sample(k / FS, (k - 1) / FS)
        out[k - 1] = acc.last_measured
    v = _vibration().samples(np.arange(1, n + 1))  # the same draws again (the run's are no longer held)
    return out, v


def test_rectification_shifts_the_mean_by_vre_g_rms_squared():
    n = 40000
    vre = 1000.0  # ug/g^2, large enough to stand above the finite-sample mean of the vibration itself
    with_vre, v = _accel_mean(vre, n)
    without, v0 = _accel_mean(0.0, n)
    assert np.array_equal(v, v0)
    k = vre * 1e-6 / G_STD  # 1/(m/s^2)
    # exactly: the rectified part is k v^2, sample by sample (the ADC's clip is far away)
    assert np.mean(with_vre - without, axis=0) == pytest.approx(k * np.mean(v * v, axis=0), rel=1e-9)
    # and in the mean: k g_rms^2 (m/s^2) of the profile's closed form, per axis
    g_rms2 = psd_integral([tuple(p) for p in FIELD["psd"]]) * 4 * np.array(FIELD["axes"])
    shift = np.mean(with_vre, axis=0) - np.mean(v, axis=0)
    assert shift == pytest.approx(vre * 1e-6 * G_STD * g_rms2, rel=0.05)
    # the look-ahead (vectorised) path gives the same bits as the per-interval path
    per, _ = _accel_mean(vre, 3000, look_ahead=False)
    assert np.array_equal(per, with_vre[:3000])


def test_field_profile_is_moderate_and_within_the_imu_band():
    pts = [tuple(p) for p in FIELD["psd"]]
    assert pts[-1][0] <= FS / 2
    g_rms = math.sqrt(psd_integral(pts))
    assert 0.3 < g_rms < 0.6  # vertical, g: a moderate land vehicle (docs/sensors.md, "Vibration")
