"""The run summary (``summary.json``) as a typed model: :class:`RunSummary`.

The assembly builds the summary as a dict (:mod:`emulator.assembly.session`) and the recorder writes it as strict
JSON; readers load it through :func:`load_summary`, which validates it against this model, so a reader gets
typed sections and a clear error for a file that is not a summary. Sections that grow with the firmware (``dsp``,
``firmware``, ``fpga``, ``devices``) are typed where readers depend on them and open (``extra="allow"``)
elsewhere. ``docs/summary.schema.json`` is generated from this model (:func:`summary_json_schema`;
``tests/emulator/recording/test_summary_model.py`` keeps it current).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, ValidationError

from ..errors import RecordingError

__all__ = ["EnvelopeRecord", "ErrorStat", "ExpectationRecord", "LinkCounters", "PsnsSection", "RunSummary",
           "load_summary", "summary_json_schema"]


class _Open(BaseModel):
    model_config = ConfigDict(extra="allow")


class ErrorStat(_Open):
    rms: float | None = Field(None, description="RMS over the navigating frames (null: none, or not a number)")
    max: float | None = Field(None, description="largest absolute value (null: none, or not a number)")


class LinkCounters(_Open):
    bytes: int = Field(0, description="bytes that crossed the link, both directions")
    frames: int = Field(0, description="frames decoded on the link")
    crc_errors: int = Field(0, description="frames with a bad checksum")
    dropped: int = Field(0, description="bytes lost: TX queue overflow, a full kernel buffer")
    no_peer: int = Field(0, description="bytes a pty sent while no peer was attached (unheard, not dropped)")
    garbage_bytes: int = Field(0, description="bytes the decoders skipped while resynchronising")
    framing_errors: int = Field(0, description="characters with a bad stop bit")


class DspTask(_Open):
    task: str
    calls: int
    cycles_min: int | None = None
    cycles_avg: float | None = None
    cycles_max: int | None = None
    utilization_max_pct: float | None = None
    kernels: dict[str, float] = Field(default_factory=dict, description="cycles per kernel, summed over calls")


class DspSection(_Open):
    clock_hz: float | None = Field(description="DSP clock, Hz (null: the DSP is outside, dsp.external)")
    cpu_load_pct_max: float | None = Field(None, description="CPU load of the worst 1 s, %")
    tick_budget_cycles: int | None = None
    deadline_misses: int | None = Field(0, description="ticks that ended late (null: not observed, the DSP is "
                                           "outside)")
    cost_model: str | None = None
    tasks: list[DspTask] = Field(default_factory=list)


class ExternalDspSection(_Open):
    """What the emulator saw of a DSP outside (``dsp.external``; docs/runtime.md, DSP out)."""

    nav_frames: int = Field(0, description="NAV_SOLUTION frames the outside DSP wrote on UART0")
    garbage_bytes: int = Field(0, description="UART0 bytes from the outside DSP that were no frame")
    crc_errors: int = Field(0, description="UART0 frames from the outside DSP with a bad CRC")
    length_errors: int = Field(0, description="UART0 frame headers with an impossible length")
    unexpected_bytes: dict[str, int] = Field(default_factory=dict,
                                             description="bytes the outside DSP wrote on an input-only UART")
    silent: bool = Field(False, description="the outside DSP never sent a byte")
    silences: int = Field(0, description="times it said nothing for silence_s once it had IMU frames")
    silent_s: float = Field(0.0, description="time it spent silent, s")


class FaultRecord(_Open):
    index: int
    kind: str
    target: str
    fired: bool | None = Field(None, description="whether the fault took effect (null: nothing to check)")
    active_from_s: float | None = None
    active_until_s: float | None = None
    evidence: dict[str, Any] = Field(default_factory=dict)


class SolarVectorError(_Open):
    median: float | None = Field(None, description="median angle between the solved and the true solar vector, deg")
    p95: float | None = Field(None, description="95th percentile (linear interpolation), deg")
    max: float | None = Field(None, description="largest, deg")


class PsnsSection(_Open):
    """The firmware's solved solar vectors against truth (``psns.csv``; emulator/recording/psns_error.py)."""

    solves: int = Field(0, description="solar vectors the firmware solved (one row each in psns.csv)")
    uses: dict[str, int] = Field(default_factory=dict, description="solves by what the loop did with them: "
                                 "accepted, refused (the filter's gate), alignment, sun_low, stale, no_utc, disabled")
    solar_vector_error_deg: SolarVectorError = Field(
        default_factory=SolarVectorError, description="angle between the solved bi-direction solar vector and the "
                                                      "world's sun in the body frame at the exposure time, deg")
    azimuth_error_deg: SolarVectorError = Field(
        default_factory=SolarVectorError, description="|azimuth error| of the solve turned to ENU with the true "
                                                      "attitude (what a sun-referenced heading inherits), deg")
    elevation_error_deg: SolarVectorError = Field(
        default_factory=SolarVectorError, description="|elevation error| of the solve turned to ENU with the true "
                                                      "attitude (what maps into tilt), deg")


