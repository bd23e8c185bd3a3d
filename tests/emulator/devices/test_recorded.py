"""Recorded-data injection: IMU/GNSS CSV, NMEA logs, image files; errors name file, line and column."""

from __future__ import annotations

import asyncio
import datetime as dt

import numpy as np
import pytest

from emulator.clock import EmulatorLoop
from emulator.devices.camera import CameraConfig, PolarizationCameraModel
from emulator.devices.gnss import GnssConfig
from emulator.devices.recorded import RecordedImages, RecordedImu, RecordedNmea, read_mosaic, recorded_gnss
from emulator.errors import RecordingError
from emulator.links import LineConfig, MemHub
from emulator.world.sky import SkyModel
from emulator.world.sun import SunModel
from emulator.world.trajectory import StaticTrajectory
from protocols.constants import DEG
from protocols.nmea import Gga, NmeaFormat, build_gga, build_rmc
from protocols.stream import StreamDecoder

EPOCH = dt.datetime(2019, 9, 18, 8, 14, tzinfo=dt.UTC)


def write_imu(path, t, w_dps, f):
    lines = ["# a test record", "time_s,gyro_x_dps,gyro_y_dps,gyro_z_dps,accel_x_mps2,accel_y_mps2,accel_z_mps2,temp_c"]
    for ti, wi, fi in zip(t, w_dps, f):
        lines.append(",".join(f"{v:.12g}" for v in (ti, *wi, *fi, 25.0)))
    path.write_text("\n".join(lines) + "\n")


def test_imu_csv_mean_over_intervals_is_the_exact_integral(tmp_path):
    t = np.arange(0, 2.0001, 0.01)
    w = np.stack([np.sin(t), 2 * t, np.full_like(t, 0.5)], axis=1)  # deg/s
    f = np.stack([np.zeros_like(t), t, np.full_like(t, 9.8)], axis=1)
    p = tmp_path / "imu.csv"
    write_imu(p, t, w, f)
    rec = RecordedImu(p, time_offset_s=0.5)
    # a linear column integrates exactly: mean of 2 (t - 0.5) over [1.0, 1.005]
    m = rec.mean_rate(1.0, 1.005) / DEG
    assert m[1] == pytest.approx(2 * (1.0025 - 0.5), abs=1e-12) and m[2] == pytest.approx(0.5)
    assert rec.mean_specific_force(1.0, 1.005)[1] == pytest.approx(1.0025 - 0.5, abs=1e-12)
    assert rec.mean_rate(2.4, 2.6) is None  # beyond the record: the gyro stays silent
    assert rec.mean_specific_force(3.0, 3.005)[2] == pytest.approx(9.8)


def test_recorded_imu_drives_the_gyro_words(tmp_path):
    from emulator.devices.imu import ImuTruthTap, Stim210Gyro
    from protocols.stim import GYRO_RATE_LSB_DPS, Stim210Format

    t = np.arange(0, 1.0001, 0.005)
    w = np.tile([1.0, -2.0, 3.0], (len(t), 1))
    p = tmp_path / "imu.csv"
    write_imu(p, t, w, np.tile([0, 0, 9.8], (len(t), 1)))
    rec = RecordedImu(p)
    loop = EmulatorLoop("fast")
    a, b = MemHub().pair("gyro", LineConfig(baud=460800), loop)
    gyro = Stim210Gyro(a, ImuTruthTap(StaticTrajectory(0, 0, 0)), np.random.default_rng(1), source=rec.mean_rate)
    dec = StreamDecoder([Stim210Format("m")])
    got = []
    b.on_receive = lambda d: got.extend(dec.feed(d))

    async def main():
        for k in range(1, 6):
            gyro.trigger(k * 0.005, (k - 1) * 0.005)
        await asyncio.sleep(0.05)

    loop.run_until_complete(main())
    loop.close()
    assert [d.gyro for d in got] == [tuple(round(v / GYRO_RATE_LSB_DPS) for v in (1.0, -2.0, 3.0))] * 5


@pytest.mark.parametrize("text, where", [
    ("time_s,gyro_x_dps\n0,1\n", "line 1, column 1: missing column"),
    ("time_s,gyro_x_dps,gyro_y_dps,gyro_z_dps,accel_x_mps2,accel_y_mps2,accel_z_mps2\n0,0,0,0,0,0,9.8\n"
     "0.005,0,abc,0,0,0,9.8\n", "line 3, column 9: gyro_y_dps (3 characters) is not a number"),
    ("# c\ntime_s,gyro_x_dps,gyro_y_dps,gyro_z_dps,accel_x_mps2,accel_y_mps2,accel_z_mps2\n0,0,0,0,0,0,9.8\n"
     "0.005,0,0\n", "line 4, column 10"),
])
def test_bad_imu_files_name_file_line_and_column(tmp_path, text, where):
    p = tmp_path / "bad.csv"
    p.write_text(text)
    with pytest.raises(RecordingError) as ei:
        RecordedImu(p)
    assert str(p) in str(ei.value) and where in str(ei.value)


