"""Scenario sections owned by the firmware: variant, precision, rates, alignment, PSNS processing.

Everything here is what the firmware team configures or calibrates (the DSP's view of the system);
the sensors' true behaviour lives in the sensor sections. ``firmware.variants`` holds the parameters of
the filter variants (``firmware_model.variants.params``; docs/variants.md); only the selected
variant reads its own.
"""

from __future__ import annotations

from pathlib import PurePosixPath, PureWindowsPath
from typing import Any, Literal

from pydantic import Field, field_validator, model_validator

from .base import Model

__all__ = [
    "AlignmentSpec",
    "CalibrationResidualsSpec",
    "CalibrationSpec",
    "CameraCalibrationSpec",
    "DualVectorSpec",
    "FederatedSpec",
    "FirmwareSpec",
    "KmeansSpec",
    "ModeManagerSpec",
    "NmeaOutputSpec",
    "PsnsFirmwareSpec",
    "SunElevationSpec",
    "VariantsSpec",
]

Vec3 = tuple[float, float, float]


class AlignmentSpec(Model):
    time_s: float = Field(2.0, ge=0.1, le=600, description="coarse levelling window")
    heading_source: Literal["auto", "psns", "config"] = Field(
        "auto", description="auto: solar vector if one arrived during levelling, else heading_deg")
    heading_deg: float = Field(0.0, ge=0.0, lt=360.0, description="initial heading given to the firmware")
    heading_sigma_deg: float = Field(1.0, gt=0, le=180)
    psns_timeout_s: float = Field(10.0, ge=0, le=600, description="heading_source psns: wait this long, then fall back")
    psns_heading_sigma_deg: float = Field(0.5, gt=0, le=30)
    fine_time_s: float = Field(60.0, ge=0, le=3600, description="fine alignment (KF) before NAVIGATE is reported")
    misalignment_deg: Vec3 = Field(
        (0.0, 0.0, 0.0), description="E, N, U misalignment added to the coarse alignment (a paper's initial condition)")


class CameraCalibrationSpec(Model):
    """The polarization camera as the firmware knows it (conventions: docs/architecture.md, "Conventions").

    Every field left out is taken from the camera's nominal design (``sensors.camera``: lens, focal length,
    nominal mounting without the installation error), or from the IMX250MZR defaults without a camera section.
    The mounting uses the body-attitude convention of ``sensors.camera.mounting``:
    ``C_c^b = a2mat(pitch, roll, yaw(heading))``.
    """

    projection: Literal["pinhole", "fisheye"] | None = None
    focal_mm: float | None = Field(None, gt=0.1, le=100)
    nx: int | None = Field(None, ge=2, le=20000)
    ny: int | None = Field(None, ge=2, le=20000)
    pixel_um: float | None = Field(None, gt=0.1, le=100)
    mounting_heading_deg: float | None = Field(None, ge=-360, le=360)
    mounting_pitch_deg: float | None = Field(None, ge=-90, le=90)
    mounting_roll_deg: float | None = Field(None, ge=-180, le=180)


class PsnsFirmwareSpec(Model):
    enabled: bool | None = Field(None, description="use PSNS frames; default: on when a psns link exists")
    sigma_deg: float | None = Field(None, gt=0, le=10, description="solar-vector noise floor per axis (R of Eq. 42); "
                                    "default: the spec sheet's psns.noise_floor_deg")
    dop_min: float = Field(0.05, ge=0, lt=1)
    quality_max: float = Field(0.2, gt=0, le=1, description="largest lambda_min/lambda_mid accepted")
    min_sun_elevation_deg: float = Field(5.0, ge=-10, le=80)
    gate_chi2: float = Field(16.27, gt=0, description="innovation gate (chi-square, 3 dof)")
    camera: CameraCalibrationSpec = CameraCalibrationSpec()


class ModeManagerSpec(Model):
    # floats in Literal: pydantic validates them as an enum; the typing spec allows no floats there
    chi2_alpha: Literal[0.05, 0.01, 0.005, 0.001] = Field(  # type: ignore[valid-type]
        0.001, description="false-alarm rate of the chi-square gates")
    dop_min: float = Field(0.05, ge=0, lt=1, description="a polarization unit/point below this DOP is not valid")
    min_sun_elevation_deg: float = Field(5.0, ge=-10, le=80)


