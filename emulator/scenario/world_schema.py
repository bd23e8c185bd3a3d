"""Scenario sections owned by the world model: origin, initial attitude, motion segments, sky.

Motion segments (a list; each item has exactly one key). Angles in degrees, rates in deg/s.
The vehicle moves along its body +y axis (forward), so pitching while moving changes the flight
path and turning changes the course (``emulator.world.trajectory``):

``static: {duration_s}``
    At rest (the speed must already be 0).
``accelerate: {duration_s, to_speed_mps | accel_mps2}``
    Forward speed changes linearly (negative ``accel_mps2`` or a lower ``to_speed_mps`` brakes).
``cruise: {duration_s}``
    Constant speed and attitude.
``turn: {rate_dps, angle_deg | duration_s}``
    Heading changes at ``|rate_dps|``; ``angle_deg`` signed (positive = clockwise, to the right),
    or ``duration_s`` with a signed ``rate_dps``.
``climb: {duration_s, vertical_speed_mps | pitch_deg, transition_s}`` / ``descend: {...}``
    Pitch to the flight-path angle that gives ``vertical_speed_mps`` (or to ``pitch_deg``) in
    ``transition_s``, hold, and pitch back in the last ``transition_s``; the segment ends at the
    pitch it started with. For ``descend`` the values are positive downwards.
``pitch: {by_deg | to_deg, rate_dps, duration_s}`` / ``roll: {...}``
    Rotate at ``rate_dps`` (magnitude) by ``by_deg`` or to ``to_deg``, then hold for the rest of
    ``duration_s``. ``to_deg`` needs ``duration_s`` (the start angle is only known at build time);
    without ``rate_dps`` the manoeuvre takes the whole ``duration_s``.
"""

from __future__ import annotations

import math
from typing import ClassVar, Literal

from pydantic import Field, model_validator

from .base import Model, OneKindModel

__all__ = [
    "AccelerateParams",
    "Attitude",
    "ClimbParams",
    "CloudSpec",
    "CruiseParams",
    "EnvelopeSpec",
    "MotionSegment",
    "OccluderSpec",
    "Origin",
    "RotateParams",
    "SkySpec",
    "StaticParams",
    "TurnParams",
]


class Origin(Model):
    lat_deg: float = Field(ge=-90.0, le=90.0, description="geodetic latitude, deg")
    lon_deg: float = Field(ge=-180.0, le=180.0, description="longitude, deg east")
    height_m: float = Field(0.0, ge=-500.0, le=50000.0, description="ellipsoidal height, m")


class Attitude(Model):
    heading_deg: float = Field(0.0, ge=0.0, lt=360.0, description="clockwise from true north, deg")
    pitch_deg: float = Field(0.0, ge=-90.0, le=90.0, description="nose up positive, deg")
    roll_deg: float = Field(0.0, ge=-180.0, le=180.0, description="right wing down positive, deg")


class StaticParams(Model):
    duration_s: float = Field(gt=0.0, description="s")

    @property
    def total_s(self) -> float:
        return self.duration_s


class AccelerateParams(Model):
    duration_s: float = Field(gt=0.0, description="s")
    to_speed_mps: float | None = Field(None, ge=0.0, le=2000.0, description="forward speed at the end, m/s")
    accel_mps2: float | None = Field(None, ge=-100.0, le=100.0, description="forward acceleration, m/s^2")

    @model_validator(mode="after")
    def _one(self) -> AccelerateParams:
        if (self.to_speed_mps is None) == (self.accel_mps2 is None):
            raise ValueError("accelerate needs exactly one of to_speed_mps, accel_mps2")
        return self

    @property
    def total_s(self) -> float:
        return self.duration_s


class CruiseParams(Model):
    duration_s: float = Field(gt=0.0, description="s")

    @property
    def total_s(self) -> float:
        return self.duration_s


