"""The micro-polarizers' extinction ratio over wavelength, and the effective ratio of the monochrome sensor under a
blue sky.

A wire-grid polarizer passes the field across its wires (TM) and blocks the one along them (TE). Between two
wires the blocked field is a parallel-plate waveguide mode below cut-off: for a gap ``a`` narrower than half the
wavelength it decays along the wire height ``h`` with ``kappa(lambda) = 2 pi sqrt(1 / (2 a)^2 - 1 / lambda^2)``, so
the leakage is ``T_TE ~ exp(-2 kappa h)`` and, with a wavelength-flat pass transmittance ``T_TM``, the extinction
ratio is ``ER(lambda) = ER_ref exp(2 h (kappa(lambda) - kappa(lambda_ref)))``: it falls towards the blue, steeply
as ``lambda`` approaches the cut-off ``2 a`` (the TE_1 cut-off of a parallel-plate waveguide of width ``a``: a
simplified model of ours, not a rigorous grating calculation; docs/sensors.md).

Skylight is Rayleigh-scattered sunlight: relative spectral radiance ``B(lambda, 5778 K) lambda^-4`` (the Sun as a
black body, Planck's law, times the lambda^-4 of Rayleigh scattering), seen through the sensor's quantum efficiency
``QE(lambda)``. A monochrome pixel behind a polarizer at angle ``theta`` integrates Malus' law over wavelength:
``I = 1/2 int w (T_max + T_min) S0 + (T_max - T_min)(S1 cos 2theta + S2 sin 2theta) dlambda`` with ``w = L QE``;
for a polarization state that is the same at every wavelength (the Rayleigh DOP and AOP are) this is Malus' law
with ``T_max,eff = int w T_max``, ``T_min,eff = int w T_min``, so the effective ratio is
``ER_eff = int w / int (w / ER(lambda))`` (``T_max`` flat), and the camera's Malus model uses
``D = (ER_eff - 1) / (ER_eff + 1)`` (docs/sensors.md, "Polarization camera", extinction ratio).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

__all__ = [
    "IMX250MZR_QE",
    "WireGrid",
    "effective_extinction_ratio",
    "skylight_weights",
]

#: Planck's law constants: h c / k_B (m K)
_HC_K = 0.014387769
T_SUN_K = 5778.0

#: Relative quantum efficiency of the monochrome IMX250MZR (nm -> QE), the shape of the sensor's published curve read
#: coarsely (peak near 500-550 nm, half of it near 420 and 700 nm); an assumption [D] (docs/sensors.md).
IMX250MZR_QE: tuple[tuple[float, float], ...] = (
    (400.0, 0.30), (450.0, 0.50), (500.0, 0.62), (550.0, 0.60), (600.0, 0.52), (650.0, 0.42), (700.0, 0.32),
    (750.0, 0.22), (800.0, 0.15), (850.0, 0.10), (900.0, 0.06), (950.0, 0.03), (1000.0, 0.01))


@dataclass(frozen=True)
class WireGrid:
    """A wire-grid micro-polarizer: extinction ratio ``er_ref`` at ``ref_nm``, gap ``gap_nm``, wire height
    ``height_nm`` (module docstring). ``gap_nm`` must be below half the shortest wavelength used."""

    er_ref: float = 300.0
    ref_nm: float = 525.0
    gap_nm: float = 75.0
    height_nm: float = 150.0

    def kappa(self, lam_nm: np.ndarray) -> np.ndarray:
        """Decay constant of the blocked mode, 1/nm."""
        lam = np.asarray(lam_nm, dtype=np.float64)
        c = 1.0 / (2.0 * self.gap_nm) ** 2 - 1.0 / lam**2
        if np.any(c <= 0):
            raise ValueError(f"wire grid gap {self.gap_nm} nm is not below half of every wavelength "
                             f"(shortest {float(lam.min()):g} nm)")
        return 2.0 * math.pi * np.sqrt(c)

    def extinction_ratio(self, lam_nm: np.ndarray) -> np.ndarray:
        """``ER(lambda) = ER_ref exp(2 h (kappa(lambda) - kappa(lambda_ref)))``."""
        lam = np.asarray(lam_nm, dtype=np.float64)
        k_ref = self.kappa(np.array([self.ref_nm]))[0]
        return self.er_ref * np.exp(2.0 * self.height_nm * (self.kappa(lam) - k_ref))


def skylight_weights(lam_nm: np.ndarray, qe: Sequence[tuple[float, float]] = IMX250MZR_QE,
                     t_sun_k: float = T_SUN_K) -> np.ndarray:
    """Relative detected photo-electrons per nm of a Rayleigh sky: ``B(lambda, T_sun) lambda^-4 QE(lambda)``
    times ``lambda`` (energy to photons), normalised to sum 1 over ``lam_nm``."""
    lam = np.asarray(lam_nm, dtype=np.float64)
    lam_m = lam * 1e-9
    planck = 1.0 / (lam_m**5 * np.expm1(_HC_K / (lam_m * t_sun_k)))
    q = np.interp(lam, [p[0] for p in qe], [p[1] for p in qe], left=0.0, right=0.0)
    w = planck * lam_m**-4 * q * lam_m
    return w / w.sum()


def effective_extinction_ratio(grid: WireGrid, lam_nm: np.ndarray | None = None,
                               weights: np.ndarray | None = None) -> float:
    """``ER_eff = sum w / sum (w / ER(lambda))`` over ``lam_nm`` (default 400-1000 nm in 1 nm steps) with the
    skylight weights (default :func:`skylight_weights`)."""
    lam = np.arange(400.0, 1000.5, 1.0) if lam_nm is None else np.asarray(lam_nm, dtype=np.float64)
    w = skylight_weights(lam) if weights is None else np.asarray(weights, dtype=np.float64)
    return float(np.sum(w) / np.sum(w / grid.extinction_ratio(lam)))
