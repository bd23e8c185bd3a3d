"""The scenario's ``faults`` section: one model per fault kind, each with its schedule.

Faults (``emulator.faults`` injects them): a list; each item has exactly one key naming the
fault, whose value holds its parameters and its schedule ``start_s`` (default 0) and
``duration_s`` (omitted: until the end of the run)::

    faults:
      - gnss_outage: {start_s: 60, duration_s: 30}
      - link_bit_errors: {link: gnss, ber: 1.0e-3, start_s: 10, duration_s: 20}

Every fault must show evidence that it took effect while it was active (bytes corrupted,
epochs without a fix, samples clipped...); a fault without evidence makes the run invalid.
Cross-field checks that need the whole scenario (a fault at a time outside the run, on a link or a sensor the
scenario does not have) are in :func:`emulator.scenario.cross_checks.cross_check`, which the loader runs after the
schema validation.
"""

from __future__ import annotations

import math
from typing import ClassVar, Literal

from pydantic import ConfigDict, Field, field_validator, model_validator

from .base import Model, OneKindModel

__all__ = [
    "DEFAULT_DIRECTION",
    "FAULT_KINDS",
    "DspExtraLoadFault",
    "Fault",
    "FaultWindow",
    "FpgaChannelStallFault",
    "GnssDegradedFault",
    "GnssGlitchFault",
    "GnssOutageFault",
    "ImuBiasStepFault",
    "ImuDroppedDatagramsFault",
    "ImuSaturationFault",
    "ImuStuckAxisFault",
    "LinkBaudMismatchFault",
    "LinkBitErrorsFault",
    "LinkByteDropsFault",
    "LinkDisconnectFault",
    "LinkNoiseBurstFault",
    "LinkStallFault",
    "PsnsCloudCoverFault",
    "PsnsInstallationErrorFault",
    "PsnsSunOccludedFault",
    "PsnsUnitBlockedFault",
]

Vec3 = tuple[float, float, float]
#: link name -> direction the fault applies to by default (named from the DSP, see docs/scenarios.md)
DEFAULT_DIRECTION = {"host": "from_dsp", "monitor": "from_dsp"}


# ============================================================================ faults
class FaultWindow(Model):
    """Schedule of one fault: active from ``start_s`` for ``duration_s`` (omitted: to the end of the run)."""

    start_s: float = Field(0.0, ge=0.0, description="scenario time the fault starts, s")
    duration_s: float | None = Field(None, gt=0.0, description="how long it lasts, s (omit: until the run ends)")

    def end_s(self, run_duration_s: float) -> float:
        return run_duration_s if self.duration_s is None else self.start_s + self.duration_s


class GnssOutageFault(FaultWindow):
    """The receiver loses lock: sentences without a fix (GGA quality 0, RMC V), no PPS; re-acquires after."""


class GnssGlitchFault(FaultWindow):
    """The reported position jumps by ``offset_enu_m`` (multipath, false lock) while the fix stays valid."""

    offset_enu_m: Vec3 = Field(description="position error added, ENU metres")


class GnssDegradedFault(FaultWindow):
    """Poorer solution: more noise, fewer satellites, a downgraded fix type (fewer than 4 satellites: no fix)."""

    noise_scale: float = Field(3.0, ge=1.0, le=1000.0, description="position and velocity noise multiplier")
    num_sats: int | None = Field(None, ge=0, le=99, description="satellites used (< 4: no fix)")
    hdop: float | None = Field(None, gt=0.0, le=99.0)
    fix_quality: Literal[1, 2, 4, 5] | None = Field(
        None, description="GGA quality reported (1 GPS, 2 DGPS, 4 RTK fixed, 5 RTK float)")


class PsnsCloudCoverFault(FaultWindow):
    """A cloud over part of the sky (default: overcast around the zenith): lower DOP, scrambled AOP."""

    az_deg: float = Field(0.0, ge=0.0, lt=360.0, description="centre azimuth, clockwise from north, deg")
    el_deg: float = Field(90.0, ge=0.0, le=90.0, description="centre elevation, deg")
    radius_deg: float = Field(60.0, gt=0.0, le=180.0, description="angular radius, deg")
    dop_scale: float = Field(0.1, ge=0.0, le=1.0, description="DOP multiplier inside")
    aop_sigma_deg: float = Field(30.0, ge=0.0, le=180.0, description="AOP scrambling inside, deg (1 sigma)")
    intensity_scale: float = Field(1.5, gt=0.0, le=10.0)
    drift_az_dps: float = Field(0.0, ge=-180.0, le=180.0, description="azimuth drift of the centre, deg/s")


