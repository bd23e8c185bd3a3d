"""Firmware model wall time: Firmware.service per 200 Hz tick, and the PSNS solve rate.

The stream is the firmware tests' synthetic static stream (IMU 200 Hz, GNSS 1 Hz, PSNS solar-vector frames
at 5 Hz), fed through Firmware.receive/service; the time of service() alone is measured, best of 3.
"""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from firmware_model import Firmware, FirmwareConfig, psns  # noqa: E402
from firmware_model.psns_geometry import CameraGeometry  # noqa: E402
from tests.firmware_model.sky import observe_sky  # noqa: E402
from tests.firmware_model.synth import SensorErrors, StaticTruth, StreamConfig, static_stream  # noqa: E402

ERR = SensorErrors(gyro_bias_dph=(5, -3, 4), gyro_arw_deg_rt_h=0.15, accel_bias_mg=(1, -1, 0.5),
                   accel_noise_ug_rt_hz=100, gnss_pos_sigma_m=3, gnss_vel_sigma_mps=0.03, psns_sigma_deg=0.03)


def _service_us_per_tick(psns_kind: str | None, seconds: float = 60.0) -> float:
    events = list(static_stream(StaticTruth(), ERR, StreamConfig(psns=psns_kind), seconds))
    best = math.inf
    for _ in range(3):
        fw = Firmware(FirmwareConfig(initial_heading_deg=30.5))
        n, ts = 0, 0.0
        for t, uart, data in events:
            fw.receive(uart, data, t)
            if uart == 1:
                t0 = time.perf_counter()
                n += len(fw.service())
                ts += time.perf_counter() - t0
        best = min(best, ts / n)
    return best * 1e6


def _solves_per_s(n_points_stride: int) -> tuple[float, int]:
    cam = CameraGeometry()
    s = np.array([-0.876416, -0.282797, 0.389770])
    obs = observe_sky(s / np.linalg.norm(s), cam, stride_px=n_points_stride)
    x, y = obs.x_px, obs.y_px
    aop = (obs.aop_deg * math.pi / 180).astype(np.float32)
    dop = obs.dop.astype(np.float32)
    reps = 200
    t0 = time.perf_counter()
    for _ in range(reps):
        psns.solve_solar_vector(psns.evectors_camera(x, y, aop, cam), dop)
    return reps / (time.perf_counter() - t0), len(x)


def run() -> list[dict]:
    rows = []
    for kind in ("solar_vector", "polarization_obs"):
        us = _service_us_per_tick(kind)
        rows.append({"name": f"Firmware.service per tick (static, GNSS, PSNS {kind})", "value": us, "unit": "us",
                     "baseline": 5000.0, "ratio": us / 5000.0, "note": "baseline: the 5 ms tick period"})
    for stride in (160, 16):
        rate, n = _solves_per_s(stride)
        rows.append({"name": f"PSNS solve, {n} points (E-vectors + K + eigen)", "value": rate, "unit": "solves/s",
                     "baseline": 5.0, "ratio": rate / 5.0, "note": "baseline: 5 Hz frame rate"})
    return rows
