"""Vehicle vibration: body-frame acceleration noise drawn from a power spectral density.

A profile is given as MIL-STD-810 / RTCA DO-160 style breakpoints ``[(f_i, S_i)]`` (Hz, g^2/Hz), the PSD
straight between breakpoints on log-log axes and zero outside ``[f_0, f_last]``, scaled per body axis
(x right, y forward, z up) by ``axes``. The world draws, for every axis independently, white Gaussian noise at
the IMU's trigger rate ``fs`` through a linear-phase FIR filter (``scipy.signal.firwin2``) whose gain is
``|H(f)| = sqrt(S(f) fs / 2)``: unit white noise at ``fs`` has the one-sided PSD ``2 / fs``, so the output has
the one-sided PSD ``|H|^2 2 / fs = S(f)``. The filter is normalised so that the output variance equals the PSD
integral exactly (``sum h^2 = integral S df``), so the drawn signal's RMS is the profile's g_rms.

Sample ``k`` is the mean vibration acceleration over the trigger interval that ends at ``k / fs``: what the
FPGA's boxcar-averaging ADC and the STIM's integrating output see. The filter resolves about ``fs / NUMTAPS``
(0.4 Hz at 200 Hz): finer detail of a profile is smoothed, its RMS is kept. Components above the IMU's Nyquist
frequency are outside the model (the scenario check rejects a profile reaching beyond ``fs / 2``); the
vibration is linear acceleration only (no angular vibration, so no coning or sculling), and its displacement
(millimetres) is not added to the trajectory: it adds to the specific force the accelerometers measure and,
through their g-sensitivity, to the gyros' bias (docs/sensors.md, "Vibration").
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence

import numpy as np
from scipy.signal import firwin2, lfilter

from protocols.constants import G_STD

__all__ = ["VibrationModel", "psd_at", "psd_integral"]

#: FIR length (odd: linear phase, type I); at 200 Hz a resolution of ~0.4 Hz
NUMTAPS = 513
#: samples drawn per block
BLOCK = 2048


def psd_at(points: Sequence[tuple[float, float]], f: np.ndarray) -> np.ndarray:
    """The profile's PSD (g^2/Hz) at frequencies ``f`` (Hz): log-log interpolation, 0 outside the breakpoints."""
    fp = np.array([p[0] for p in points], dtype=np.float64)
    sp = np.array([p[1] for p in points], dtype=np.float64)
    f = np.asarray(f, dtype=np.float64)
    out = np.zeros_like(f)
    inside = (f >= fp[0]) & (f <= fp[-1]) & (f > 0)
    out[inside] = np.exp(np.interp(np.log(f[inside]), np.log(fp), np.log(sp)))
    return out


def psd_integral(points: Sequence[tuple[float, float]]) -> float:
    """The closed-form integral of the log-log profile, g^2 (its square root is g_rms).

    Per segment with slope ``b = ln(S2/S1) / ln(f2/f1)``: ``S1 f1 ((f2/f1)^(b+1) - 1) / (b + 1)``, or
    ``S1 f1 ln(f2/f1)`` when ``b = -1``."""
    total = 0.0
    for (f1, s1), (f2, s2) in itertools.pairwise(points):
        r = f2 / f1
        b = math.log(s2 / s1) / math.log(r)
        total += s1 * f1 * math.log(r) if abs(b + 1.0) < 1e-12 else s1 * f1 * (r ** (b + 1.0) - 1.0) / (b + 1.0)
    return total


class VibrationModel:
    """Body-frame vibration acceleration on the IMU's trigger grid (see module docstring).

    Parameters
    ----------
    psd : breakpoints ``[(f_hz, g2_per_hz), ...]``, frequencies increasing, the last at most ``rate_hz / 2``.
    axes : (3,) PSD level multiplier per body axis (x right, y forward, z up).
    rate_hz : the IMU's trigger rate ``fs``, Hz (sample ``k`` is the interval ending at ``k / fs``).
    rng : the world's vibration generator.
    """

    def __init__(self, psd: Sequence[tuple[float, float]], axes: Sequence[float], rate_hz: float,
                 rng: np.random.Generator) -> None:
        self.points = [(float(f), float(s)) for f, s in psd]
        self.axes = np.asarray(axes, dtype=np.float64)
        self.fs = float(rate_hz)
        self.rng = rng
        #: variance per axis, (m/s^2)^2: the PSD integral times the axis multiplier
        self.variance = psd_integral(self.points) * self.axes * G_STD**2
        #: g_rms per axis (the profile's RMS), g
        self.g_rms = np.sqrt(psd_integral(self.points) * self.axes)
        nyq = self.fs / 2.0
        grid = np.linspace(0.0, nyq, 4097)
        gain = np.sqrt(psd_at(self.points, grid) * self.fs / 2.0)
        h = firwin2(NUMTAPS, grid / nyq, gain, window="hamming")
        # normalise: sum h^2 = integral of the PSD (per unit multiplier, g^2), so var = the integral exactly
        h *= math.sqrt(psd_integral(self.points) / float(np.sum(h * h)))
        self.taps = h
        self._scale = np.sqrt(self.axes) * G_STD  # per axis, g -> m/s^2 and the axis level
        self._zi = np.zeros((3, NUMTAPS - 1))
        self._k0 = 0
        self._buf = np.zeros((0, 3))
        # fill the filters' memory so that the first sample is already stationary
        self._draw(BLOCK)
        self._buf = np.zeros((0, 3))
        self._k0 = 0

    def _draw(self, n: int) -> np.ndarray:
        w = self.rng.standard_normal((3, n))
        out = np.empty((n, 3))
        for ax in range(3):
            y, self._zi[ax] = lfilter(self.taps, [1.0], w[ax], zi=self._zi[ax])
            out[:, ax] = y * self._scale[ax]
        return out

    def _ensure(self, k_max: int) -> None:
        end = self._k0 + len(self._buf)
        if k_max < end:
            return
        # always in blocks of BLOCK draws: the samples do not depend on who asked for what, when
        new = np.concatenate([self._draw(BLOCK) for _ in range((k_max - end) // BLOCK + 1)])
        keep = self._buf[-BLOCK:]  # one block of history for callers a little behind (the gyro's group delay)
        self._k0 = end - len(keep)
        self._buf = np.concatenate([keep, new])

    def samples(self, k: np.ndarray) -> np.ndarray:
        """Vibration (n, 3) m/s^2 of trigger intervals ``k`` (n,) ints (non-negative, at most one block behind
        the latest sample drawn)."""
        k = np.asarray(k, dtype=np.int64)
        self._ensure(int(k.max()))
        i = k - self._k0
        if i.min() < 0:
            raise ValueError(f"vibration sample {int(k.min())} is no longer held (oldest {self._k0})")
        return self._buf[i]

    def sample(self, k: int) -> np.ndarray:
        """Vibration (3,) m/s^2 of trigger interval ``k``."""
        self._ensure(k)
        if k < self._k0:
            raise ValueError(f"vibration sample {k} is no longer held (oldest {self._k0})")
        return self._buf[k - self._k0]

    def at(self, t1: float) -> np.ndarray:
        """Vibration (3,) m/s^2 of the trigger interval that ends at ``t1`` (s): sample ``round(t1 fs)``."""
        k = round(t1 * self.fs)
        i = k - self._k0
        if 0 <= i < len(self._buf):  # the common case, once per IMU tick: already drawn
            return self._buf[i]
        return self.sample(k)
