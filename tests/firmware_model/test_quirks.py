"""Every stream of the quirks corpus (tests/firmware_model/quirks.py) through the firmware, outcome asserted."""

from __future__ import annotations

import datetime as dt
import heapq

import pytest

from firmware_model import Firmware, FirmwareConfig

from .quirks import CORPUS, Quirk
from .synth import SensorErrors, StaticTruth, StreamConfig, static_stream

DURATION_S = 10.0
BAUD = 38400


def run_quirk(q: Quirk) -> tuple[Firmware, dict[str, int], int]:
    truth = StaticTruth()
    fw = Firmware(FirmwareConfig(gnss_baud=BAUD, gnss_latency_s=0.05, align_time_s=2.0))
    chunks = []
    epochs = 0
    for k in range(1, int(DURATION_S)):
        data = q.epoch(truth.epoch + dt.timedelta(seconds=k), truth.lat_deg, truth.lon_deg, truth.height_m)
        chunks.append((k + 0.05 + len(data) * 10 / BAUD, 3, data))
        epochs += 1
    imu = list(static_stream(truth, SensorErrors(), StreamConfig(gnss=False, psns=None), DURATION_S))
    for t_rx, uart, data in heapq.merge(imu, chunks, key=lambda x: x[0]):
        fw.receive(uart, data, t_rx)
        if uart == 1:
            fw.service()
    dec = fw.decoder_stats()["uart3"]
    got = {**fw.counters, **{k: v for k, v in dec.items() if isinstance(v, int)}}
    return fw, got, epochs


@pytest.mark.parametrize("q", CORPUS, ids=[q.name for q in CORPUS])
def test_quirk(q: Quirk) -> None:
    _fw, got, epochs = run_quirk(q)
    assert q.source
    for key, (op, per_epoch) in q.expect.items():
        want = per_epoch * epochs if key not in ("crc_errors", "length_errors", "parse_errors") else per_epoch
        if op == "==":
            assert got[key] == want, (key, got[key], want)
        else:
            assert got[key] >= want, (key, got[key], want)
    assert got["input_faults"] == 0
