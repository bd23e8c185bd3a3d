"""Scenario sections owned by the scenario runner: expectations (and faults)."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, model_validator

from .base import Model

__all__ = ["NavErrorBound", "LinkCounterBound", "DspBound", "Expectation"]


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