def nmea_log(tmp_path, n=5, corrupt_line=None):
    out = []
    for k in range(n):
        utc = EPOCH + dt.timedelta(seconds=k)
        out.append(build_gga(utc.time(), 39.979 + k * 1e-5, 116.339, 50.0, 0.0).decode().strip())
        out.append(build_rmc(utc.time(), utc.date(), 39.979 + k * 1e-5, 116.339, 1.0, 0.0).decode().strip())
    if corrupt_line is not None:
        out[corrupt_line] = out[corrupt_line][:-2] + "00"
    p = tmp_path / "gnss.nmea"
    p.write_text("\n".join(out) + "\n")
    return p


def test_nmea_log_replays_epochs_with_pps(tmp_path):
    p = nmea_log(tmp_path)
    loop = EmulatorLoop("fast")
    a, b = MemHub().pair("gnss", LineConfig(baud=9600), loop)
    pps = []
    dev = recorded_gnss(a, p, "nmea", EPOCH, GnssConfig(), 0.0, pps.append, np.random.default_rng(1))
    dec = StreamDecoder([NmeaFormat()])
    got = []
    b.on_receive = lambda d: got.extend((loop.time(), s) for s in dec.feed(d))

    async def main():
        dev.start()
        await asyncio.sleep(6.0)

    loop.run_until_complete(main())
    loop.close()
    assert pps == [0.0, 1.0, 2.0, 3.0, 4.0]
    ggas = [(t, s) for t, s in got if isinstance(s, Gga)]
    assert len(ggas) == 5 and ggas[2][1].lat_deg == pytest.approx(39.979 + 2e-5, abs=1e-7)
    assert all(int(t) == k for k, (t, _) in enumerate(ggas))


def test_bad_nmea_log_names_line_and_column(tmp_path):
    p = nmea_log(tmp_path, corrupt_line=3)
    with pytest.raises(RecordingError, match=r"gnss\.nmea: line 4, column \d+: NMEA checksum mismatch"):
        RecordedNmea(p, EPOCH)


def test_gnss_csv_replay(tmp_path):
    p = tmp_path / "fix.csv"
    p.write_text("time_s,lat_deg,lon_deg,height_m,vel_e_mps,vel_n_mps,vel_u_mps,fix_quality\n"
                 "0,39.979,116.339,50,0,1,0,1\n1,39.97901,116.339,50,0,1,0,2\n")
    loop = EmulatorLoop("fast")
    a, b = MemHub().pair("gnss", LineConfig(baud=9600), loop)
    pps = []
    dev = recorded_gnss(a, p, "csv", EPOCH, GnssConfig(), 0.0, pps.append, np.random.default_rng(1))
    dec = StreamDecoder([NmeaFormat()])
    got = []
    b.on_receive = lambda d: got.extend(s for s in dec.feed(d) if isinstance(s, Gga))

    async def main():
        dev.start()
        await asyncio.sleep(3.5)

    loop.run_until_complete(main())
    loop.close()
    assert [g.quality for g in got] == [1, 2, 0, 0]
    assert len(pps) == 2


def test_images_png_tiff_npz_replace_the_rendering(tmp_path):
    from PIL import Image

    traj = StaticTrajectory(39.979, 116.339, 50.0, 30.0)
    m = PolarizationCameraModel(CameraConfig(fidelity="full", noise=False), SkyModel(), SunModel(EPOCH, 69.0), traj,
                                np.random.default_rng(1))
    mosaic = m.render_mosaic(0.0).copy()
    Image.fromarray(mosaic).save(tmp_path / "f0.png")
    Image.fromarray(mosaic).save(tmp_path / "f1.tif")
    planes = {f"I{th}": mosaic[r::2, c::2] for th, (r, c) in {0: (1, 1), 45: (0, 1), 90: (0, 0), 135: (1, 0)}.items()}
    np.savez(tmp_path / "f2.npz", **planes)
    for name in ("f0.png", "f1.tif", "f2.npz"):
        assert np.array_equal(read_mosaic(tmp_path / name, mosaic.shape), mosaic)
    (tmp_path / "index.csv").write_text("time_s,file\n0.0005,f0.png\n0.2005,f1.tif\n0.4005,f2.npz\n")
    src = RecordedImages(index=tmp_path / "index.csv")
    ref = m.observe(0.0)
    obs = m.observe(0.2005, src.mosaic_at(0.2005))
    assert np.allclose(obs.aop, ref.aop) and np.allclose(obs.dop, ref.dop)
    assert src.mosaic_at(5.0) is None
    np.savez(tmp_path / "bad.npz", I0=np.zeros((3, 3)), I45=0, I90=0, I135=0)
    with pytest.raises(RecordingError, match=r"bad\.npz: line 1, column 1: I\d+ has shape"):
        read_mosaic(tmp_path / "bad.npz", mosaic.shape)
    (tmp_path / "index2.csv").write_text("time_s,file\nzero,f0.png\n")
    with pytest.raises(RecordingError, match=r"index2\.csv: line 2, column 1"):
        RecordedImages(index=tmp_path / "index2.csv")