class DualVectorSpec(Model):
    tp: float = Field(0.05, gt=0, le=1, description="information-discrimination threshold T_p on |p~ x p|")
    aop_sigma_deg: float | None = Field(
        None, gt=0, le=10,
        description="unit AOP noise at dop_ref (grows as dop_ref/DOP), deg; default: the spec sheet's compass section")
    dop_ref: float | None = Field(None, gt=0, le=1,
                                  description="DOP of aop_sigma_deg; default: the spec sheet's compass section")
    sigma_floor_deg: float = Field(0.05, ge=0, le=10)
    min_scattering_deg: float = Field(10.0, ge=0, le=90)
    min_pair_sine: float = Field(0.15, gt=0, le=1)


class KmeansSpec(Model):
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
    heading_sigma_deg: float = Field(0.3, gt=0, le=30,
                                     description="constant part of the magnetometer heading error (bias state), deg")
    heading_noise_deg: float = Field(0.03, gt=0, le=30,
                                     description="white part of the magnetometer heading's error, deg")
    fix_events: bool = Field(False, description="every fix as an event kmeans_fix (pitch, roll, heading, t_meas_s), "
                             "admitted or not; the event log only")


#: The federated filter's sub-filters.
SubfilterName = Literal["sins_gnss", "pol_mimu"]
DEFAULT_SUBFILTERS: tuple[SubfilterName, ...] = ("sins_gnss", "pol_mimu")


class FederatedSpec(Model):
    beta_sins_gnss: float = Field(0.5, gt=0, le=1)
    beta_pol_mimu: float = Field(0.5, gt=0, le=1)
    subfilters: list[SubfilterName] = Field(
        default_factory=lambda: list(DEFAULT_SUBFILTERS), min_length=1, description="what the master fuses")
    readmit_after: int = Field(1, ge=1, le=100, description="consecutive passing epochs before GNSS is readmitted")
    motion_accel_tau_s: float = Field(5.0, gt=0)
    motion_accel_sigma_mps2: float = Field(0.05, gt=0)
    gravity_sigma_mps2: float = Field(0.02, gt=0)
    sun_sigma: float | None = Field(
        None, gt=0, le=1, description="fixed sun-vector noise per component (Ge et al.'s simulation: 0.01); "
        "null: from the solve's quality and the spec sheet, as the base filter")
    initial_attitude_sigma_deg: Vec3 | None = Field(
        None, description="sigma (E, N, U) of the study's imposed initial misalignment (alignment.misalignment_deg), "
        "deg: its variance is added to the spec sheet's attitude P0 of both sub-filters; null: none")


class SunElevationSpec(Model):
    elevation_sigma_deg: float | None = Field(
        None, gt=0, le=10, description="fixed sigma of the measured sun elevation (Sage-Husa's R0), deg; null: from "
        "the spec sheet's compass figures and the pair's geometry")
    forgetting: float = Field(0.95, gt=0, lt=1, description="Sage-Husa forgetting factor b")
    r_min_factor: float = Field(0.01, gt=0, le=1)
    r_max_factor: float = Field(100.0, ge=1)
    min_pair_sine: float = Field(0.2, gt=0, le=1)
    attitude_coupling: bool = Field(False, description="tilt columns in H (the paper's H has none; D-5.21)")
    update_every: int = Field(1, ge=1, le=100)
    attitude_aiding: bool = Field(False,
                                  description="also the compass's solar-vector attitude update (not in the paper)")
    elevation_update: bool = Field(True, description="make the sun-elevation position update (false: the paper's "
                                                     "pure-SINS baseline, the same filter without it)")


class VariantsSpec(Model):
    mode_manager: ModeManagerSpec = ModeManagerSpec()
    dual_vector: DualVectorSpec = DualVectorSpec()
    kmeans_3d: KmeansSpec = KmeansSpec()
    federated: FederatedSpec = FederatedSpec()
    sun_elevation: SunElevationSpec = SunElevationSpec()