class PsnsUnitBlockedFault(FaultWindow):
    """Polarization units covered (dirt, a hand, snow): compass units see unpolarized light (DOP ~0, scrambled
    AOP; the compass's blocked-units schedule); a camera sends frames without observation points
    (OCCLUDED, LOW_DOP)."""

    units: list[int] | None = Field(None, description="compass unit indices (omit: all); not for a camera")

    @field_validator("units")
    @classmethod
    def _units(cls, v: list[int] | None) -> list[int] | None:
        if v is not None:
            if not v:
                raise ValueError("units must not be empty (omit it to block every unit)")
            bad = [u for u in v if not 0 <= u < 64]
            if bad:
                raise ValueError(f"compass unit indices are 0 or more (and below 64), got {bad}")
        return v


class PsnsSunOccludedFault(FaultWindow):
    """The sky around the sun is hidden (a cloud or a building in front of the sun): unpolarized, darker."""

    radius_deg: float = Field(15.0, gt=0.0, le=90.0, description="hidden region around the sun, deg")
    dop_scale: float = Field(0.0, ge=0.0, le=1.0)
    intensity_scale: float = Field(0.3, gt=0.0, le=10.0)


class PsnsInstallationErrorFault(FaultWindow):
    """The sensor mount shifts by a small rotation (the firmware keeps its nominal calibration)."""

    rotation_deg: Vec3 = Field(description="rotation vector about the sensor's own axes, deg")

    @field_validator("rotation_deg")
    @classmethod
    def _small(cls, v: Vec3) -> Vec3:
        n = math.sqrt(sum(x * x for x in v))
        if n == 0.0:
            raise ValueError("rotation_deg is zero: the fault would change nothing")
        if n > 30.0:
            raise ValueError(f"rotation_deg has norm {n:.1f} deg; an installation error is at most 30 deg")
        return v


class ImuBiasStepFault(FaultWindow):
    """A step in the gyro or accelerometer bias (exactly one of the two fields)."""

    gyro_deg_h: Vec3 | None = Field(None, description="gyro bias step per body axis x, y, z, deg/h")
    accel_mg: Vec3 | None = Field(None, description="accelerometer bias step per body axis, mg")

    @model_validator(mode="after")
    def _one(self) -> ImuBiasStepFault:
        if (self.gyro_deg_h is None) == (self.accel_mg is None):
            raise ValueError("imu_bias_step needs exactly one of gyro_deg_h, accel_mg")
        v = self.gyro_deg_h if self.gyro_deg_h is not None else self.accel_mg
        if not any(v):  # type: ignore[arg-type]
            raise ValueError("the bias step is zero: the fault would change nothing")
        return self

    @property
    def sensor(self) -> str:
        return "gyro" if self.gyro_deg_h is not None else "accel"


class ImuStuckAxisFault(FaultWindow):
    """Axes of a sensor freeze at their last output."""

    sensor: Literal["gyro", "accel"]
    axes: list[Literal["x", "y", "z"]] = Field(min_length=1, description="body axes that freeze")


class ImuSaturationFault(FaultWindow):
    """The sensor's range drops (a gain fault): outputs beyond it clip (exactly one field)."""

    gyro_range_dps: float | None = Field(None, gt=0.0, le=400.0)
    accel_range_g: float | None = Field(None, gt=0.0, le=30.0)

    @model_validator(mode="after")
    def _one(self) -> ImuSaturationFault:
        if (self.gyro_range_dps is None) == (self.accel_range_g is None):
            raise ValueError("imu_saturation needs exactly one of gyro_range_dps, accel_range_g")
        return self

    @property
    def sensor(self) -> str:
        return "gyro" if self.gyro_range_dps is not None else "accel"


class ImuDroppedDatagramsFault(FaultWindow):
    """The STIM210 skips datagrams (the FPGA then flags GYRO_MISSING)."""

    probability: float = Field(0.5, gt=0.0, le=1.0, description="chance that a datagram is not sent")


class _LinkFault(FaultWindow):
    link: str = Field(description="gyro, gnss, psns, host, monitor or uart0..uart3")
    direction: Literal["to_dsp", "from_dsp"] | None = Field(
        None, description="which way the bytes travel (default: from_dsp for host and monitor, to_dsp otherwise)")

    def effective_direction(self) -> str:
        return self.direction or DEFAULT_DIRECTION.get(self.link, "to_dsp")


class LinkBitErrorsFault(_LinkFault):
    """Random bit errors on the wire at ``ber`` per bit."""

    ber: float = Field(gt=0.0, le=0.5, description="bit error rate (per bit on the wire, start/stop bits included)")


