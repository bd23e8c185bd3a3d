"""Build/run-time parameters of the filter variants (units in the names, degrees where a user types them).

One dataclass per variant plus the mode manager's; :class:`VariantParams` holds them all and travels in
:attr:`firmware_model.FirmwareConfig.variants`. Each field is declared once, here, with its default and the bounds a
scenario may set it within (:func:`param`, read back by :func:`bounds_of`); the scenario section
``firmware.variants`` is generated from these declarations (``emulator/scenario/variants_schema.py``, written by
``python -m emulator.dsp.variant_params``, checked by ``tests/emulator/dsp/test_variant_params.py``). Where a paper
gives a figure it is the default, and ``docs/variants.md`` says where each default comes from.
"""

from __future__ import annotations

from dataclasses import Field as _Field
from dataclasses import dataclass, field
from typing import Any, Literal, TypeVar

__all__ = [
    "BOUNDS_KEY",
    "Bounds",
    "DualVectorParams",
    "FederatedParams",
    "KmeansParams",
    "ModeManagerParams",
    "SubfilterName",
    "SunElevationParams",
    "VariantParams",
    "bounds_of",
    "param",
]

_T = TypeVar("_T")

#: key of a field's :class:`Bounds` in its ``dataclasses.Field.metadata``
BOUNDS_KEY = "psns_hil.bounds"

#: the federated filter's sub-filters
SubfilterName = Literal["sins_gnss", "pol_mimu"]


@dataclass(frozen=True)
class Bounds:
    """What a scenario may set a parameter to: open/closed limits (``gt``/``ge``, ``lt``/``le``), the allowed values
    (``choices``), the fewest items of a sequence (``min_items``), and a one-line description for the scenario's
    JSON Schema. A ``None`` parameter value is always allowed where the field's type admits ``None``."""

    ge: float | None = None
    gt: float | None = None
    le: float | None = None
    lt: float | None = None
    choices: tuple[float, ...] | None = None
    min_items: int | None = None
    description: str | None = None


def param(default: _T, *, ge: float | None = None, gt: float | None = None, le: float | None = None,
          lt: float | None = None, choices: tuple[float, ...] | None = None, min_items: int | None = None,
          description: str | None = None) -> _T:
    """A parameter field: its default and its :class:`Bounds` (``dataclasses.field`` with the bounds in its
    metadata)."""
    b = Bounds(ge=ge, gt=gt, le=le, lt=lt, choices=choices, min_items=min_items, description=description)
    return field(default=default, metadata={BOUNDS_KEY: b})


def bounds_of(f: _Field[Any]) -> Bounds:
    """The :class:`Bounds` declared for a field by :func:`param` (none: no bounds)."""
    b = f.metadata.get(BOUNDS_KEY)
    return b if isinstance(b, Bounds) else Bounds()


@dataclass
class ModeManagerParams:
    """Measurement admission shared by every variant (validity and chi-square gating)."""

    #: false-alarm probability of the chi-square gates (docs/reference/algorithms.md 5.2 table: 0.05, 0.01, 0.005,
    #: 0.001)
    chi2_alpha: float = param(0.001, choices=(0.05, 0.01, 0.005, 0.001),
                              description="false-alarm rate of the chi-square gates")
    #: a polarization sensor / observation point below this DOP is not valid (AOP unreliable)
    dop_min: float = param(0.05, ge=0, lt=1, description="a polarization unit/point below this DOP is not valid")
    #: no polarization update with the sun below this elevation (twilight, night)
    min_sun_elevation_deg: float = param(
        5.0, ge=-10, le=80, description="below this sun elevation the mode manager uses no polarization, deg")


@dataclass
class DualVectorParams:
    """Dual-vector switching (patent CN 2021 Guo et al.)."""

    #: information-discrimination threshold ``T_p`` on ``lambda_i = |p~_i x p_i|`` (sine of the angle
    #: between measured and predicted polarization vectors); q_i = 1 when lambda_i < T_p
    tp: float = param(0.05, gt=0, le=1, description="information-discrimination threshold T_p on |p~ x p|")
    #: AOP noise of a unit (1 sigma, deg) at ``dop_ref``; grows as dop_ref / DOP (the compass's own error model).
    #: None (the default): the spec sheet's compass figures (``compass_aop_sigma_deg`` at ``compass_aop_dop_ref``)
    aop_sigma_deg: float | None = param(
        None, gt=0, le=10,
        description="unit AOP noise at dop_ref (grows as dop_ref/DOP), deg; default: the spec sheet's compass section")
    dop_ref: float | None = param(None, gt=0, le=1,
                                  description="DOP of aop_sigma_deg; default: the spec sheet's compass section")
    #: floor of the measurement sigma (model errors of the Rayleigh sky)
    sigma_floor_deg: float = param(0.05, ge=0, le=10)
    #: a unit whose predicted E-vector is ill-defined (sun within this angle of its view ray) is not used
    min_scattering_deg: float = param(10.0, ge=0, le=90)
    #: smallest ``|p_i x p_j|`` of the pair that forms the sun vector (sun-error-vector mode)
    min_pair_sine: float = param(0.15, gt=0, le=1)


