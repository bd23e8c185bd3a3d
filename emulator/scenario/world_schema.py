"""Scenario sections owned by the world model: origin, initial attitude, motion segments."""

from __future__ import annotations

from pydantic import Field, model_validator

from .base import Model

__all__ = ["Origin", "Attitude", "StaticParams", "MotionSegment"]


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