class ExpectationRecord(_Open):
    index: int
    kind: str
    description: str
    value: float | int | str | None = None
    passed: bool
    message: str = ""
    applicable: bool = Field(True, description="false when the expectation cannot apply (a replay); it then "
                                               "does not fail")


class ReplayInfo(_Open):
    source: str | None = Field(None, description="the capture replayed")
    records: int = Field(0, description="captured DSP UART records replayed")
    truncated: bool | None = Field(None, description="the capture ends before the scenario did")
    captured_s: float | None = Field(None, description="the duration the capture really holds, s")
    scenario_duration_s: float | None = None


class EnvelopeRecord(_Open):
    preset: str = Field(description="the envelope preset (emulator/presets/envelope.yaml)")
    groups: list[str] | None = Field(None, description="the groups drawn (null: every group of the preset)")
    draws: dict[str, Any] = Field(description="scenario key -> the value this run's seed drew (the key's units)")
    pinned: list[str] = Field(default_factory=list, description="keys the scenario set itself: not drawn")


class RunSummary(_Open):
    """``summary.json`` of one run (see module docstring)."""

    psns_hil_version: str | None = None
    scenario: str = Field(description="the scenario's name")
    scenario_file: str | None = None
    seed: int | None = None
    mode: str | None = Field(None, description="fast or realtime")
    speed: float | None = None
    epoch: str | None = Field(None, description="UTC epoch of t = 0, ISO 8601")
    sim_duration_s: float | None = Field(None, description="simulated time the run covered, s")
    wall_s: float | None = None
    realtime_factor: float | None = None
    paced_writer: dict[str, Any] | None = Field(
        None, description="realtime with a lead: the paced writer's backend asked for and the one writing (process "
                          "or thread), its scheduling policy, writes, failures and the error if its process died "
                          "(docs/decisions/performance.md D-10.E11); null otherwise")
    interrupted: bool = False
    started: bool | None = Field(None, description="false when the run was interrupted while starting")
    replay: ReplayInfo | None = None
    envelope: EnvelopeRecord | None = Field(
        None, description="the world this seed drew from an envelope (docs/sensors.md \"The envelope\"); null: the "
                          "scenario's world as written")
    run_dir: str
    nav_error: dict[str, ErrorStat] = Field(
        default_factory=dict, description="error against truth while navigating (fine alignment included), per metric")
    nav_error_by_phase: dict[str, dict[str, ErrorStat]] = Field(
        default_factory=dict, description="nav_error split by phase: fine_alignment (ALIGNING with NAVIGATING) "
                                          "and navigating (NAVIGATING alone), per metric")
    nav_frames: int | None = None
    links: dict[str, LinkCounters] = Field(default_factory=dict)
    link_stats: dict[str, dict[str, Any]] = Field(default_factory=dict, description="raw counters per link end")
    bound_ports: dict[str, dict[str, Any]] = Field(
        default_factory=dict, description="sensor ports bound out to a real port (links.NAME.direction out / tee): "
                                          "the real port's counters, its direction and url, and peer_bytes (what its "
                                          "peer sent to the sensor)")
    dsp: DspSection | None = None
    firmware: dict[str, Any] = Field(default_factory=dict)
    external_dsp: ExternalDspSection | None = None
    fpga: dict[str, Any] = Field(default_factory=dict)
    devices: dict[str, Any] = Field(default_factory=dict)
    ports: list[dict[str, Any]] = Field(default_factory=list)
    events: dict[str, int] = Field(default_factory=dict, description="event counts by name")
    psns: PsnsSection | None = Field(None, description="the solved solar vectors against truth (null: the firmware "
                                                       "solved none, or the run has no polarization sensor)")
    faults: list[FaultRecord] = Field(default_factory=list)
    valid: bool = Field(True, description="false when a scheduled fault never took effect")
    expectations: list[ExpectationRecord] = Field(default_factory=list)
    passed: bool = False
    non_finite: list[str] = Field(default_factory=list, description="paths of values that were NaN or infinite, "
                                                                    "written as null")


def load_summary(path: str | Path) -> RunSummary:
    """Read and validate a ``summary.json`` (a run directory is accepted too)."""
    p = Path(path)
    if p.is_dir():
        p = p / "summary.json"
    try:
        data = json.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise RecordingError(f"{p.parent}: not a run directory (no summary.json)") from None
    except (OSError, ValueError) as exc:
        raise RecordingError(f"{p}: cannot read the run summary: {exc}") from None
    try:
        return RunSummary.model_validate(data)
    except ValidationError as exc:
        first = exc.errors(include_url=False)[0]
        where = ".".join(str(x) for x in first["loc"])
        raise RecordingError(f"{p}: not a psns-hil run summary ({where}: {first['msg']})") from None


def summary_json_schema() -> str:
    """The JSON Schema of ``summary.json`` (``docs/summary.schema.json``)."""
    schema = RunSummary.model_json_schema()
    schema["$schema"] = "https://json-schema.org/draft/2020-12/schema"
    schema["title"] = "psns-hil run summary (summary.json)"
    return json.dumps(schema, indent=2, sort_keys=True) + "\n"
