"""Scenario sections owned by the scenario runner: ``faults`` and ``expectations``.

Faults (``emulator.faults`` injects them): a list; each item has exactly one key naming the
fault, whose value holds its parameters and its schedule ``start_s`` (default 0) and
``duration_s`` (omitted: until the end of the run)::

    faults:
      - gnss_outage: {start_s: 60, duration_s: 30}
      - link_bit_errors: {link: gnss, ber: 1.0e-3, start_s: 10, duration_s: 20}

Every fault must show evidence that it took effect while it was active (bytes corrupted,
epochs without a fix, samples clipped...); a fault without evidence makes the run invalid.

Expectations (``emulator.verification.expectations`` evaluates them at the end of the run): a list; each item
has exactly one key naming the kind of check. Time windows are ``after_s`` / ``until_s`` or
``between_s: [a, b]`` (scenario seconds, inclusive).

Cross-field checks that need the whole scenario (a fault at a time outside the run, a fault or an
expectation on a link the scenario does not have, a fault on a sensor it does not have, a Python
hook that does not import...) are in :func:`emulator.scenario.cross_checks.cross_check`, which the
loader runs after the schema validation. An expectation window after the end of the run is not an error
here (tests shorten library scenarios by overriding ``duration_s``); it fails at the end with "nothing
measured".
"""

from __future__ import annotations

import importlib.util
import math
import sys
from pathlib import Path
from typing import Any, ClassVar, Literal

from pydantic import ConfigDict, Field, field_validator, model_validator

from .base import Model, OneKindModel

__all__ = [
    "EXPECTATION_KINDS",
    "FAULT_KINDS",
    "DspBound",
    "DspExtraLoadFault",
    "EventExpectation",
    "Expectation",
    "Fault",
    "FaultWindow",
    "FieldRange",
    "FpgaChannelStallFault",
    "GnssDegradedFault",
    "GnssGlitchFault",
    "GnssOutageFault",
    "HookError",
    "ImuBiasStepFault",
    "ImuDroppedDatagramsFault",
    "ImuSaturationFault",
    "ImuStuckAxisFault",
    "LinkBaudMismatchFault",
    "LinkBitErrorsFault",
    "LinkByteDropsFault",
    "LinkCounterBound",
    "LinkDisconnectFault",
    "LinkNoiseBurstFault",
    "LinkStallFault",
    "NavErrorBound",
    "NavModeExpectation",
    "PsnsCloudCoverFault",
    "PsnsInstallationErrorFault",
    "PsnsSunOccludedFault",
    "PsnsUnitBlockedFault",
    "PythonHook",
    "SummaryValueBound",
    "TimeWindow",
    "load_hook",
]

Vec3 = tuple[float, float, float]
#: link name -> direction the fault applies to by default (named from the DSP, see docs/scenarios.md)
DEFAULT_DIRECTION = {"host": "from_dsp", "monitor": "from_dsp"}
LINK_COUNTERS = ("bytes", "frames", "crc_errors", "dropped", "garbage_bytes", "framing_errors")


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


# ============================================================================ expectations
class TimeWindow(Model):
    """``after_s`` / ``until_s``, or ``between_s: [a, b]`` (inclusive, scenario seconds)."""

    after_s: float = Field(0.0, ge=0.0)
    until_s: float | None = Field(None, gt=0.0)
    between_s: tuple[float, float] | None = Field(None, description="[after_s, until_s] in one field")

    @model_validator(mode="after")
    def _window(self) -> TimeWindow:
        if self.between_s is not None:
            a, b = (float(x) for x in self.between_s)
            if a < 0 or b <= a:
                raise ValueError(f"between_s must be [a, b] with 0 <= a < b, got [{a:g}, {b:g}]")
            # a re-validated dump carries all three; only a contradiction is an error
            if ("after_s" in self.model_fields_set and self.after_s != a) or (
                    "until_s" in self.model_fields_set and self.until_s != b):
                raise ValueError("give between_s or after_s/until_s, not both")
            self.after_s, self.until_s = a, b
        if self.until_s is not None and self.until_s <= self.after_s:
            raise ValueError(f"until_s {self.until_s:g} must be after after_s {self.after_s:g}")
        return self

    def describe_window(self) -> str:
        if self.until_s is None:
            return f"t >= {self.after_s:g} s"
        return f"{self.after_s:g} s <= t <= {self.until_s:g} s"

    def covers(self, t: float) -> bool:
        return t >= self.after_s and (self.until_s is None or t <= self.until_s)


class NavErrorBound(TimeWindow):
    """RMS or max of a navigation error against truth inside a window, at most ``max``."""

    metric: Literal["attitude_deg", "heading_deg", "position_m", "velocity_mps"]
    stat: Literal["rms", "max"] = "max"
    max: float = Field(ge=0)


class FieldRange(Model):
    min: float | None = None
    max: float | None = None


class EventExpectation(TimeWindow):
    """An event (``events.jsonl``) that must occur (``min_count``, default 1, or 0 when only ``max_count`` is
    given) or must not (``max_count: 0``)
    inside a window, optionally from one ``source`` and with field values (``fields``: exact values, or
    ``{min, max}`` for numbers)."""

    name: str = Field(min_length=1, description="the event's name (its 'event' field)")
    source: str | None = Field(None, description="firmware, fault, dsp, fpga, ... (omit: any)")
    min_count: int = Field(1, ge=0)
    max_count: int | None = Field(None, ge=0)
    fields: dict[str, str | int | float | bool | FieldRange] = Field(default_factory=dict)

    @model_validator(mode="after")
    def _counts(self) -> EventExpectation:
        if self.max_count is not None and "min_count" not in self.model_fields_set:
            self.min_count = 0  # "at most N" (max_count: 0 = must not occur)
        if self.max_count is not None and self.max_count < self.min_count:
            raise ValueError(f"max_count {self.max_count} is below min_count {self.min_count}")
        return self


