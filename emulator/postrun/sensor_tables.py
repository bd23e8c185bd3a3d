"""Raw sensor tables: the IMU, GNSS and PSNS streams of a capture, decoded, one row per frame, units in the names.

The rows come from the capture (``capture.psnscap``: the recorder's taps on the links, so nothing here reaches into
a device), decoded with the protocols' stream decoders (:func:`emulator.assembly.ports.port_formats`, the formats
the recorder counts with):

``imu.csv``
    One row per FPGA IMU frame the DSP received on UART1 (one per STIM210 datagram, with the accelerometer ADC
    words of the same trigger; ``protocols.imu_frame``): the gyro words scaled by the STIM's LSB (deg/s for the
    rate output, deg for the incremental-angle output), the specific force by the ADC's nominal scale (g).
``gnss.csv``
    One row per GNSS epoch on the GNSS port: a GGA or GNS sentence (``protocols.nmea``) or a UBX-NAV-PVT
    (``protocols.ubx``), whichever the receiver sends.
``psns_frames.csv``
    One row per frame on the PSNS port (``protocols.psns``): POLARIZATION_OBS, compass and solar-vector frames, with
    the header and, for a solar-vector frame, the vector and its quality.

``t_rx_s`` is the scenario time (s) of the capture chunk that completed the frame. A table whose stream is absent
from the capture (a replay run, a scenario without that sensor) is not written.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from protocols.imu_frame import ImuFrame, accel_code_to_g
from protocols.nmea import Gga, Gns
from protocols.psns import CompassFrame, PolarizationObs, PolarizationObsPacked, SolarVectorFrame
from protocols.stim import GYRO_ANGLE_LSB_DEG, GYRO_RATE_LSB_DPS
from protocols.stream import StreamDecoder
from protocols.ubx import NavPvt

from ..recording.capture import CaptureRecord, iter_capture
from ..recording.formatting import csv_row
from ..recording.rundir import open_no_follow

__all__ = ["GNSS_COLUMNS", "PSNS_FRAME_COLUMNS", "SENSOR_TABLES", "SensorDecoder", "SensorFrame",
           "decode_sensor_frames", "imu_columns", "write_sensor_tables"]

#: the tables: file name -> (capture link, direction) whose frames it holds
SENSOR_TABLES = {"imu.csv": ("uart1", "in"), "gnss.csv": ("gnss", "in"), "psns_frames.csv": ("psns", "in")}

GNSS_COLUMNS = ["t_rx_s", "message", "time_utc", "lat_deg", "lon_deg", "height_msl_m", "fix_quality", "num_sats",
                "hdop", "h_acc_m", "v_acc_m", "vel_e_mps", "vel_n_mps", "vel_u_mps"]
PSNS_FRAME_COLUMNS = ["t_rx_s", "frame", "seq", "exposure_us", "latency_us", "status", "count", "n_points",
                      "s_x", "s_y", "s_z", "quality"]


def imu_columns(gyro_rate: bool) -> list[str]:
    """The ``imu.csv`` columns: the gyro in deg/s (``gyro_rate``) or as incremental angles in deg."""
    g = "dps" if gyro_rate else "deg"
    return ["t_rx_s", "seq", "t_trigger_us", "t_pps_us", "pps_count", f"gyro_x_{g}", f"gyro_y_{g}", f"gyro_z_{g}",
            "gyro_status", "gyro_counter", "gyro_latency_us", "accel_x_g", "accel_y_g", "accel_z_g", "fpga_status"]


@dataclass
class SensorFrame:
    """One decoded frame of a sensor stream: the table it belongs to, its receive time (s) and its row cells."""

    table: str
    t_rx_s: float
    row: dict[str, Any] = field(default_factory=dict)
    #: the decoded frame object (``protocols``)
    frame: Any = None


def _formats(link: str) -> list[Any]:
    from ..assembly.ports import port_formats  # the recorder's formats for that link (one declaration)

    return port_formats(link).get("in", [])


def _imu_row(t: float, f: ImuFrame, gyro_rate: bool) -> dict[str, Any]:
    lsb = GYRO_RATE_LSB_DPS if gyro_rate else GYRO_ANGLE_LSB_DEG
    cols = imu_columns(gyro_rate)
    vals = (t, f.seq, f.t_trigger_us, f.t_pps_us, f.pps_count, f.gyro[0] * lsb, f.gyro[1] * lsb, f.gyro[2] * lsb,
            f.gyro_status, f.gyro_counter, f.gyro_latency_us, accel_code_to_g(f.accel[0], 0),
            accel_code_to_g(f.accel[1], 1), accel_code_to_g(f.accel[2], 2), f.fpga_status)
    return dict(zip(cols, vals, strict=True))


def _gnss_row(t: float, f: Any) -> dict[str, Any] | None:
    if isinstance(f, Gga | Gns):
        return {"t_rx_s": t, "message": type(f).__name__.upper(),
                "time_utc": f.time_utc.isoformat() if f.time_utc is not None else "",
                "lat_deg": f.lat_deg, "lon_deg": f.lon_deg, "height_msl_m": f.altitude_msl_m,
                "fix_quality": f.quality if isinstance(f, Gga) else f.mode, "num_sats": f.num_sats, "hdop": f.hdop}
    if isinstance(f, NavPvt):
        return {"t_rx_s": t, "message": "NAV-PVT",
                "time_utc": f"{f.hour:02d}:{f.min:02d}:{f.sec:02d}",
                "lat_deg": f.lat * 1e-7, "lon_deg": f.lon * 1e-7, "height_msl_m": f.hMSL * 1e-3,
                "fix_quality": f.fixType, "num_sats": f.numSV, "h_acc_m": f.hAcc * 1e-3, "v_acc_m": f.vAcc * 1e-3,
                "vel_e_mps": f.velE * 1e-3, "vel_n_mps": f.velN * 1e-3, "vel_u_mps": -f.velD * 1e-3}
    return None


def _psns_row(t: float, f: Any) -> dict[str, Any] | None:
    kinds = {PolarizationObs: "POLARIZATION_OBS", PolarizationObsPacked: "POLARIZATION_OBS",
             CompassFrame: "COMPASS", SolarVectorFrame: "SOLAR_VECTOR"}
    kind = kinds.get(type(f))
    if kind is None:
        return None
    h = f.header
    row: dict[str, Any] = {"t_rx_s": t, "frame": kind, "seq": h.seq, "exposure_us": h.exposure_us,
                           "latency_us": h.latency_us, "status": h.status, "count": h.count}
    if isinstance(f, PolarizationObs | PolarizationObsPacked):
        row["n_points"] = f.n_points
    elif isinstance(f, CompassFrame):
        row["n_points"] = len(f.units)
    else:
        row.update(s_x=f.s[0], s_y=f.s[1], s_z=f.s[2], quality=f.quality)
    return row


class SensorDecoder:
    """The sensor streams of a capture, decoded record by record (:meth:`feed`) as :data:`SENSOR_TABLES` says: for
    a whole capture (:func:`decode_sensor_frames`) or one that is still being written (the live view)."""

    def __init__(self, gyro_rate: bool = True) -> None:
        self.gyro_rate = gyro_rate
        self._decoders: dict[str, StreamDecoder] = {}
        for table, (link, _d) in SENSOR_TABLES.items():
            fm = _formats(link)
            if fm:
                self._decoders[table] = StreamDecoder(fm)
        self._by_link = {(link, d): table for table, (link, d) in SENSOR_TABLES.items() if table in self._decoders}

    def feed(self, r: CaptureRecord) -> list[SensorFrame]:
        """The frames capture record ``r`` completes (none for a link that is not a sensor stream)."""
        table = self._by_link.get((r.link, r.direction))
        if table is None:
            return []
        out: list[SensorFrame] = []
        for fr in self._decoders[table].feed(r.data):
            row: dict[str, Any] | None
            if table == "imu.csv":
                row = _imu_row(r.t_s, fr, self.gyro_rate) if isinstance(fr, ImuFrame) else None
            elif table == "gnss.csv":
                row = _gnss_row(r.t_s, fr)
            else:
                row = _psns_row(r.t_s, fr)
            if row is not None:
                out.append(SensorFrame(table, r.t_s, row, fr))
        return out


def decode_sensor_frames(records: Iterable[CaptureRecord], gyro_rate: bool = True) -> Iterator[SensorFrame]:
    """The sensor frames of ``records`` (capture order), decoded as :data:`SENSOR_TABLES` says."""
    dec = SensorDecoder(gyro_rate)
    for r in records:
        yield from dec.feed(r)


def gyro_is_rate(header: dict[str, Any]) -> bool:
    """Whether the capture's IMU sends angular rates (else incremental angles), from its scenario."""
    spec = header.get("scenario_spec") or {}
    imu = (spec.get("sensors") or {}).get("imu") or {}
    return str(imu.get("output", "rate")) == "rate"


def write_sensor_tables(run_dir: Path, capture: Path | None = None) -> dict[str, int]:
    """Write :data:`SENSOR_TABLES` into ``run_dir`` from its capture; returns the rows written per table."""
    run_dir = Path(run_dir)
    header, records = iter_capture(capture if capture is not None else run_dir / "capture.psnscap")
    rate = gyro_is_rate(header)
    cols = {"imu.csv": imu_columns(rate), "gnss.csv": GNSS_COLUMNS, "psns_frames.csv": PSNS_FRAME_COLUMNS}
    files: dict[str, Any] = {}
    counts: dict[str, int] = {}
    try:
        for fr in decode_sensor_frames(records, rate):
            f = files.get(fr.table)
            if f is None:
                f = files[fr.table] = open_no_follow(run_dir / fr.table, newline="")
                f.write(",".join(cols[fr.table]) + "\r\n")
            f.write(csv_row(["" if fr.row.get(c) is None else fr.row[c] for c in cols[fr.table]]))
            counts[fr.table] = counts.get(fr.table, 0) + 1
    finally:
        for f in files.values():
            f.close()
    return counts
