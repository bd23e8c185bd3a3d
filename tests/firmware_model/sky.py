"""Test helper: a Rayleigh sky seen by a DoFP polarization camera (docs/reference/algorithms.md sections 2.1-2.3).

Independent of the firmware's solve: the E-vector is ``S x V`` (Rayleigh), its projection on the
image plane gives the image angle psi (docs/architecture.md "Conventions"), Malus' law with the extinction ratio gives
the four channel
intensities, then shot noise, read noise and 12-bit quantization; the observation (AOP, DOP) comes
from the channel Stokes parameters, as on the camera.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from firmware_model.psns_geometry import CameraGeometry

THETA_P = np.deg2rad([0.0, 45.0, 90.0, 135.0])


@dataclass
class SkyObservation:
    x_px: np.ndarray
    y_px: np.ndarray
    aop_deg: np.ndarray
    dop: np.ndarray
    s0_dn: np.ndarray
    psi_true: np.ndarray


def rayleigh(s_c: np.ndarray, v: np.ndarray, p_max: float = 0.8) -> tuple[np.ndarray, np.ndarray]:
    """DOP and unit E-vectors (camera frame) for sun ``s_c`` and view rays ``v`` (N, 3)."""
    cg = v @ s_c
    dop = p_max * (1.0 - cg * cg) / (1.0 + cg * cg)
    e = np.cross(s_c[None, :], v)
    e /= np.linalg.norm(e, axis=1, keepdims=True)
    return dop, e


def observe_sky(s_c: np.ndarray, cam: CameraGeometry, stride_px: int = 32, rng: np.random.Generator | None = None,
                p_max: float = 0.8, extinction_ratio: float = 300.0, full_well_e: float = 10000.0,
                read_noise_e: float = 5.0, bits: int = 12, signal_fraction: float = 0.8) -> SkyObservation:
    """Observation points on a ``stride_px`` grid of 1-based pixels; ``rng=None`` is the noise-free camera.

    ``signal_fraction`` sets S0 relative to the full well (the exposure control's target).
    Noise-free also means no quantization and an ideal polarizer (infinite extinction ratio) unless
    ``extinction_ratio`` is given with a noisy camera.
    """
    xs = np.arange(1 + stride_px // 2, cam.nx + 1, stride_px)
    ys = np.arange(1 + stride_px // 2, cam.ny + 1, stride_px)
    xx, yy = np.meshgrid(xs, ys)
    x, y = xx.ravel(), yy.ravel()
    v = cam.view_rays(x.astype(np.float64), y.astype(np.float64))  # pixel numbers, exact as doubles
    dop, e = rayleigh(np.asarray(s_c, dtype=np.float64), v, p_max)
    psi = np.arctan2(e[:, 1], e[:, 0])
    s0_e = signal_fraction * full_well_e * np.ones_like(dop)
    d = 1.0 if rng is None else (extinction_ratio - 1.0) / (extinction_ratio + 1.0)
    # Malus: I_theta = S0/2 [1 + D DOP cos(2 (psi - theta_p))]
    inten = 0.5 * s0_e[:, None] * (1.0 + d * dop[:, None] * np.cos(2.0 * (psi[:, None] - THETA_P[None, :])))
    if rng is not None:
        inten = rng.poisson(inten).astype(np.float64) + rng.normal(0.0, read_noise_e, inten.shape)
        dn = np.clip(np.round(inten / full_well_e * (2**bits - 1)), 0, 2**bits - 1)
    else:
        dn = inten / full_well_e * (2**bits - 1)
    i0, i45, i90, i135 = dn.T
    s0 = 0.5 * (i0 + i45 + i90 + i135)
    s1, s2 = i0 - i90, i45 - i135
    dop_m = np.sqrt(s1 * s1 + s2 * s2) / s0
    psi_m = 0.5 * np.arctan2(s2, s1)
    aop = math.pi / 2 - psi_m
    aop = aop - np.pi * np.ceil((aop - math.pi / 2) / np.pi)
    return SkyObservation(x, y, np.rad2deg(aop), np.clip(dop_m, 0.0, 1.0), s0, psi)


def render_mosaic(s_c: np.ndarray, cam: CameraGeometry, rng: np.random.Generator | None = None, p_max: float = 0.8,
                  extinction_ratio: float = 300.0, full_well_e: float = 10000.0, read_noise_e: float = 5.0,
                  bits: int = 12, signal_fraction: float = 0.8) -> np.ndarray:
    """A raw IMX250MZR mosaic (ny, nx) in DN: (0,0)=90, (0,1)=45, (1,0)=135, (1,1)=0 deg (the conventions)."""
    yy, xx = np.meshgrid(np.arange(1, cam.ny + 1), np.arange(1, cam.nx + 1), indexing="ij")
    v = cam.view_rays(xx.ravel().astype(np.float64), yy.ravel().astype(np.float64))
    dop, e = rayleigh(np.asarray(s_c, dtype=np.float64), v, p_max)
    psi = np.arctan2(e[:, 1], e[:, 0]).reshape(cam.ny, cam.nx)
    dop = dop.reshape(cam.ny, cam.nx)
    theta = np.empty((cam.ny, cam.nx))
    theta[0::2, 0::2] = math.radians(90)
    theta[0::2, 1::2] = math.radians(45)
    theta[1::2, 0::2] = math.radians(135)
    theta[1::2, 1::2] = 0.0
    d = 1.0 if rng is None else (extinction_ratio - 1.0) / (extinction_ratio + 1.0)
    inten = 0.5 * signal_fraction * full_well_e * (1.0 + d * dop * np.cos(2.0 * (psi - theta)))
    if rng is not None:
        inten = rng.poisson(inten).astype(np.float64) + rng.normal(0.0, read_noise_e, inten.shape)
        return np.clip(np.round(inten / full_well_e * (2**bits - 1)), 0, 2**bits - 1)
    return inten / full_well_e * (2**bits - 1)