# -- non-physical values refused at load (issue 41 item 6; docs/hostile-input.md section 6) ------------------------

_IMU_HEAD = "time_s,gyro_x_dps,gyro_y_dps,gyro_z_dps,accel_x_mps2,accel_y_mps2,accel_z_mps2\n"


@pytest.mark.parametrize("row, where", [
    ("0.005,0,0,1e300,0,0,9.8", "line 3, column 11: gyro_z_dps is outside its physical range [-10000, 10000] deg/s"),
    ("0.005,-20000,0,0,0,0,9.8", "line 3, column 7: gyro_x_dps is outside its physical range"),
    ("0.005,0,0,0,0,3000,9.8", "line 3, column 15: accel_y_mps2 is outside its physical range [-2000, 2000] m/s^2"),
    ("1e12,0,0,0,0,0,9.8", "line 3, column 1: time_s is outside its physical range"),
])
def test_non_physical_imu_values_are_refused_at_load(tmp_path, row, where):
    """A recorded gyro of 1e300 deg/s was clipped to the STIM210's range and navigated (2.3 km off) before issue 41;
    now the file is refused, naming file, line, column and field (never the cell)."""
    p = tmp_path / "imu.csv"
    p.write_text(_IMU_HEAD + "0,0,0,0,0,0,9.8\n" + row + "\n")
    with pytest.raises(RecordingError) as ei:
        RecordedImu(p)
    msg = str(ei.value)
    assert msg.startswith(f"{p}: ") and where in msg and "1e300" not in msg


def test_the_largest_physical_imu_values_are_accepted(tmp_path):
    p = tmp_path / "imu.csv"
    p.write_text(_IMU_HEAD + "0,10000,-10000,0,2000,-2000,9.8\n0.005,0,0,0,0,0,9.8\n")
    assert RecordedImu(p).mean_rate(0.0, 0.005) is not None


@pytest.mark.parametrize("cols, row, where", [
    ("", "1,91,116.3,50,0,0,0", "line 3, column 3: lat_deg is outside its physical range [-90, 90] deg"),
    ("", "1,39.9,116.3,-1e6,0,0,0", "height_m is outside its physical range"),
    ("", "1,39.9,116.3,50,0,900,0", "vel_n_mps is outside its physical range"),
    (",fix_quality", "1,39.9,116.3,50,0,0,0,1.5", "fix_quality is not an integer"),
    (",hdop", "1,39.9,116.3,50,0,0,0,-1", "hdop is outside its physical range"),
])
def test_non_physical_gnss_csv_values_are_refused_at_load(tmp_path, cols, row, where):
    from emulator.devices.recorded import RecordedGnssCsv

    p = tmp_path / "gnss.csv"
    extra = ",1" if cols == ",fix_quality" else ",0.9" if cols == ",hdop" else ""
    p.write_text("time_s,lat_deg,lon_deg,height_m,vel_e_mps,vel_n_mps,vel_u_mps" + cols + "\n"
                 "0,39.9,116.3,50,0,0,0" + extra + "\n" + row + "\n")
    with pytest.raises(RecordingError) as ei:
        RecordedGnssCsv(p)
    assert str(p) in str(ei.value) and where in str(ei.value)


def test_non_physical_nmea_log_fields_are_refused_at_load(tmp_path):
    """A GGA of the log whose height is far below any surface (valid checksum) is refused naming its line."""
    out = [build_gga(EPOCH.time(), 39.979, 116.339, 50.0, 0.0).decode().strip(),
           build_gga((EPOCH + dt.timedelta(seconds=1)).time(), 39.979, 116.339, -5e4, 0.0).decode().strip()]
    p = tmp_path / "gnss.nmea"
    p.write_text("\n".join(out) + "\n")
    with pytest.raises(RecordingError, match=r"gnss\.nmea: line 2, column 1: GGA height is outside its physical "
                                             r"range \[-1000, 60000\] m"):
        RecordedNmea(p, EPOCH)


@pytest.mark.parametrize("value", [-5.0, 1e300, float("nan"), 70000.0])
def test_non_physical_npz_pixels_are_refused(tmp_path, value):
    """An NPZ plane with a negative, non-finite or beyond-16-bit value was clipped silently into the mosaic."""
    planes = {f"I{t}": np.full((4, 4), 100.0) for t in (0, 45, 90, 135)}
    planes["I90"][1, 2] = value
    p = tmp_path / "f.npz"
    np.savez(p, **planes)
    with pytest.raises(RecordingError, match=r"f\.npz: line 1, column 1: I90 holds"):
        read_mosaic(p, (8, 8))