class TurnParams(Model):
    rate_dps: float = Field(description="heading rate, deg/s (positive clockwise unless angle_deg gives the sign)")
    angle_deg: float | None = Field(None, description="heading change, deg (positive clockwise)")
    duration_s: float | None = Field(None, gt=0.0, description="s")

    @model_validator(mode="after")
    def _check(self) -> TurnParams:
        if (self.angle_deg is None) == (self.duration_s is None):
            raise ValueError("turn needs exactly one of angle_deg, duration_s")
        if self.rate_dps == 0.0:
            raise ValueError("turn needs a non-zero rate_dps")
        if self.angle_deg is not None and self.angle_deg == 0.0:
            raise ValueError("turn angle_deg must not be 0")
        return self

    @property
    def total_s(self) -> float:
        if self.duration_s is not None:
            return self.duration_s
        return abs(float(self.angle_deg)) / abs(self.rate_dps)  # type: ignore[arg-type]

    @property
    def heading_rate_dps(self) -> float:
        """Signed heading rate (positive clockwise)."""
        if self.angle_deg is not None:
            return math.copysign(abs(self.rate_dps), self.angle_deg)
        return self.rate_dps


class ClimbParams(Model):
    duration_s: float = Field(gt=0.0, description="s, transitions included")
    vertical_speed_mps: float | None = Field(None, gt=0.0, description="m/s (up for climb, down for descend)")
    pitch_deg: float | None = Field(None, gt=0.0, lt=89.0, description="pitch during the hold, deg")
    transition_s: float = Field(2.0, gt=0.0, description="pitch-in and pitch-out time, s each")

    @model_validator(mode="after")
    def _check(self) -> ClimbParams:
        if (self.vertical_speed_mps is None) == (self.pitch_deg is None):
            raise ValueError("climb/descend needs exactly one of vertical_speed_mps, pitch_deg")
        if 2.0 * self.transition_s > self.duration_s + 1e-9:
            raise ValueError("climb/descend: 2 x transition_s exceeds duration_s")
        return self

    @property
    def total_s(self) -> float:
        return self.duration_s


class RotateParams(Model):
    by_deg: float | None = Field(None, description="change, deg")
    to_deg: float | None = Field(None, description="final angle, deg")
    rate_dps: float | None = Field(None, gt=0.0, description="rotation rate magnitude, deg/s")
    duration_s: float | None = Field(None, gt=0.0, description="s (manoeuvre + hold)")

    @model_validator(mode="after")
    def _check(self) -> RotateParams:
        if (self.by_deg is None) == (self.to_deg is None):
            raise ValueError("pitch/roll needs exactly one of by_deg, to_deg")
        if self.to_deg is not None and self.duration_s is None:
            raise ValueError("pitch/roll with to_deg needs duration_s")
        if self.by_deg is not None and self.duration_s is None and self.rate_dps is None:
            raise ValueError("pitch/roll needs rate_dps or duration_s")
        if (self.by_deg is not None and self.rate_dps is not None and self.duration_s is not None
                and abs(self.by_deg) / self.rate_dps > self.duration_s + 1e-9):
            raise ValueError("pitch/roll: by_deg / rate_dps exceeds duration_s")
        return self

    @property
    def total_s(self) -> float:
        if self.duration_s is not None:
            return self.duration_s
        return abs(float(self.by_deg)) / float(self.rate_dps)  # type: ignore[arg-type]


class MotionSegment(OneKindModel):
    """One motion segment; exactly one key (see module docstring)."""

    kind_label: ClassVar[str] = "a motion segment"

    static: StaticParams | None = None
    accelerate: AccelerateParams | None = None
    cruise: CruiseParams | None = None
    turn: TurnParams | None = None
    climb: ClimbParams | None = None
    descend: ClimbParams | None = None
    pitch: RotateParams | None = None
    roll: RotateParams | None = None

    @property
    def params(self) -> Model:
        return self.value

    @property
    def duration_s(self) -> float:
        return float(self.value.total_s)