class LinkCounterBound(Model):
    """A link counter of the summary's link table between ``min`` and ``max``."""

    name: str = Field(description="gyro, gnss, psns, host, monitor or uart0..uart3")
    counter: Literal["bytes", "frames", "crc_errors", "dropped", "garbage_bytes", "framing_errors"]
    min: int | None = Field(None, ge=0)
    max: int | None = Field(None, ge=0)

    @model_validator(mode="after")
    def _some(self) -> LinkCounterBound:
        if self.min is None and self.max is None:
            raise ValueError("a link expectation needs min, max or both")
        if self.min is not None and self.max is not None and self.max < self.min:
            raise ValueError(f"max {self.max} is below min {self.min}")
        return self


class DspBound(Model):
    """A DSP figure of the summary between ``min`` and ``max``."""

    field: Literal["cpu_load_pct_max", "deadline_misses", "tick_utilization_max_pct", "watchdog_trips", "resets"]
    min: float | None = Field(None, ge=0)
    max: float | None = Field(None, ge=0)

    @model_validator(mode="after")
    def _some(self) -> DspBound:
        if self.min is None and self.max is None:
            raise ValueError("a dsp expectation needs min, max or both")
        if self.min is not None and self.max is not None and self.max < self.min:
            raise ValueError(f"max {self.max:g} is below min {self.min:g}")
        return self


NAV_MODE_FLAGS = {"aligning": 0x01, "navigating": 0x02, "gnss_aided": 0x04, "psns_aided": 0x08, "degraded": 0x10}


class NavModeExpectation(TimeWindow):
    """The fraction of the host's NAV_SOLUTION frames inside a window that carry a mode flag."""

    flag: Literal["aligning", "navigating", "gnss_aided", "psns_aided", "degraded"]
    min_fraction: float | None = Field(None, ge=0.0, le=1.0)
    max_fraction: float | None = Field(None, ge=0.0, le=1.0)

    @model_validator(mode="after")
    def _some(self) -> NavModeExpectation:
        if self.min_fraction is None and self.max_fraction is None:
            raise ValueError("a nav_mode expectation needs min_fraction, max_fraction or both")
        return self


class SummaryValueBound(Model):
    """Any number in ``summary.json`` by its dotted path (e.g. ``firmware.counters.psns_rejected``)."""

    path: str = Field(pattern=r"^[A-Za-z0-9_]+(\.[A-Za-z0-9_]+)*$")
    min: float | None = None
    max: float | None = None

    @model_validator(mode="after")
    def _some(self) -> SummaryValueBound:
        if self.min is None and self.max is None:
            raise ValueError("a summary expectation needs min, max or both")
        return self


class PythonHook(Model):
    """A function in a ``.py`` file next to the scenario: ``function(summary, run_dir, **args)`` returns
    ``bool``, ``(passed, value[, message])`` or ``{"passed", "value", "message"}``."""

    file: str = Field(pattern=r"\.py$", description="path relative to the scenario file")
    function: str = Field(pattern=r"^[A-Za-z_][A-Za-z0-9_]*$")
    args: dict[str, Any] = Field(default_factory=dict, description="keyword arguments passed to the function")
    description: str | None = None


class Expectation(OneKindModel):
    """One check evaluated at the end of the run; exactly one key."""

    kind_label: ClassVar[str] = "an expectation"

    model_config = ConfigDict(json_schema_extra={"minProperties": 1, "maxProperties": 1})

    nav_error: NavErrorBound | None = None
    event: EventExpectation | None = None
    link: LinkCounterBound | None = None
    dsp: DspBound | None = None
    nav_mode: NavModeExpectation | None = None
    summary: SummaryValueBound | None = None
    python: PythonHook | None = None


EXPECTATION_KINDS = tuple(Expectation.model_fields)


# ============================================================================ Python hooks
class HookError(Exception):
    """A Python hook file that cannot be loaded (message says why)."""


def load_hook(base_dir: str | Path | None, file: str, function: str) -> Any:
    """Import ``file`` (relative to ``base_dir``) and return its ``function``; :class:`HookError` otherwise."""
    p = Path(file)
    if not p.is_absolute() and base_dir is not None:
        p = Path(base_dir) / p
    if not p.is_file():
        raise HookError(f"no such file {str(p)!r}")
    mod_name = f"_psns_hil_hook_{abs(hash(str(p.resolve())))}"
    spec = importlib.util.spec_from_file_location(mod_name, p)
    if spec is None or spec.loader is None:
        raise HookError(f"cannot import {str(p)!r}")
    mod = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(mod)
    except SyntaxError as exc:
        raise HookError(f"{p.name}:{exc.lineno}: syntax error: {exc.msg}") from exc
    except Exception as exc:
        raise HookError(f"importing {p.name} raised {type(exc).__name__}: {exc}") from exc
    fn = getattr(mod, function, None)
    if fn is None:
        names = sorted(n for n in vars(mod) if callable(vars(mod)[n]) and not n.startswith("_"))
        import difflib

        close = difflib.get_close_matches(function, names, n=1, cutoff=0.6)
        hint = f"; did you mean {close[0]!r}?" if close else (f"; it defines {', '.join(names)}" if names else "")
        raise HookError(f"{p.name} has no function {function!r}{hint}")
    if not callable(fn):
        raise HookError(f"{p.name}: {function!r} is not a function")
    sys.modules.pop(mod_name, None)
    return fn
