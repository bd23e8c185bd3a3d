"""Scenario sections owned by the sensor models: IMU, GNSS, polarization camera and compass, magnetometer.

Every sensor picks a named preset (``emulator/presets/<kind>.yaml``) and may override single
figures; ``None`` means "take the preset's value". Any sensor may read a recorded file instead of
its model (``recorded:``; formats in ``docs/sensors.md``). Units are in the field names.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import Field, field_validator, model_validator

from .base import Model
from .presets import preset_names

__all__ = [
    "SUITE_PRESETS",
    "AccelSpec",
    "BlockedUnitsSpec",
    "CameraDefectsSpec",
    "CameraSpec",
    "CompassSpec",
    "CompassUnitSpec",
    "GnssErrorSpec",
    "GnssGlitchSpec",
    "GnssOutageSpec",
    "GnssSpec",
    "GyroSpec",
    "ImuSpec",
    "ImuTemperatureSpec",
    "MagnetometerSpec",
    "MountingSpec",
    "RecordedGnssSpec",
    "RecordedImagesSpec",
    "RecordedImuSpec",
    "Sensors",
    "VibrationSpec",
    "preset_of",
]

Vec3 = tuple[float, float, float]


def _check_preset(kind: str, name: str) -> str:
    names = preset_names(kind)
    if name not in names:
        raise ValueError(f"unknown {kind} preset {name!r}; available: {', '.join(names)}")
    return name


#: a PSD breakpoint's frequency, Hz, and level, g^2/Hz (the IMU's Nyquist limit is a scenario check)
PsdFrequency = Annotated[float, Field(gt=0, le=1000)]
PsdLevel = Annotated[float, Field(gt=0, le=100)]
AxisLevel = Annotated[float, Field(ge=0, le=10)]
VreCoeff = Annotated[float, Field(ge=-1000, le=1000)]


class GyroSpec(Model):
    arw_deg_rt_h: float | None = Field(None, ge=0)
    bias_repeatability_deg_h: float | None = Field(None, ge=0)
    bias_instability_deg_h: float | None = Field(None, ge=0)
    bias_corr_time_s: float | None = Field(None, gt=0)
    rate_random_walk_deg_h_rt_h: float | None = Field(None, ge=0)
    scale_factor_ppm: float | None = Field(None, ge=0)
    scale_asymmetry_ppm: float | None = Field(None, ge=0)
    misalignment_mrad: float | None = Field(None, ge=0)
    nonlinearity_ppm_fs: float | None = Field(None, ge=0)
    bias_temp_coeff_deg_h_per_c: float | None = Field(None, ge=0)
    bias_temp_gradient_deg_h: float | None = Field(None, ge=0)
    g_sensitivity_deg_h_per_g: float | None = Field(None, ge=0)
    range_dps: float | None = Field(None, gt=0)
    turn_on_bias_deg_h: Vec3 | None = Field(
        None, description="the unit's turn-on bias per axis, deg/h (instead of a draw from bias_repeatability_deg_h)")


class AccelSpec(Model):
    bias_repeatability_mg: Vec3 | None = None
    bias_instability_mg: Vec3 | None = None
    bias_corr_time_s: float | None = Field(None, gt=0)
    noise_ug_rt_hz: float | None = Field(None, ge=0)
    bias_random_walk_mg_rt_h: float | None = Field(None, ge=0)
    scale_factor_ppm: Vec3 | None = None
    scale_error_ppm: Vec3 | None = None
    misalignment_mrad: float | None = Field(None, ge=0)
    bias_temp_coeff_mg_per_c: float | None = Field(None, ge=0)
    range_g: Vec3 | None = None
    vre_ug_per_g2: tuple[VreCoeff, VreCoeff, VreCoeff] | None = None
    turn_on_bias_mg: Vec3 | None = Field(
        None, description="the unit's turn-on bias per axis, mg (instead of a draw from bias_repeatability_mg)")


class ImuTemperatureSpec(Model):
    start_c: float = Field(25.0, ge=-60, le=125)
    rate_c_per_min: float = Field(0.0, ge=-20, le=20)
    cal_c: float = Field(25.0, ge=-60, le=125)
    warmup_c: float | None = Field(None, ge=-40, le=60)
    warmup_tau_s: float | None = Field(None, ge=1, le=36000)


class VibrationSpec(Model):
    """Vibration as a PSD profile (MIL-STD-810 / DO-160 style breakpoints), drawn by the world (docs/sensors.md)."""

    enabled: bool = True
    psd: list[tuple[PsdFrequency, PsdLevel]] | None = Field(None, min_length=2)
    axes: tuple[AxisLevel, AxisLevel, AxisLevel] | None = None


class RecordedImuSpec(Model):
    """IMU samples from a CSV file (columns in docs/sensors.md), replacing truth and error model."""

    file: str
    time_offset_s: float = Field(0.0, description="scenario time = file time + offset")


class ImuSpec(Model):
    preset: str = "paper"
    format: Literal["s", "e", "j", "k", "l", "m", "n", "o", "p"] = "m"
    device: Literal["stim210", "stim300"] = "stim210"
    stim300_datagram: Literal["0x90", "0x91", "0x92", "0x93", "0x94", "0xA5", "0xA6", "0xA7", "0xF0", "0xF1", "0xF2",
                              "0xF3", "0xF4", "0xF5", "0xF6", "0xF7"] = "0x93"
    output: Literal["rate", "angle"] = "rate"
    rate_hz: float = Field(200.0, gt=0, le=2000)
    lp_filter_hz: Literal[0, 16, 33, 66, 131, 262] | None = Field(
        None, description="STIM210 low-pass filter -3 dB setting (0: none); default from the preset")
    gyro: GyroSpec = GyroSpec()
    accel: AccelSpec = AccelSpec()
    temperature: ImuTemperatureSpec = ImuTemperatureSpec()
    vibration: VibrationSpec | None = None
    recorded: RecordedImuSpec | None = None

    @field_validator("preset")
    @classmethod
    def _preset(cls, v: str) -> str:
        return _check_preset("imu", v)


class GnssErrorSpec(Model):
    pos_sigma_h_m: float | None = Field(None, ge=0)
    pos_sigma_v_m: float | None = Field(None, ge=0)
    pos_white_fraction: float | None = Field(None, ge=0, le=1)
    pos_corr_time_s: float | None = Field(None, gt=0, le=86400)
    multipath_sigma_h_m: float | None = Field(None, ge=0, le=100)
    multipath_sigma_v_m: float | None = Field(None, ge=0, le=100)
    multipath_corr_time_s: float | None = Field(None, gt=0, le=3600)
    vel_sigma_h_mps: float | None = Field(None, ge=0)
    vel_sigma_v_mps: float | None = Field(None, ge=0)
    pps_jitter_ns: float | None = Field(None, ge=0)


class GnssOutageSpec(Model):
    start_s: float = Field(ge=0)
    duration_s: float = Field(gt=0)


class GnssGlitchSpec(Model):
    start_s: float = Field(ge=0)
    duration_s: float = Field(gt=0)
    offset_enu_m: Vec3


class RecordedGnssSpec(Model):
    """Fixes from a file: ``csv`` (columns in docs/sensors.md) or an ``nmea`` log replayed sentence by sentence."""

    file: str
    format: Literal["csv", "nmea"] = "csv"
    time_offset_s: float = 0.0


#: NMEA sentences the modelled receiver can emit.
NmeaSentenceName = Literal["GGA", "RMC", "VTG", "GSA", "GSV", "GST", "ZDA"]
DEFAULT_NMEA_SENTENCES: tuple[NmeaSentenceName, ...] = ("GGA", "RMC")
#: UBX messages the modelled receiver can emit (NAV-PVT, or the set of u-blox 5/6/7).
UbxMessageName = Literal["NAV-PVT", "NAV-STATUS", "NAV-SOL", "NAV-POSLLH", "NAV-VELNED", "NAV-TIMEUTC", "NAV-TIMEGPS"]


class GnssSpec(Model):
    enabled: bool = True
    preset: str = "paper"
    rate_hz: float = Field(1.0, gt=0, le=20)
    latency_s: float | None = Field(None, ge=0, lt=1, description="epoch to first byte, s; default from the preset")
    sentences: list[NmeaSentenceName] = Field(
        default_factory=lambda: list(DEFAULT_NMEA_SENTENCES), description="NMEA sentences per epoch, in this order")
    ubx: list[UbxMessageName] = Field(
        default_factory=list, description="UBX messages per epoch, after the NMEA sentences (NAV-PVT, or the set of "
        "u-blox 5/6/7: NAV-SOL, NAV-POSLLH, NAV-VELNED, NAV-TIMEUTC, NAV-TIMEGPS, NAV-STATUS)")
    talker: Literal["GP", "GN", "GL", "GA", "GB", "BD"] = "GP"
    nmea_version: Literal["2.3", "4.10"] = "2.3"
    geoid_sep_m: float | None = None
    geoid_sep_field: Literal["reported", "empty"] = "reported"
    fix_quality: Literal[1, 2, 4, 5] | None = None
    reacquisition_s: float | None = Field(None, ge=0, lt=1.0, description="paper: < 1 s")
    num_sats: int = Field(12, ge=4, le=99)
    hdop: float = Field(0.8, gt=0, le=99)
    environment: Literal["open_sky", "suburban", "urban_canyon"] | None = Field(
        None, description="the antenna's surroundings (emulator/devices/gnss_environment.py, docs/sensors.md "
                          "\"The envelope\"): multipath, NLOS outliers, fewer satellites, worse DOP; None: the "
                          "preset's receiver as it is")
    errors: GnssErrorSpec = GnssErrorSpec()
    outages: list[GnssOutageSpec] = Field(default_factory=list)
    glitches: list[GnssGlitchSpec] = Field(default_factory=list)
    recorded: RecordedGnssSpec | None = None

    @field_validator("preset")
    @classmethod
    def _preset(cls, v: str) -> str:
        return _check_preset("gnss", v)


class MountingSpec(Model):
    """Sensor-to-body rotation: a nominal mount (Euler angles, body-attitude convention) and an installation error."""

    heading_deg: float = Field(0.0, ge=-360, le=360)
    pitch_deg: float = Field(0.0, ge=-90, le=90)
    roll_deg: float = Field(0.0, ge=-180, le=180)
    installation_error_deg: Vec3 = Field((0.0, 0.0, 0.0),
                                         description="small rotation vector about the sensor axes, deg")


class RecordedImagesSpec(Model):
    """Raw mosaics from files: an index CSV ``time_s,file`` or a glob with a frame rate."""

    index: str | None = Field(None, description="CSV with columns time_s,file (paths relative to the index)")
    files: str | None = Field(None, description="glob of 16-bit PNG/TIFF mosaics or NPZ (I0, I45, I90, I135)")
    rate_hz: float | None = Field(None, gt=0)
    start_s: float = 0.0

    @model_validator(mode="after")
    def _one(self) -> RecordedImagesSpec:
        if (self.index is None) == (self.files is None):
            raise ValueError("recorded images need exactly one of index, files")
        if self.files is not None and self.rate_hz is None:
            raise ValueError("recorded files need rate_hz")
        return self


class CameraDefectsSpec(Model):
    """The sensor's fixed pattern, field by field over the preset's ``defects`` (docs/sensors.md, "Polarization
    camera"): the world's truth only; the firmware knows it through its calibration file."""

    orientation_sigma_deg: float | None = Field(None, ge=0, le=5)
    orientation_bias_deg: tuple[float, float, float, float] | None = None
    extinction_spread: float | None = Field(None, ge=0, le=1)
    prnu: float | None = Field(None, ge=0, le=0.2)
    dark_e: float | None = Field(None, ge=0, le=100000)
    crosstalk: float | None = Field(None, ge=0, le=0.1)
    vignetting: bool | None = None

    @field_validator("orientation_bias_deg")
    @classmethod
    def _bias(cls, v: tuple[float, float, float, float] | None) -> tuple[float, float, float, float] | None:
        if v is not None and any(not -5.0 <= b <= 5.0 for b in v):
            raise ValueError(f"each channel's orientation bias must be in [-5, 5] deg, got {list(v)}")
        return v


class CameraOpticsSpec(Model):
    """The lens over the preset's (docs/sensors.md "Polarization camera" and "The envelope"); None: the preset's.
    ``distortion_k3`` and the tangential (decentering) ``tangential_p1``/``p2`` (Brown-Conrady on the normalised
    image coordinates, pinhole lenses only) and the lens's radial diattenuation are beyond the firmware's lens family:
    a calibration in that family cannot represent them."""

    principal_point_offset_px: tuple[float, float] | None = Field(
        None, description="principal point from the sensor centre, px (x, y); default from the preset")
    distortion_k1: float | None = Field(None, ge=-0.5, le=0.5, description="radial k1 (on tan theta for pinhole)")
    distortion_k2: float | None = Field(None, ge=-0.5, le=0.5, description="radial k2 (on tan theta for pinhole)")
    distortion_k3: float = Field(0.0, ge=-0.2, le=0.2, description="pinhole: radial k3 (outside the firmware's family)")
    tangential_p1: float = Field(0.0, ge=-0.01, le=0.01, description="pinhole: decentering p1 (Brown-Conrady)")
    tangential_p2: float = Field(0.0, ge=-0.01, le=0.01, description="pinhole: decentering p2 (Brown-Conrady)")
    exit_pupil_mm: float | None = Field(None, gt=0, le=1000, description="exit pupil to image plane, mm")
    radial_diattenuation_edge: float = Field(
        0.0, ge=0.0, le=0.05, description="the lens's diattenuation (Tp - Ts)/(Tp + Ts) at the sensor's corner, "
                                          "growing as sin^2 of the field angle; p (radial) transmitted better")


class CameraSpec(Model):
    enabled: bool = True
    preset: str = "reference"
    fidelity: Literal["full", "binned"] = "binned"
    lens: Literal["pinhole", "fisheye"] | None = None
    focal_length_mm: float | None = Field(None, gt=0, le=100)
    fisheye_max_theta_deg: float = Field(90.0, gt=0, le=120)
    mounting: MountingSpec = MountingSpec()
    grid: tuple[int, int] = (15, 15)
    bin_superpixels: int = Field(8, ge=1, le=128)
    rate_hz: float = Field(5.0, gt=0, le=100)
    exposure_us: int = Field(1000, gt=0, le=1_000_000)
    processing_ms: float = Field(20.0, ge=0, le=1000)
    full_well_e: float | None = Field(None, gt=0)
    read_noise_e: float | None = Field(None, ge=0)
    adc_bits: int | None = Field(None, ge=8, le=16)
    extinction_ratio: float | None = Field(None, gt=1)
    signal_e: float | None = Field(None, gt=0)
    auto_exposure_target: float | None = Field(None, gt=0, lt=1)
    auto_exposure_percentile: float = Field(98.0, gt=0, le=100)
    noise: bool | None = None
    sun_glare_deg: float = Field(3.0, ge=0, le=30)
    min_sun_elevation_deg: float = Field(0.0, ge=-18, le=30)
    dop_threshold: float = Field(0.05, ge=0, le=1)
    min_points: int = Field(10, ge=1)
    recorded: RecordedImagesSpec | None = None
    defects: CameraDefectsSpec = CameraDefectsSpec()
    optics: CameraOpticsSpec = CameraOpticsSpec()

    @field_validator("preset")
    @classmethod
    def _preset(cls, v: str) -> str:
        return _check_preset("camera", v)


class CompassUnitSpec(Model):
    """View direction of one single-direction unit (mounting convention: docs/architecture.md, "Conventions")."""

    zenith_deg: float = Field(ge=0, le=90, description="angle from body +z")
    azimuth_deg: float = Field(ge=-360, le=360, description="from body +y (forward) towards +x (right)")


class BlockedUnitsSpec(Model):
    """Units that see unpolarized light (DOP ~ 0, scrambled AOP) for a while: obstruction, thick cloud."""

    units: list[int] = Field(min_length=1, description="unit indices (0-based, in the order of units)")
    start_s: float = Field(ge=0)
    duration_s: float = Field(gt=0)


class CompassSpec(Model):
    enabled: bool = True
    preset: str = "paper"
    rate_hz: float = Field(5.0, gt=0, le=100)
    integration_ms: float = Field(10.0, gt=0, le=1000)
    processing_ms: float = Field(5.0, ge=0, le=1000)
    aop_sigma_deg: float | None = Field(None, ge=0)
    dop_ref: float | None = Field(None, gt=0, le=1)
    extinction_ratio: float | None = Field(None, gt=1)
    fov_half_deg: float | None = Field(None, ge=0, le=45)
    installation_error_sigma_deg: float | None = Field(
        None, ge=0, le=10, description="random per-unit mounting error, deg (1 sigma); default from the preset")
    dop_noise_model: Literal["inverse", "zhang"] | None = Field(
        None, description="AOP error vs DOP: inverse (sigma ~ 1/DOP) or zhang (Zhang et al. 2021 measured bins)")
    aop_offset_deg: list[float] | None = Field(
        None, min_length=1, max_length=16,
        description="constant E-vector (AOP) error per unit left by the calibration, deg (a turn of the installed unit "
                    "about its own view ray; e.g. Zhang et al. 2021 Table 2); one value per unit")
    min_sun_elevation_deg: float = Field(0.0, ge=-18, le=30)
    units: list[CompassUnitSpec] | None = Field(
        None, min_length=1, max_length=16, description="unit view directions; default: the 9-unit compass")
    blocked: list[BlockedUnitsSpec] = Field(default_factory=list, description="blocked-unit windows")

    @field_validator("preset")
    @classmethod
    def _preset(cls, v: str) -> str:
        return _check_preset("compass", v)

    @model_validator(mode="after")
    def _blocked_units_exist(self) -> CompassSpec:
        n = len(self.units) if self.units is not None else 9
        for i, b in enumerate(self.blocked):
            bad = [u for u in b.units if not 0 <= u < n]
            if bad:
                raise ValueError(f"blocked[{i}]: the compass has units 0..{n - 1}, not {bad}")
        if self.aop_offset_deg is not None:
            if len(self.aop_offset_deg) != n:
                raise ValueError(f"aop_offset_deg: the compass has {n} units, got {len(self.aop_offset_deg)} values")
            if any(not -10.0 <= v <= 10.0 for v in self.aop_offset_deg):
                raise ValueError("aop_offset_deg: each value must lie within +-10 deg")
        return self


class MagnetometerSpec(Model):
    enabled: bool = True
    preset: str = "default"
    declination_deg: float = Field(-7.133, ge=-180, le=180, description="east positive (default: IGRF-13 Beijing)")
    inclination_deg: float = Field(59.215, ge=-90, le=90, description="down positive")
    intensity_nt: float = Field(54769.0, gt=0, le=100000)
    noise_nt: float | None = Field(None, ge=0)
    hard_iron_nt: Vec3 | None = None
    soft_iron_scale: Vec3 | None = None
    soft_iron_cross: Vec3 | None = Field(None, description="off-diagonal xy, xz, yz")

    @field_validator("preset")
    @classmethod
    def _preset(cls, v: str) -> str:
        return _check_preset("magnetometer", v)


#: What a suite-level ``sensors.preset`` means for each sensor (a sensor's own ``preset`` wins when given):
#: ``ideal`` for debugging (no errors), ``paper`` the source papers' figures, ``field`` realistic figures from
#: datasheets and the literature (docs/sensors.md, "Presets").
SUITE_PRESETS: dict[str, dict[str, str]] = {
    "ideal": {"imu": "perfect", "gnss": "perfect", "camera": "ideal", "compass": "ideal", "magnetometer": "perfect"},
    "paper": {"imu": "paper", "gnss": "paper", "camera": "reference", "compass": "paper", "magnetometer": "default"},
    "field": {"imu": "field", "gnss": "field", "camera": "reference", "compass": "field", "magnetometer": "field"},
}


class Sensors(Model):
    preset: Literal["ideal", "paper", "field"] = Field(
        "paper", description="suite preset: ideal (no errors), paper (the papers' figures) or field (realistic, "
                             "datasheets and literature; docs/sensors.md); a sensor's own preset wins")
    imu: ImuSpec = ImuSpec()
    gnss: GnssSpec = GnssSpec()
    camera: CameraSpec | None = None
    compass: CompassSpec | None = None
    magnetometer: MagnetometerSpec | None = None


def preset_of(sensors: Sensors, kind: str, spec: Model | None) -> str:
    """The preset a sensor uses: its own ``preset`` if the scenario gave one, else the suite preset's choice."""
    if spec is not None and "preset" in spec.model_fields_set:
        return str(spec.preset)  # type: ignore[attr-defined]
    return SUITE_PRESETS[sensors.preset][kind]