class CalibrationResidualsSpec(Model):
    """One sigma of what a bench calibration leaves unknown (docs/calibration.md). The calibration file the DSP
    loads is the world's truth plus one draw of these (seeded by the run's seed)."""

    boresight_deg: float = Field(0.05, ge=0, le=2, description="camera-to-body rotation, per axis")
    focal_rel: float = Field(1e-3, ge=0, le=0.02, description="relative focal-length error")
    principal_point_px: float = Field(0.5, ge=0, le=20, description="per axis")
    distortion_k1: float = Field(1e-3, ge=0, le=0.05)
    exit_pupil_rel: float = Field(0.02, ge=0, le=0.3, description="relative exit-pupil distance error")
    polarizer_deg: float = Field(0.05, ge=0, le=2, description="per micro-polarizer channel")
    compass_installation_deg: float = Field(0.13, ge=0, le=5)
    mag_hard_iron_nt: float = Field(30.0, ge=0, le=5000)
    mag_soft_iron: float = Field(0.001, ge=0, le=0.1)


class CalibrationSpec(Model):
    """How the firmware's calibration file (``calibration.json`` in the run directory) comes about.

    ``residuals``: the world's truth plus the residuals below (the default: a calibrated unit); ``perfect``: the
    truth itself (for debugging); ``nominal``: the design values, no calibration (an installation error or a lens
    defect is unknown to the DSP); ``file``: the user's own file (``file``, relative to the scenario's directory);
    ``lab``: the lens fitted in the firmware's lens family to simulated bench observations of the true camera (which
    may be outside that family), the rest as ``residuals`` (docs/calibration.md, "Lab calibration").
    """

    source: Literal["residuals", "perfect", "nominal", "file", "lab"] = "residuals"
    residuals: CalibrationResidualsSpec = CalibrationResidualsSpec()
    file: str | None = Field(None, description="calibration JSON, relative to the scenario file's directory")

    @field_validator("file")
    @classmethod
    def _confined(cls, v: str | None) -> str | None:
        if v is None:
            return v
        for p in (PurePosixPath(v), PureWindowsPath(v)):
            if p.is_absolute() or p.drive or ".." in p.parts:
                raise ValueError("the calibration file must be a relative path inside the scenario's directory")
        return v

    @model_validator(mode="after")
    def _file_given(self) -> CalibrationSpec:
        if (self.source == "file") != (self.file is not None):
            raise ValueError("source: file needs file, and file needs source: file")
        return self


class NmeaOutputSpec(Model):
    """NMEA 0183 navigation output on the host port, written by the firmware next to NAV_SOLUTION (docs/icd.md,
    "NMEA navigation output")."""

    sentences: list[Literal["GGA", "RMC", "VTG", "ZDA", "HDT", "THS", "PASHR"]] = Field(default_factory=list)
    rate_hz: float = Field(1.0, gt=0, le=200)
    attitude_rate_hz: float = Field(1.0, gt=0, le=200)
    talker: str = Field("GN", pattern=r"^[A-Z]{2}$")


def _check_filter(name: str) -> str:
    """``firmware.filter`` against the filter registry (built-in variants and ``psns_hil.filters`` plugins)."""
    from ..plugins import did_you_mean, filter_names

    known = filter_names()
    if name not in known:
        raise ValueError(did_you_mean("filter", name, known, "psns_hil.filters"))
    return name


