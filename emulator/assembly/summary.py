"""What a run reports: the 1 Hz samples (``timeline.csv``, ``filter_state.csv``) and ``summary.json``."""

from __future__ import annotations

import math
from typing import Any

from firmware_model.c674x import COST_MODEL_VERSION

from ..dsp.host import VirtualDsp
from ..recording.recorder import Recorder

__all__ = ["SAMPLE_OFFSET_S", "dsp_sections", "fpga_section", "take_sample"]

#: 1 Hz samples (timeline.csv, filter_state.csv) are taken this long after each whole second, half an IMU
#: period, so that no tick of the 200 Hz executive coincides with them (a sample never depends on the
#: order of callbacks scheduled for the same instant).
SAMPLE_OFFSET_S = 0.0025


def take_sample(rec: Recorder, dsp: Any, t: float, final: bool = False) -> None:
    """One row of ``timeline.csv`` (link counters, DSP load in the second before ``t``) and, except for
    the ``final`` row at the end of the run, of ``filter_state.csv`` (the filter's state)."""
    local = isinstance(dsp, VirtualDsp)  # a split run's DSP lives in another process
    row: dict[str, Any] = {"time_s": t, "nav_frames": rec.nav_count}
    b = math.ceil(t - 1e-9) - 1  # the second [b, b + 1) that ends at or contains t
    span = min(1.0, t - b)
    if local:
        row["cpu_load_pct"] = 100.0 * dsp.busy_per_second.get(b, 0.0) / span if span > 0 else 0.0
    row["deadline_misses"] = dsp.deadline_misses
    row["watchdog_trips"] = dsp.watchdog_trips
    for name, v in rec.link_summary().items():
        for k in ("frames", "crc_errors", "dropped", "garbage_bytes", "framing_errors"):
            row[f"{name}_{k}"] = v[k]
    rec.table_row("timeline", row)
    if final or not local:
        return
    snap = dsp.fw.snapshot()  # the firmware interface (firmware_model.registry.FirmwareProtocol)
    st: dict[str, Any] = {"time_s": t, "state": snap.state, "mode": snap.mode}
    if snap.covariance_diag is not None:
        for i, v in enumerate(snap.covariance_diag):
            st[f"p{i}"] = v
    for name, bias in (("gyro_bias", snap.gyro_bias_rad_s), ("accel_bias", snap.accel_bias_mps2)):
        if bias is not None:
            for ax, v in zip("xyz", bias):
                st[f"{name}_{ax}"] = v
    rec.table_row("filter_state", st)


def dsp_sections(dsp: VirtualDsp) -> dict[str, Any]:
    """The ``dsp`` and ``firmware`` sections of the summary."""
    snap = dsp.fw.snapshot()
    budget = snap.tick_budget_cycles
    return {
        "dsp": {
            "clock_hz": dsp.clock_hz,
            "cpu_load_pct_max": dsp.cpu_load_pct_max(),
            "tick_utilization_max_pct": 100.0 * dsp.max_tick_cycles / budget if budget else None,
            "tick_budget_cycles": budget,
            "deadline_misses": dsp.deadline_misses,
            "over_budget_ticks": dsp.over_budget_ticks,
            "ticks": dsp.ticks,
            "cost_model": COST_MODEL_VERSION,
            "tasks": snap.cycles if snap.cycles is not None else [],
            **dsp.counters(),
        },
        "firmware": {"filter": snap.filter, "precision": snap.precision, "spec_sheet": snap.spec_sheet,
                     "counters": dict(snap.counters), "decoders": snap.decoders,
                     # NIS sums per measurement type (consistency check, emulator/distributed/campaign/consistency.py)
                     "innovation": {k: dict(v) for k, v in snap.innovation.items()}},
    }


def fpga_section(fpga: Any) -> dict[str, Any]:
    """The ``fpga`` section of the summary."""
    return {"imu_frames": fpga.imu_frames, "gyro_missing": fpga.gyro_missing, "mag_frames": fpga.mag_frames,
            "routes": fpga.routes, "monitor_records": fpga.monitor_records}