class LinkByteDropsFault(_LinkFault):
    """Bytes lost on the wire, each with ``probability``."""

    probability: float = Field(gt=0.0, le=1.0)


class LinkNoiseBurstFault(_LinkFault):
    """Electrical noise: bit errors at ``ber`` plus spurious bytes (false start bits), ``spurious_per_byte``
    extra random bytes per byte on the wire."""

    ber: float = Field(0.02, gt=0.0, le=0.5)
    spurious_per_byte: float = Field(0.05, ge=0.0, le=10.0)


class LinkBaudMismatchFault(_LinkFault):
    """The receiving UART runs at a wrong baud (``baud_error_pct`` off, or ``rx_baud``); it samples the
    transmitter's waveform bit by bit (framing errors, corrupted bytes). Direction ``to_dsp`` only."""

    baud_error_pct: float | None = Field(None, ge=-50.0, le=100.0)
    rx_baud: int | None = Field(None, gt=0, le=20_000_000)

    @model_validator(mode="after")
    def _one(self) -> LinkBaudMismatchFault:
        if (self.baud_error_pct is None) == (self.rx_baud is None):
            raise ValueError("link_baud_mismatch needs exactly one of baud_error_pct, rx_baud")
        if self.baud_error_pct == 0.0:
            raise ValueError("baud_error_pct is 0: the fault would change nothing")
        if self.direction == "from_dsp":
            raise ValueError("link_baud_mismatch models the receiver of the bytes towards the DSP; "
                             "use direction to_dsp (the default)")
        return self


class LinkDisconnectFault(FaultWindow):
    """The cable is unplugged (both directions), then plugged back in."""

    link: str = Field(description="gyro, gnss, psns, host, monitor or uart0..uart3")


class LinkStallFault(_LinkFault):
    """The line stops moving bytes (flow control, a hung transmitter): bytes wait in the transmitter's queue
    (``links.<port>.queue_bytes``; the excess is lost) and go out when the stall ends."""


class FpgaChannelStallFault(FaultWindow):
    """An FPGA channel stops being serviced: ``gyro`` (datagrams ignored: GYRO_MISSING frames), ``uart1``
    (no IMU/MAG frames sent), ``mag`` (no MAG frames), or a crossbar route ``host``, ``gnss``, ``psns``
    (bytes not forwarded either way)."""

    channel: Literal["gyro", "uart1", "mag", "host", "gnss", "psns"]


class DspExtraLoadFault(FaultWindow):
    """Extra cycles on every tick (a runaway task, an interrupt storm), charged before the firmware's work:
    exactly one of ``cycles_per_tick`` or ``load_pct`` (percent of the tick budget)."""

    cycles_per_tick: int | None = Field(None, gt=0, le=10**10)
    load_pct: float | None = Field(None, gt=0.0, le=10000.0)

    @model_validator(mode="after")
    def _one(self) -> DspExtraLoadFault:
        if (self.cycles_per_tick is None) == (self.load_pct is None):
            raise ValueError("dsp_extra_load needs exactly one of cycles_per_tick, load_pct")
        return self


class Fault(OneKindModel):
    """One scheduled fault; exactly one key (see module docstring and docs/scenarios.md)."""

    kind_label: ClassVar[str] = "a fault"

    model_config = ConfigDict(json_schema_extra={"minProperties": 1, "maxProperties": 1})

    gnss_outage: GnssOutageFault | None = None
    gnss_glitch: GnssGlitchFault | None = None
    gnss_degraded: GnssDegradedFault | None = None
    psns_cloud_cover: PsnsCloudCoverFault | None = None
    psns_unit_blocked: PsnsUnitBlockedFault | None = None
    psns_sun_occluded: PsnsSunOccludedFault | None = None
    psns_installation_error: PsnsInstallationErrorFault | None = None
    imu_bias_step: ImuBiasStepFault | None = None
    imu_stuck_axis: ImuStuckAxisFault | None = None
    imu_saturation: ImuSaturationFault | None = None
    imu_dropped_datagrams: ImuDroppedDatagramsFault | None = None
    link_bit_errors: LinkBitErrorsFault | None = None
    link_byte_drops: LinkByteDropsFault | None = None
    link_noise_burst: LinkNoiseBurstFault | None = None
    link_baud_mismatch: LinkBaudMismatchFault | None = None
    link_disconnect: LinkDisconnectFault | None = None
    link_stall: LinkStallFault | None = None
    fpga_channel_stall: FpgaChannelStallFault | None = None
    dsp_extra_load: DspExtraLoadFault | None = None

    @property
    def spec(self) -> FaultWindow:
        return self.value


FAULT_KINDS = tuple(Fault.model_fields)
