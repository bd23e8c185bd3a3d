"""Stale PSNS frames are counted (issue 41 item 8): a solar vector older than ``psns_max_age_s`` when its turn
comes is dropped, and ``psns_stale`` says how many (it was dropped silently before, seen only in psns.csv's
``use`` column)."""

from __future__ import annotations

from firmware_model import Firmware, FirmwareConfig

from .synth import SensorErrors, StaticTruth, StreamConfig, static_stream


def _run(latency_us: int) -> dict[str, int]:
    fw = Firmware(FirmwareConfig(fine_align_time_s=5.0, psns_enabled=True))
    for t_rx, uart, data in static_stream(StaticTruth(), SensorErrors(), StreamConfig(psns_latency_us=latency_us),
                                          20.0, seed=3):
        fw.receive(uart, data, t_rx)
        fw.service()
    return fw.counters


def test_stale_solar_vectors_are_counted_and_fresh_ones_are_not() -> None:
    fresh = _run(30_000)
    assert fresh["psns_stale"] == 0 and fresh["psns_updates"] > 50
    stale = _run(1_500_000)  # exposure 1.5 s before the frame: older than psns_max_age_s (1 s)
    assert stale["psns_updates"] == 0
    # every solved vector after the alignment (5 Hz) is stale: the first ~2 s of the 20 s are the alignment
    assert 80 <= stale["psns_stale"] <= stale["psns_solutions"]