class CloudSpec(Model):
    """A cloud: a circular sky region (in ENU azimuth/elevation) that lowers DOP and scrambles AOP."""

    az_deg: float = Field(ge=0.0, lt=360.0, description="centre azimuth, clockwise from north, deg")
    el_deg: float = Field(ge=-90.0, le=90.0, description="centre elevation, deg")
    radius_deg: float = Field(gt=0.0, le=180.0, description="angular radius, deg")
    dop_scale: float = Field(0.2, ge=0.0, le=1.0, description="DOP multiplier inside the cloud")
    aop_sigma_deg: float = Field(20.0, ge=0.0, le=180.0, description="random AOP rotation inside, deg (1 sigma)")
    intensity_scale: float = Field(1.5, gt=0.0, le=10.0, description="radiance multiplier inside the cloud")
    start_s: float = Field(0.0, ge=0.0, description="appears at, s")
    end_s: float = Field(math.inf, description="disappears at, s")
    drift_az_dps: float = Field(0.0, description="azimuth drift of the centre, deg/s")


class OccluderSpec(Model):
    """Something opaque in front of the sky (building, tree line): an azimuth sector up to an elevation."""

    az_min_deg: float = Field(ge=0.0, lt=360.0)
    az_max_deg: float = Field(ge=0.0, le=360.0)
    el_max_deg: float = Field(ge=-90.0, le=90.0)
    intensity_scale: float = Field(0.3, ge=0.0, le=10.0, description="radiance relative to the sky")


ENVELOPE_GROUPS = ("imu", "gnss", "sky", "camera", "mounting", "calibration")


class EnvelopeSpec(Model):
    """The world as a distribution (``emulator.world.envelope``; docs/sensors.md "The envelope"): each run's seed draws
    every parameter of the preset's groups from its published range, on top of the scenario. ``preset`` None: the
    scenario's world as written (the default)."""

    preset: str | None = Field(None, description="an envelope of emulator/presets/envelope.yaml, e.g. published")
    groups: list[Literal["imu", "gnss", "sky", "camera", "mounting", "calibration"]] | None = Field(
        None, description="draw only these groups (default: every group of the preset)")

    @model_validator(mode="after")
    def _known(self) -> EnvelopeSpec:
        if self.preset is not None:
            from .presets import preset_names

            names = preset_names("envelope")
            if self.preset not in names:
                raise ValueError(f"unknown envelope preset {self.preset!r}; available: {', '.join(names)}")
        return self


class SkySpec(Model):
    """Sky polarization model (``emulator.world.sky``)."""

    model: str = Field("realistic", pattern="^(realistic|rayleigh|berry|queen)$",
                       description="realistic (turbid sky, neutral points, aerosol aureole, CIE radiance; docs/"
                                   "sensors.md), rayleigh (clear single scattering), berry (neutral points) or queen "
                                   "(Berry's quartic with Pan et al. 2023's neutral-point placement, pyskylumos' "
                                   "QuEEN)")
    neutral_points: Literal["symmetric", "pan2023"] = Field(
        "symmetric", description="realistic/berry: the neutral points symmetric about the sun and the antisun "
                                 "(neutral_point_sep_deg) or placed from the solar elevation after Pan et al. 2023")
    p_max: float = Field(0.7, gt=0.0, le=1.0, description="rayleigh/berry: maximum degree of polarization")
    neutral_point_sep_deg: float | None = Field(
        None, ge=0.0, le=60.0, description="berry/realistic: Babinet-Brewster separation (2 delta), deg; default 20 "
                                           "(berry), 40 (realistic: each point ~20 deg from the sun, Coulson 1988)")
    turbidity: float = Field(3.0, ge=1.0, le=20.0,
                             description="realistic: Preetham turbidity (1 molecules only, 2 very clear, 3 clear, "
                                         "6+ hazy)")
    aerosol_g: float = Field(0.7, ge=0.0, lt=1.0,
                             description="realistic: Henyey-Greenstein asymmetry of the aerosol phase function")
    delta_t_s: float | None = Field(None, description="TT - UT1 for SPA, s (default: pvlib's estimate)")
    pressure_hpa: float = Field(1013.25, gt=0.0)
    temperature_c: float = Field(12.0)
    clouds: list[CloudSpec] = Field(default_factory=list)
    occluders: list[OccluderSpec] = Field(default_factory=list)
