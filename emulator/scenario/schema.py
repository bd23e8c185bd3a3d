"""The scenario schema (pydantic v2). Units are in the field names; angles in degrees.

A scenario file is one YAML mapping::

    name, description, seed, epoch (UTC), duration_s, mode (fast|realtime), speed
    origin      {lat_deg, lon_deg, height_m}
    attitude    {heading_deg, pitch_deg, roll_deg}           initial attitude
    motion      [ {static: {duration_s}} ... ]                 motion segments
    sensors     {imu: {...}, gnss: {...}}                      presets + overrides
    links       {gyro|gnss|psns|host: {url, baud, mode, queue_bytes}}
    fpga        {routing: {port: uartN}, uarts: {uartN: {baud, queue_bytes}}}
    dsp         {clock_hz}
    firmware    {filter, precision, output_rate_hz, kf_predict_every, alignment: {...}}
    faults      [ ... ]
    expectations [ ... ]

Unknown keys anywhere are errors. ``docs/scenarios.md`` is the guide.
"""

from __future__ import annotations

import datetime as _dt
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field, PrivateAttr, field_validator, model_validator

__all__ = [
    "Scenario",
    "Origin",
    "Attitude",
    "MotionSegment",
    "LinkSpec",
    "ImuSpec",
    "GnssSpec",
    "FpgaSpec",
    "DspSpec",
    "FirmwareSpec",
    "Expectation",
]


class Model(BaseModel):
    model_config = ConfigDict(extra="forbid", validate_assignment=False)


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


class MotionSegment(Model):
    """One motion segment; exactly one key."""

    static: StaticParams | None = None

    @model_validator(mode="after")
    def _one(self) -> "MotionSegment":
        set_keys = [k for k in type(self).model_fields if getattr(self, k) is not None]
        if len(set_keys) != 1:
            raise ValueError(f"a motion segment has exactly one kind, got {set_keys or 'none'}")
        return self

    @property
    def duration_s(self) -> float:
        for k in type(self).model_fields:
            v = getattr(self, k)
            if v is not None:
                return float(v.duration_s)
        return 0.0


class LinkSpec(Model):
    url: str = Field(description="mem://NAME, pty://NAME or serial:///dev/ttyXXX")
    baud: int | None = Field(None, gt=0, le=20_000_000)
    mode: str = Field("8N1", pattern=r"^[5-8][NEO](1|1\.5|2)$")
    queue_bytes: int = Field(4096, ge=1, le=1 << 24)

    @field_validator("url")
    @classmethod
    def _url(cls, v: str) -> str:
        from ..links import parse_link_url

        parse_link_url(v)  # raises LinkConfigError (a ValueError) with the accepted form
        return v


class Links(Model):
    gyro: LinkSpec = LinkSpec(url="mem://gyro", baud=460800)
    gnss: LinkSpec = LinkSpec(url="mem://gnss", baud=9600)
    psns: LinkSpec | None = None
    host: LinkSpec = LinkSpec(url="mem://host", baud=460800)


class GyroSpec(Model):
    arw_deg_rt_h: float | None = Field(None, ge=0)
    bias_repeatability_deg_h: float | None = Field(None, ge=0)
    bias_instability_deg_h: float | None = Field(None, ge=0)
    bias_corr_time_s: float | None = Field(None, gt=0)
    range_dps: float | None = Field(None, gt=0)


class AccelSpec(Model):
    bias_repeatability_mg: tuple[float, float, float] | None = None
    bias_instability_mg: tuple[float, float, float] | None = None
    bias_corr_time_s: float | None = Field(None, gt=0)
    noise_ug_rt_hz: float | None = Field(None, ge=0)


class ImuSpec(Model):
    preset: Literal["paper", "perfect"] = "paper"
    format: Literal["s", "e", "j", "k", "l", "m", "n", "o", "p"] = "m"
    output: Literal["rate", "angle"] = "rate"
    rate_hz: float = Field(200.0, gt=0, le=2000)
    gyro: GyroSpec = GyroSpec()
    accel: AccelSpec = AccelSpec()


class GnssErrorSpec(Model):
    pos_sigma_h_m: float | None = Field(None, ge=0)
    pos_sigma_v_m: float | None = Field(None, ge=0)
    pos_corr_time_s: float | None = Field(None, gt=0)
    vel_sigma_h_mps: float | None = Field(None, ge=0)
    vel_sigma_v_mps: float | None = Field(None, ge=0)


class GnssSpec(Model):
    enabled: bool = True
    preset: Literal["paper", "perfect"] = "paper"
    rate_hz: float = Field(1.0, gt=0, le=20)
    latency_s: float = Field(0.05, ge=0, lt=1)
    sentences: list[Literal["GGA", "RMC"]] = ["GGA", "RMC"]
    geoid_sep_m: float = 0.0
    errors: GnssErrorSpec = GnssErrorSpec()