def _check_params(name: str, params: dict[str, Any], variants: VariantsSpec) -> VariantsSpec:
    """``firmware.params`` against the parameter model the filter ``name`` declares; for a built-in variant they
    override ``firmware.variants.NAME`` (same fields, same ranges). Returns the variants section to keep."""
    from dataclasses import MISSING, fields, is_dataclass

    from pydantic import TypeAdapter, ValidationError

    from ..plugins import PLUGIN_ERRORS, plugin

    if name in VariantsSpec.model_fields and name != "mode_manager":
        spec = getattr(variants, name)
        try:  # its ranges; extra keys refused
            merged = type(spec).model_validate({**spec.model_dump(), **params})
        except ValidationError as exc:
            raise ValueError(f"filter {name!r}: " + "; ".join(
                f"params.{'.'.join(str(p) for p in e['loc'])}: {e['msg']}" for e in exc.errors())) from None
        return variants.model_copy(update={name: merged})
    cls = plugin("psns_hil.filters", name)  # the plugin's filter class: it declares its parameter model
    if cls is None and ("psns_hil.filters", name) in PLUGIN_ERRORS:
        raise ValueError(f"filter {name!r}: its plugin failed to load: {PLUGIN_ERRORS['psns_hil.filters', name]}")
    model = getattr(cls, "params_model", None)
    if model is not None and not (isinstance(model, type) and is_dataclass(model)):
        raise ValueError(f"filter {name!r}: its params_model is not a dataclass ({model!r})")
    if model is None:
        if params:
            raise ValueError(f"filter {name!r} declares no parameters; firmware.params must be empty")
        return variants
    names = [f.name for f in fields(model)]
    unknown = sorted(set(params) - set(names))
    if unknown:
        import difflib

        hints = [f"{k!r} (did you mean {c[0]!r}?)" if (c := difflib.get_close_matches(k, names, n=1)) else repr(k)
                 for k in unknown]
        raise ValueError(f"filter {name!r} has no parameter {', '.join(hints)}; its parameters: {', '.join(names)}")
    missing = [f.name for f in fields(model) if f.default is MISSING and f.default_factory is MISSING
               and f.name not in params]
    if missing:
        raise ValueError(f"filter {name!r} needs firmware.params: {', '.join(missing)}")
    try:
        TypeAdapter(model).validate_python(params)
    except ValidationError as exc:
        raise ValueError(f"filter {name!r}: " + "; ".join(
            f"params.{'.'.join(str(p) for p in e['loc'])}: {e['msg']}" for e in exc.errors())) from None
    return variants


class FirmwareSpec(Model):
    filter: str = Field("base", description="the filter variant: a built-in one (base, dual_vector, kmeans_3d, "
                        "federated, sun_elevation) or one a plugin package registers (psns_hil.filters entry points, "
                        "docs/plugins.md)")
    params: dict[str, Any] = Field(
        default_factory=dict, description="parameters of the selected filter, validated against the parameter "
        "model it declares (built-in variants: the fields of firmware.variants.NAME, which they override)")
    implementation: str = Field(
        "psns_hil", description="the firmware the virtual DSP runs: psns_hil (this package's) or one a plugin "
        "registers (psns_hil.firmware entry points)")
    spec_sheet: str = Field("default", pattern=r"^[A-Za-z0-9_][A-Za-z0-9_./-]*$",
                            description="the firmware's sensor spec sheet: a bundled name (default, field) or a "
                                        "YAML file relative to the scenario's directory")
    precision: Literal["float32", "float64"] = "float32"
    nav_state_precision: Literal["float32", "float64"] = Field(
        "float64", description="strapdown quaternion/velocity accumulators (docs/decisions/firmware.md D-L.1)")
    output_rate_hz: float = Field(100.0, gt=0, le=200)
    nmea: NmeaOutputSpec = NmeaOutputSpec()
    text_rate_hz: float = Field(0.0, ge=0, le=200, description="the $PSNS text output (docs/icd.md 7: $PSNSPOS, "
                                "VEL, ATT, STA) for terminal users, groups per second (0: off); on links.host_nmea "
                                "when given (text only there: the README's miniterm recipe), else on the host port "
                                "with NAV_SOLUTION; divides output_rate_hz")
    kf_predict_every: int = Field(20, ge=1, le=200)
    coning_samples: Literal[0, 1, 2] = Field(0, description="0: two-sample with angle increments, else one")
    alignment: AlignmentSpec = AlignmentSpec()
    psns: PsnsFirmwareSpec = PsnsFirmwareSpec()
    calibration: CalibrationSpec = CalibrationSpec()
    variants: VariantsSpec = VariantsSpec()

    @field_validator("filter")
    @classmethod
    def _filter(cls, v: str) -> str:
        return _check_filter(v)

    @field_validator("implementation")
    @classmethod
    def _implementation(cls, v: str) -> str:
        from ..plugins import did_you_mean, firmware_names

        known = firmware_names()
        if v not in known:
            raise ValueError(did_you_mean("firmware implementation", v, known, "psns_hil.firmware"))
        return v

    @model_validator(mode="after")
    def _params(self) -> FirmwareSpec:
        variants = _check_params(self.filter, self.params, self.variants)
        if variants is not self.variants:
            self.variants = variants
        return self
