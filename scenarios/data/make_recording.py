"""Generate the committed recording of ``scenarios/recorded_replay.yaml`` (deterministic, seed 2019).

    .venv/bin/python scenarios/data/make_recording.py

writes ``scenarios/data/drive_imu.csv`` (gyro in deg/s and specific force in m/s^2, body axes,
100 Hz: each row the interval mean of the emulator's paper-preset STIM210 / accelerometer error
models over the trajectory of the scenario) and ``scenarios/data/drive_gnss.nmea`` (GGA + RMC at
1 Hz from the paper-preset receiver model). Re-running it reproduces the files byte for byte
(``tests/emulator/postrun/test_golden.py::test_the_committed_recording_is_what_its_generator_makes``).
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]
SEED = 2019
RATE_HZ = 100.0


def make(out_dir: Path = HERE) -> tuple[Path, Path]:
    sys.path.insert(0, str(ROOT))
    from emulator.devices.gnss import GnssConfig, GnssReceiver
    from emulator.devices.imu import AccelErrors, GyroErrors, accel_error_model, gyro_error_model
    from emulator.scenario import load_scenario
    from emulator.world.build import build_trajectory

    scn = load_scenario(ROOT / "scenarios" / "recorded_replay.yaml")
    traj = build_trajectory(scn)
    rng = np.random.default_rng(SEED)
    gyro = gyro_error_model(GyroErrors(), rng)
    accel = accel_error_model(AccelErrors(), rng)
    dt = 1.0 / RATE_HZ
    n = round(scn.duration_s * RATE_HZ)
    lines = ["# psns-hil recording (synthetic): scenarios/data/make_recording.py, seed 2019; body axes x right, "
             "y forward, z up; interval means over 10 ms",
             "time_s,gyro_x_dps,gyro_y_dps,gyro_z_dps,accel_x_mps2,accel_y_mps2,accel_z_mps2"]
    for k in range(-2, n + 1):  # from -20 ms, so that the first trigger interval [-5 ms, 0] is covered
        t = k * dt
        t0, t1 = max(0.0, t - 0.5 * dt), min(scn.duration_s, t + 0.5 * dt)
        if t1 <= t0:  # before the start: the vehicle stands as at t = 0
            t0, t1 = 0.0, dt
        dth, dv = traj.imu_increments(t0, t1)
        w = gyro.measure(dth / (t1 - t0), t1 - t0, f_b=dv / (t1 - t0))
        f = accel.measure(dv / (t1 - t0), t1 - t0)
        wd = w * (180.0 / math.pi)
        lines.append(f"{t + 0.0:.2f},{wd[0]:.6f},{wd[1]:.6f},{wd[2]:.6f},{f[0]:.6f},{f[1]:.6f},{f[2]:.6f}")
    imu_path = out_dir / "drive_imu.csv"
    imu_path.write_text("\n".join(lines) + "\n", encoding="ascii")

    rx = GnssReceiver(None, traj, scn.epoch, np.random.default_rng(SEED + 1), GnssConfig())  # type: ignore[arg-type]
    out = bytearray()
    for k in range(int(scn.duration_s)):
        out += rx.sentences(float(k), True)
    gnss_path = out_dir / "drive_gnss.nmea"
    gnss_path.write_bytes(bytes(out).replace(b"\r\n", b"\n"))
    return imu_path, gnss_path


if __name__ == "__main__":
    for p in make():
        print(f"wrote {p} ({p.stat().st_size} bytes)")