class Sensors(Model):
    imu: ImuSpec = ImuSpec()
    gnss: GnssSpec = GnssSpec()


class UartSpec(Model):
    baud: int = Field(gt=0, le=3_000_000)
    queue_bytes: int = Field(4096, ge=1, le=1 << 24)


def _default_uarts() -> dict[str, UartSpec]:
    return {
        "uart0": UartSpec(baud=460800),
        "uart1": UartSpec(baud=460800),
        "uart2": UartSpec(baud=115200),
        "uart3": UartSpec(baud=115200),
    }


class FpgaSpec(Model):
    routing: dict[Literal["host", "gnss", "psns"], Literal["uart0", "uart2", "uart3"]] = Field(
        default_factory=lambda: {"host": "uart0", "psns": "uart2", "gnss": "uart3"}
    )
    uarts: dict[Literal["uart0", "uart1", "uart2", "uart3"], UartSpec] = Field(default_factory=_default_uarts)
    gyro_timeout_s: float = Field(0.004, gt=0, lt=0.1)

    @field_validator("uarts")
    @classmethod
    def _fill(cls, v: dict[str, UartSpec]) -> dict[str, UartSpec]:
        out = _default_uarts()
        out.update(v)
        return out


class DspSpec(Model):
    clock_hz: float = Field(300e6, ge=1e6, le=2e9)


class AlignmentSpec(Model):
    time_s: float = Field(2.0, ge=0.1, le=600)
    heading_deg: float = Field(0.0, ge=0.0, lt=360.0, description="initial heading given to the firmware")
    heading_sigma_deg: float = Field(1.0, gt=0, le=180)


class FirmwareSpec(Model):
    filter: Literal["base"] = "base"
    precision: Literal["float32", "float64"] = "float32"
    output_rate_hz: float = Field(100.0, gt=0, le=200)
    kf_predict_every: int = Field(20, ge=1, le=200)
    alignment: AlignmentSpec = AlignmentSpec()


class NavErrorBound(Model):
    metric: Literal["attitude_deg", "heading_deg", "position_m", "velocity_mps"]
    stat: Literal["rms", "max"] = "max"
    max: float = Field(ge=0)
    after_s: float = Field(0.0, ge=0)
    until_s: float | None = Field(None, gt=0)


class LinkCounterBound(Model):
    name: str
    counter: Literal["bytes", "frames", "crc_errors", "dropped"]
    min: int | None = Field(None, ge=0)
    max: int | None = Field(None, ge=0)


class DspBound(Model):
    field: Literal["cpu_load_pct_max", "deadline_misses"]
    max: float = Field(ge=0)


class Expectation(Model):
    """One check evaluated at the end of the run; exactly one key."""

    nav_error: NavErrorBound | None = None
    link: LinkCounterBound | None = None
    dsp: DspBound | None = None

    @model_validator(mode="after")
    def _one(self) -> "Expectation":
        set_keys = [k for k in type(self).model_fields if getattr(self, k) is not None]
        if len(set_keys) != 1:
            raise ValueError(f"an expectation has exactly one kind, got {set_keys or 'none'}")
        return self


class Scenario(Model):
    """A whole scenario (see module docstring)."""

    name: str = Field(pattern=r"^[A-Za-z0-9_.-]+$", max_length=80)
    description: str = ""
    seed: int = Field(1, ge=0, lt=2**32)
    epoch: _dt.datetime
    duration_s: float = Field(gt=0, le=86400)
    mode: Literal["fast", "realtime"] = "fast"
    speed: float = Field(1.0, gt=0, le=1000)
    origin: Origin
    attitude: Attitude = Attitude()
    motion: list[MotionSegment] = Field(default_factory=list)
    sensors: Sensors = Sensors()
    links: Links = Links()
    fpga: FpgaSpec = FpgaSpec()
    dsp: DspSpec = DspSpec()
    firmware: FirmwareSpec = FirmwareSpec()
    faults: list[dict[str, Any]] = Field(default_factory=list, max_length=0)
    expectations: list[Expectation] = Field(default_factory=list)

    _source_file: str = PrivateAttr(default="<scenario>")
    _base_dir: str | None = PrivateAttr(default=None)

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
        return v.astimezone(_dt.timezone.utc)

    @model_validator(mode="after")
    def _motion_covers(self) -> "Scenario":
        total = sum(seg.duration_s for seg in self.motion)
        if self.motion and total + 1e-9 < self.duration_s:
            raise ValueError(
                f"motion segments cover {total:g} s but duration_s is {self.duration_s:g} s"
            )
        return self