@dataclass
class KmeansParams:
    """K-means sun finding + 3-D attitude (Yang et al. 2020)."""

    clusters: int = param(3, ge=2, le=8)
    iterations: int = param(10, ge=1, le=100)
    #: the lowest-DOP cluster must hold at least this many points
    min_cluster_points: int = param(3, ge=1)
    #: its centre must be below this fraction of the highest cluster centre (a real low-DOP blob)
    max_centre_ratio: float = param(0.6, gt=0, le=1)
    #: refuse when the sun lies closer than this to the edge of the observed field of view
    fov_margin_deg: float = param(2.0, ge=0, le=45)
    #: refuse when the refined sun vector and the K-means direction disagree by more than this
    max_disagreement_deg: float = param(30.0, gt=0, le=180)
    #: refuse when no low-DOP cluster member lies within this angle of the refined Sun
    max_gap_deg: float = param(15.0, gt=0, le=90)
    #: eigen-solution quality lambda_min / lambda_mid must be below this
    max_quality: float = param(0.2, gt=0, le=1)
    #: magnetic declination (east positive) the firmware assumes for the heading, deg
    mag_declination_deg: float = param(-7.133, ge=-180, le=180, description="east positive")
    #: magnetic inclination (down positive) for the TRIAD start of the heading/tilt solve, deg
    mag_inclination_deg: float = param(59.215, ge=-90, le=90, description="down positive")
    #: MAG frames within this time of the camera's mid-exposure are averaged for the heading, s
    mag_half_window_s: float = param(0.025, gt=0, le=1)
    #: Newton steps of the self-consistent heading/tilt solve (heading needs the tilt, the tilt the heading)
    attitude_iterations: int = param(3, ge=1, le=20)
    #: the magnetometer heading's error (1 sigma, deg): its constant part (calibration residual of the hard and soft
    #: iron, declination model), a bias state of the filter, and its white part (15 nT per axis over the 29.5 uT
    #: horizontal field, 0.03 deg). The tilt's noise comes from the solve's own quality (D-5.23).
    heading_sigma_deg: float = param(
        0.3, gt=0, le=30, description="constant part of the magnetometer heading error (bias state), deg")
    heading_noise_deg: float = param(0.03, gt=0, le=30,
                                     description="white part of the magnetometer heading's error, deg")
    #: every fix as an event ``kmeans_fix`` (its pitch, roll and heading, ``t_meas_s``), whether the gate admits it
    #: or not: the single fixes of the paper's field table (benchmarks/paper_reproductions.py yang). Off by default:
    #: the other events are logged on a change only, and this one changes nothing but the event log
    fix_events: bool = param(False, description="every fix as an event kmeans_fix (pitch, roll, heading, t_meas_s), "
                             "admitted or not; the event log only")


