"""Scenario sections owned by the sensor models: IMU, GNSS (presets + overrides)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from .base import Model

__all__ = ["GyroSpec", "AccelSpec", "ImuSpec", "GnssErrorSpec", "GnssSpec", "Sensors"]


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


