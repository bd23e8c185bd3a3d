"""The scenario section ``firmware.variants``: GENERATED from firmware_model/variants/params.py by
``python -m emulator.dsp.variant_params``; do not edit (the declarations, their defaults and bounds are
there; tests/emulator/dsp/test_variant_params.py fails when this file is stale). Only the selected
variant reads its own section (docs/variants.md)."""
# ruff: noqa: E501

from __future__ import annotations

from typing import Literal

from pydantic import Field

from .base import Model

__all__ = ["DualVectorSpec", "FederatedSpec", "KmeansSpec", "ModeManagerSpec", "SunElevationSpec", "VariantsSpec"]


class ModeManagerSpec(Model):
    # firmware_model.variants.params.ModeManagerParams
    chi2_alpha: Literal[0.05, 0.01, 0.005, 0.001] = Field(0.001, description="false-alarm rate of the chi-square gates")  # type: ignore[valid-type]
    dop_min: float = Field(0.05, ge=0, lt=1, description="a polarization unit/point below this DOP is not valid")
    min_sun_elevation_deg: float = Field(5.0, ge=-10, le=80, description="below this sun elevation the mode manager uses no polarization, deg")


class DualVectorSpec(Model):
    # firmware_model.variants.params.DualVectorParams
    tp: float = Field(0.05, gt=0, le=1, description="information-discrimination threshold T_p on |p~ x p|")
    aop_sigma_deg: float | None = Field(None, gt=0, le=10, description="unit AOP noise at dop_ref (grows as dop_ref/DOP), deg; default: the spec sheet's compass section")
    dop_ref: float | None = Field(None, gt=0, le=1, description="DOP of aop_sigma_deg; default: the spec sheet's compass section")
    sigma_floor_deg: float = Field(0.05, ge=0, le=10)
    min_scattering_deg: float = Field(10.0, ge=0, le=90)
    min_pair_sine: float = Field(0.15, gt=0, le=1)


class KmeansSpec(Model):
    # firmware_model.variants.params.KmeansParams
    clusters: int = Field(3, ge=2, le=8)
    iterations: int = Field(10, ge=1, le=100)
    min_cluster_points: int = Field(3, ge=1)
    max_centre_ratio: float = Field(0.6, gt=0, le=1)
    fov_margin_deg: float = Field(2.0, ge=0, le=45)
    max_disagreement_deg: float = Field(30.0, gt=0, le=180)
    max_gap_deg: float = Field(15.0, gt=0, le=90)
    max_quality: float = Field(0.2, gt=0, le=1)
    mag_declination_deg: float = Field(-7.133, ge=-180, le=180, description="east positive")
    mag_inclination_deg: float = Field(59.215, ge=-90, le=90, description="down positive")
    mag_half_window_s: float = Field(0.025, gt=0, le=1)
    attitude_iterations: int = Field(3, ge=1, le=20)
    heading_sigma_deg: float = Field(0.3, gt=0, le=30, description="constant part of the magnetometer heading error (bias state), deg")
    heading_noise_deg: float = Field(0.03, gt=0, le=30, description="white part of the magnetometer heading's error, deg")
    fix_events: bool = Field(False, description="every fix as an event kmeans_fix (pitch, roll, heading, t_meas_s), admitted or not; the event log only")


class FederatedSpec(Model):
    # firmware_model.variants.params.FederatedParams
    beta_sins_gnss: float = Field(0.5, gt=0, le=1)
    beta_pol_mimu: float = Field(0.5, gt=0, le=1)
    subfilters: list[Literal["sins_gnss", "pol_mimu"]] = Field(default_factory=lambda: ["sins_gnss", "pol_mimu"], min_length=1, description="what the master fuses")  # type: ignore[arg-type]
    readmit_after: int = Field(1, ge=1, le=100, description="consecutive passing epochs before GNSS is readmitted")
    motion_accel_tau_s: float = Field(5.0, gt=0)
    motion_accel_sigma_mps2: float = Field(0.05, gt=0)
    gravity_sigma_mps2: float = Field(0.02, gt=0)
    sun_sigma: float | None = Field(None, gt=0, le=1, description="fixed sun-vector noise per component (Ge et al.'s simulation: 0.01); null: from the solve's quality and the spec sheet, as the base filter")
    initial_attitude_sigma_deg: tuple[float, float, float] | None = Field(None, description="sigma (E, N, U) of the study's imposed initial misalignment (alignment.misalignment_deg), deg: its variance is added to the spec sheet's attitude P0 of both sub-filters; null: none")


class SunElevationSpec(Model):
    # firmware_model.variants.params.SunElevationParams
    elevation_sigma_deg: float | None = Field(None, gt=0, le=10, description="fixed sigma of the measured sun elevation (Sage-Husa's R0), deg; null: from the spec sheet's compass figures and the pair's geometry")
    forgetting: float = Field(0.95, gt=0, lt=1, description="Sage-Husa forgetting factor b")
    r_min_factor: float = Field(0.01, gt=0, le=1)
    r_max_factor: float = Field(100.0, ge=1)
    min_pair_sine: float = Field(0.2, gt=0, le=1)
    attitude_coupling: bool = Field(False, description="tilt columns in H (the paper's H has none; D-5.21)")
    update_every: int = Field(1, ge=1, le=100)
    attitude_aiding: bool = Field(False, description="also the compass's solar-vector attitude update (not in the paper)")
    elevation_update: bool = Field(True, description="make the sun-elevation position update (false: the paper's pure-SINS baseline, the same filter without it)")


class VariantsSpec(Model):
    mode_manager: ModeManagerSpec = ModeManagerSpec()
    dual_vector: DualVectorSpec = DualVectorSpec()
    kmeans_3d: KmeansSpec = KmeansSpec()
    federated: FederatedSpec = FederatedSpec()
    sun_elevation: SunElevationSpec = SunElevationSpec()