@dataclass
class FederatedParams:
    """Federated SINS/GNSS + MIMU/polarization filter, no-reset (Ge et al.; Carlson 1990)."""

    beta_sins_gnss: float = param(0.5, gt=0, le=1)
    beta_pol_mimu: float = param(0.5, gt=0, le=1)
    #: which sub-filters the master fuses: "sins_gnss", "pol_mimu" (the paper's three-way = both)
    subfilters: tuple[SubfilterName, ...] = param(("sins_gnss", "pol_mimu"), min_items=1,
                                                  description="what the master fuses")
    #: GNSS readmitted after this many consecutive epochs that pass the chi-square test
    readmit_after: int = param(1, ge=1, le=100, description="consecutive passing epochs before GNSS is readmitted")
    #: correlation time of the first-order motion-acceleration model (c_a = exp(-T/tau)), s
    motion_accel_tau_s: float = param(5.0, gt=0)
    #: steady-state sigma of the motion acceleration (accelerometer "interference"), m/s^2
    motion_accel_sigma_mps2: float = param(0.05, gt=0)
    #: accelerometer gravity measurement noise (1 sigma over one KF interval), m/s^2
    gravity_sigma_mps2: float = param(0.02, gt=0)
    #: sun-vector noise per component of the MIMU/polarization sub-filter, fixed (Ge et al.'s simulation: 0.01);
    #: None: the solve's own quality and the spec sheet's floor, as the base filter (filters.solar.solar_noise_variance,
    #: docs/decisions/filter-consistency.md D-5.18)
    sun_sigma: float | None = param(
        None, gt=0, le=1, description="fixed sun-vector noise per component (Ge et al.'s simulation: 0.01); "
        "null: from the solve's quality and the spec sheet, as the base filter")
    #: sigma (E, N, U), deg, of an initial misalignment a study imposes after the coarse alignment
    #: (``alignment.misalignment_deg``, D-6.8); its variance is added to the base filter's attitude P0 (levelling
    #: from the accelerometer bias, with its correlation; heading from the alignment source), D-5.29. None: none.
    initial_attitude_sigma_deg: tuple[float, float, float] | None = param(
        None, description="sigma (E, N, U) of the study's imposed initial misalignment (alignment.misalignment_deg), "
        "deg: its variance is added to the spec sheet's attitude P0 of both sub-filters; null: none")


@dataclass
class SunElevationParams:
    """Sun-elevation positioning with the 9-unit compass and a Sage-Husa adaptive R (Zhang et al. 2021)."""

    #: sigma of the sun elevation from the two E-vectors (Sage-Husa's R0), deg, fixed; None: from the spec sheet's
    #: compass figures and the pair's geometry, per measurement (sun_elevation.elevation_noise_variance, D-5.19)
    elevation_sigma_deg: float | None = param(
        None, gt=0, le=10, description="fixed sigma of the measured sun elevation (Sage-Husa's R0), deg; null: from "
        "the spec sheet's compass figures and the pair's geometry")
    #: Sage-Husa forgetting factor b (docs/reference/algorithms.md 5.1: 0.95-0.99); d_k = (1-b)/(1-b^(k+1))
    forgetting: float = param(0.95, gt=0, lt=1, description="Sage-Husa forgetting factor b")
    #: adaptive R clamped to [r_min_factor, r_max_factor] x R0 (PSINS kfupdate)
    r_min_factor: float = param(0.01, gt=0, le=1)
    r_max_factor: float = param(100.0, ge=1)
    #: smallest ``|E_i x E_j|`` accepted for the two-E-vector sun vector
    min_pair_sine: float = param(0.2, gt=0, le=1)
    #: the tilt columns of H (phi_E, phi_N): H_n is computed with the INS attitude, so its tilt error is in z and
    #: the measurement observes the psi-angle, not position alone. False (default): the paper's H, which takes the
    #: INS tilt for position along the Sun's azimuth; True holds that direction within its sigma on
    #: sun_elevation_gnss_free but doubles the like-for-like MAE (docs/decisions/filter-consistency.md D-5.21)
    attitude_coupling: bool = param(False, description="tilt columns in H (the paper's H has none; D-5.21)")
    #: use one compass frame in this many (the paper's compass outputs 1 Hz)
    update_every: int = param(1, ge=1, le=100)
    #: also the attitude update from the same frame: the eigen-solution of all units' E-vectors (base paper
    #: Eq. 14) as a solar-vector measurement; the paper's model has the elevation measurement only (False)
    attitude_aiding: bool = param(False,
                                  description="also the compass's solar-vector attitude update (not in the paper)")
    #: make the sun-elevation position update (False: the same filter and stream without it, the paper's pure-SINS
    #: baseline; the frames are still decoded and the pair chosen, nothing reaches the state)
    elevation_update: bool = param(True, description="make the sun-elevation position update (false: the paper's "
                                                     "pure-SINS baseline, the same filter without it)")


@dataclass
class VariantParams:
    """Every variant's parameters (only the selected variant reads its own)."""

    mode_manager: ModeManagerParams = field(default_factory=ModeManagerParams)
    dual_vector: DualVectorParams = field(default_factory=DualVectorParams)
    kmeans_3d: KmeansParams = field(default_factory=KmeansParams)
    federated: FederatedParams = field(default_factory=FederatedParams)
    sun_elevation: SunElevationParams = field(default_factory=SunElevationParams)
    #: parameters of filters added by entry point (``psns_hil.filters``), by filter name: an instance of the
    #: filter's own ``params_model`` (:mod:`firmware_model.registry`)
    plugins: dict[str, Any] = field(default_factory=dict)
