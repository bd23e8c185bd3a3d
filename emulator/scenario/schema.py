"""The scenario schema (pydantic v2). Units are in the field names; angles in degrees.

A scenario file is one YAML mapping::

    name, description, seed, epoch (UTC), duration_s, mode (fast|realtime), speed
    origin      {lat_deg, lon_deg, height_m}
    attitude    {heading_deg, pitch_deg, roll_deg}           initial attitude
    motion      [ {static: {duration_s}} ... ]                 motion segments
    sky         {model, p_max, clouds, occluders, ...}          sky polarization (world_schema)
    sensors     {imu: {...}, gnss: {...}}                      presets + overrides
    links       {gyro|gnss|psns|host: {url, baud, mode, queue_bytes}}
    fpga        {routing: {port: uartN}, uarts: {uartN: {baud, queue_bytes}}}
    dsp         {clock_hz}
    firmware    {filter, precision, output_rate_hz, kf_predict_every, alignment: {...}}
    faults      [ {gnss_outage: {start_s, duration_s}} ... ]    scheduled faults (faults_schema)
    expectations [ {nav_error: {...}} ... ]                   checks at the end (expectations_schema)

Unknown keys anywhere are errors. ``docs/scenarios.md`` is the guide. Each section lives in the
module of the subsystem that owns it (``world_schema``, ``sensor_schema``, ``runtime_schema``,
``firmware_schema``, ``faults_schema``, ``expectations_schema``); this module assembles them.
"""

from __future__ import annotations

import datetime as _dt
from typing import Any, Literal

from pydantic import Field, PrivateAttr, field_validator, model_validator

from .base import Model
from .expectations_schema import (
    DspBound,
    EventExpectation,
    Expectation,
    LinkCounterBound,
    NavErrorBound,
    NavModeExpectation,
    PsnsErrorBound,
    PythonHook,
    SummaryValueBound,
)
from .faults_schema import Fault
from .firmware_schema import AlignmentSpec, FirmwareSpec
from .runtime_schema import DspSpec, FpgaSpec, Links, LinkSpec, UartSpec
from .sensor_schema import AccelSpec, GnssErrorSpec, GnssSpec, GyroSpec, ImuSpec, Sensors
from .world_schema import Attitude, EnvelopeSpec, MotionSegment, Origin, SkySpec, StaticParams

__all__ = [
    "AccelSpec",
    "AlignmentSpec",
    "Attitude",
    "DspBound",
    "DspSpec",
    "EventExpectation",
    "Expectation",
    "Fault",
    "FirmwareSpec",
    "FpgaSpec",
    "GnssErrorSpec",
    "GnssSpec",
    "GyroSpec",
    "ImuSpec",
    "LinkCounterBound",
    "LinkSpec",
    "Links",
    "MotionSegment",
    "NavErrorBound",
    "NavModeExpectation",
    "Origin",
    "PsnsErrorBound",
    "PythonHook",
    "Scenario",
    "Sensors",
    "SkySpec",
    "StaticParams",
    "SummaryValueBound",
    "UartSpec",
]


class Scenario(Model):
    """A whole scenario (see module docstring)."""

    name: str = Field(pattern=r"^[A-Za-z0-9_.-]+$", max_length=80)
    description: str = ""
    tags: list[Literal["slow", "realtime", "pty", "needs-socat"]] = Field(
        default_factory=list, description="'slow': excluded from the default test run")
    seed: int = Field(1, ge=0, lt=2**32)
    epoch: _dt.datetime
    duration_s: float = Field(gt=0, le=86400)
    mode: Literal["fast", "realtime"] = "fast"
    speed: float = Field(1.0, gt=0, le=1000)
    origin: Origin
    attitude: Attitude = Attitude()
    motion: list[MotionSegment] = Field(default_factory=list)
    sky: SkySpec = SkySpec()
    envelope: EnvelopeSpec = Field(EnvelopeSpec(), description="the world drawn per seed from published ranges "
                                                              "(docs/sensors.md \"The envelope\")")
    sensors: Sensors = Sensors()
    links: Links = Links()
    fpga: FpgaSpec = FpgaSpec()
    dsp: DspSpec = DspSpec()
    firmware: FirmwareSpec = FirmwareSpec()
    faults: list[Fault] = Field(default_factory=list, description="scheduled faults (docs/scenarios.md)")
    expectations: list[Expectation] = Field(default_factory=list)

    _source_file: str = PrivateAttr(default="<scenario>")
    _base_dir: str | None = PrivateAttr(default=None)
    #: where each key of the file is (field path -> (line, column)), for warnings after validation
    _marks: dict[tuple[Any, ...], tuple[int, int]] = PrivateAttr(default_factory=dict)

    @property
    def source_file(self) -> str:
        return self._source_file

    @property
    def base_dir(self) -> str | None:
        return self._base_dir

    @field_validator("epoch")
    @classmethod
    def _utc(cls, v: _dt.datetime) -> _dt.datetime:
        if v.tzinfo is None:
            raise ValueError("epoch needs a time zone; write UTC as e.g. 2019-09-18T08:14:00Z")
        return v.astimezone(_dt.UTC)

    @model_validator(mode="after")
    def _motion_covers(self) -> Scenario:
        total = sum(seg.duration_s for seg in self.motion)
        if self.motion and total + 1e-9 < self.duration_s:
            raise ValueError(
                f"motion segments cover {total:g} s but duration_s is {self.duration_s:g} s"
            )
        return self
