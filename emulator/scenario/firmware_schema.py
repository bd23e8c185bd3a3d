"""Scenario sections owned by the firmware: variant, precision, rates, alignment, PSNS processing.

Everything here is what the firmware team configures or calibrates (the DSP's view of the system);
the sensors' true behaviour lives in the sensor sections.
"""

from __future__ import annotations

from typing import Literal

from pydantic import Field

from .base import Model

__all__ = ["AlignmentSpec", "CameraCalibrationSpec", "PsnsFirmwareSpec", "FirmwareSpec"]


class AlignmentSpec(Model):
    time_s: float = Field(2.0, ge=0.1, le=600, description="coarse levelling window")
    heading_source: Literal["auto", "psns", "config"] = Field(
        "auto", description="auto: solar vector if one arrived during levelling, else heading_deg")
    heading_deg: float = Field(0.0, ge=0.0, lt=360.0, description="initial heading given to the firmware")
    heading_sigma_deg: float = Field(1.0, gt=0, le=180)
    psns_timeout_s: float = Field(10.0, ge=0, le=600, description="heading_source psns: wait this long, then fall back")
    psns_heading_sigma_deg: float = Field(0.5, gt=0, le=30)
    fine_time_s: float = Field(60.0, ge=0, le=3600, description="fine alignment (KF) before NAVIGATE is reported")


class CameraCalibrationSpec(Model):
    """The polarization camera as the firmware knows it (CONTRACTS C1).

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
    sigma_deg: float = Field(0.1, gt=0, le=10, description="solar-vector noise per axis (R of Eq. 42)")
    dop_min: float = Field(0.05, ge=0, lt=1)
    quality_max: float = Field(0.2, gt=0, le=1, description="largest lambda_min/lambda_mid accepted")
    min_sun_elevation_deg: float = Field(5.0, ge=-10, le=80)
    gate_chi2: float = Field(16.27, gt=0, description="innovation gate (chi-square, 3 dof)")
    camera: CameraCalibrationSpec = CameraCalibrationSpec()


class FirmwareSpec(Model):
    filter: Literal["base"] = "base"
    precision: Literal["float32", "float64"] = "float32"
    nav_state_precision: Literal["float32", "float64"] = Field(
        "float64", description="strapdown quaternion/velocity accumulators (docs/decisions.md D-L.1)")
    output_rate_hz: float = Field(100.0, gt=0, le=200)
    kf_predict_every: int = Field(20, ge=1, le=200)
    coning_samples: Literal[0, 1, 2] = Field(0, description="0: two-sample with angle increments, else one")
    alignment: AlignmentSpec = AlignmentSpec()
    psns: PsnsFirmwareSpec = PsnsFirmwareSpec()
