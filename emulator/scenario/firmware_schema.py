"""Scenario sections owned by the firmware: variant, precision, rates, alignment."""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from .base import Model

__all__ = ["AlignmentSpec", "FirmwareSpec"]


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


