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

The models live in :mod:`.faults_schema` and :mod:`.expectations_schema`; this module gathers them.
"""

from __future__ import annotations

from .expectations_schema import (
    EXPECTATION_KINDS,
    LINK_COUNTERS,
    NAV_MODE_FLAGS,
    DspBound,
    EventExpectation,
    Expectation,
    FieldRange,
    HookError,
    LinkCounterBound,
    NavErrorBound,
    NavGapExpectation,
    NavModeExpectation,
    NavRateExpectation,
    PsnsErrorBound,
    PythonHook,
    SummaryValueBound,
    TimeWindow,
    check_hook_path,
    load_hook,
)
from .faults_schema import (
    DEFAULT_DIRECTION,
    FAULT_KINDS,
    DspExtraLoadFault,
    Fault,
    FaultWindow,
    FpgaChannelStallFault,
    GnssDegradedFault,
    GnssGlitchFault,
    GnssOutageFault,
    ImuBiasStepFault,
    ImuDroppedDatagramsFault,
    ImuSaturationFault,
    ImuStuckAxisFault,
    LinkBaudMismatchFault,
    LinkBitErrorsFault,
    LinkByteDropsFault,
    LinkDisconnectFault,
    LinkNoiseBurstFault,
    LinkStallFault,
    PsnsCloudCoverFault,
    PsnsInstallationErrorFault,
    PsnsSunOccludedFault,
    PsnsUnitBlockedFault,
)

__all__ = [
    "DEFAULT_DIRECTION", "EXPECTATION_KINDS", "FAULT_KINDS", "LINK_COUNTERS", "NAV_MODE_FLAGS",
    "DspBound", "DspExtraLoadFault", "EventExpectation", "Expectation", "Fault", "FaultWindow", "FieldRange",
    "FpgaChannelStallFault", "GnssDegradedFault", "GnssGlitchFault", "GnssOutageFault", "HookError",
    "ImuBiasStepFault", "ImuDroppedDatagramsFault", "ImuSaturationFault", "ImuStuckAxisFault",
    "LinkBaudMismatchFault", "LinkBitErrorsFault", "LinkByteDropsFault", "LinkCounterBound", "LinkDisconnectFault",
    "LinkNoiseBurstFault", "LinkStallFault", "NavErrorBound", "NavGapExpectation", "NavModeExpectation",
    "NavRateExpectation", "PsnsCloudCoverFault",
    "PsnsErrorBound", "PsnsInstallationErrorFault", "PsnsSunOccludedFault", "PsnsUnitBlockedFault", "PythonHook",
    "SummaryValueBound", "TimeWindow", "check_hook_path", "load_hook",
]
