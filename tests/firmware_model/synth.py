"""Synthetic sensor byte streams for firmware-level tests (no emulator involved).

A static truth (position, attitude, UTC epoch) is turned into the byte frames the DSP's UARTs would
receive: FPGA IMU frames on UART1 (``protocols.imu_frame``), NMEA GGA + RMC on UART3 after each PPS,
and PSNS frames on UART2 (``protocols.psns``: SOLAR_VECTOR from an on-sensor solve, or
POLARIZATION_OBS built from a Rayleigh sky). Events are yielded in reception order with their
reception time, so a test drives :class:`firmware_model.Firmware` exactly as the virtual DSP does.

Sensor errors are deliberately simple (constant biases, white noise) and seeded: these tests check
the firmware, not the sensor models.
"""

from __future__ import annotations

import datetime as dt
import heapq
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from firmware_model import earth, sun
from firmware_model.attitude import a2mat, yaw_from_heading
from firmware_model.psns_geometry import CameraGeometry
from protocols.constants import DEG, DPH, G_STD
from protocols.imu_frame import ACCEL_VOLTS_PER_G, ADC_VOLTS_PER_LSB, FpgaStatus, ImuFrame, ImuFrameFormat
from protocols.nmea import build_gga, build_rmc
from protocols.psns import PolarizationPoint, PsnsHeader, PsnsStatus, encode_polarization_obs, encode_solar_vector
from protocols.stim import GYRO_ANGLE_LSB_DEG, GYRO_RATE_LSB_DPS

from .sky import observe_sky

UART_HOST, UART_IMU, UART_PSNS, UART_GNSS = 0, 1, 2, 3


@dataclass
class StaticTruth:
    lat_deg: float = 39.979
    lon_deg: float = 116.339
    height_m: float = 50.0
    heading_deg: float = 30.0
    pitch_deg: float = 2.0
    roll_deg: float = -3.0
    epoch: dt.datetime = dt.datetime(2019, 9, 18, 8, 14, 0, tzinfo=dt.UTC)

    @property
    def cbn(self) -> np.ndarray:
        return a2mat(self.pitch_deg * DEG, self.roll_deg * DEG, yaw_from_heading(self.heading_deg * DEG))

    def sun_n(self, t: float) -> np.ndarray:
        td = sun.grena_days_from_datetime(self.epoch) + t / 86400.0
        return sun.sun_vector_enu(td, self.lat_deg * DEG, self.lon_deg * DEG, dtype=np.float64)


@dataclass
class SensorErrors:
    gyro_bias_dph: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gyro_arw_deg_rt_h: float = 0.0
    accel_bias_mg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    accel_noise_ug_rt_hz: float = 0.0
    gnss_pos_sigma_m: float = 0.0
    gnss_vel_sigma_mps: float = 0.0
    psns_sigma_deg: float = 0.0


@dataclass
class StreamConfig:
    imu_rate_hz: float = 200.0
    gyro_output: str = "rate"
    gnss: bool = True
    gnss_latency_s: float = 0.05
    gnss_baud: int = 9600
    gnss_outage_s: tuple[float, float] | None = None  # no sentences (and no PPS latch change) in [start, end)
    gnss_output: str = "nmea"  # "nmea" (GGA + RMC), "ubx" (NAV-PVT) or "both"
    gnss_vel_up_error_mps: float = 0.0  # a constant error on the GNSS vertical velocity (tests of the velD path)
    pps: bool = True  # False: the IMU frames never carry PPS_VALID (an external receiver without a PPS line)
    psns: str | None = "solar_vector"  # None, "solar_vector" or "polarization_obs"
    psns_rate_hz: float = 5.0
    psns_latency_us: int = 30000
    psns_baud: int = 115200
    psns_mounting: np.ndarray = field(default_factory=lambda: np.eye(3))  # C_c^b
    camera: CameraGeometry = field(default_factory=CameraGeometry)
    obs_stride_px: int = 160


def static_stream(truth: StaticTruth, err: SensorErrors, cfg: StreamConfig, duration_s: float,
                  seed: int = 1) -> Iterator[tuple[float, int, bytes]]:
    """Yield ``(t_rx_s, uart, bytes)`` in time order for ``duration_s`` of static operation."""
    rng = np.random.default_rng(seed)
    lat, h = truth.lat_deg * DEG, truth.height_m
    cbn = truth.cbn
    w_b = cbn.T @ earth.omega_ie_n(lat) + np.array(err.gyro_bias_dph) * DPH
    f_b = cbn.T @ np.array([0.0, 0.0, earth.gravity(lat, h)]) + np.array(err.accel_bias_mg) * 1e-3 * G_STD
    T = 1.0 / cfg.imu_rate_hz
    arw = err.gyro_arw_deg_rt_h * DEG / 60.0  # rad/sqrt(s)
    vrw = err.accel_noise_ug_rt_hz * 1e-6 * G_STD  # m/s^2/sqrt(Hz)
    fmt = ImuFrameFormat()
    heap: list[tuple[float, int, int, bytes]] = []
    order = 0

    def push(t: float, uart: int, data: bytes) -> None:
        nonlocal order
        heapq.heappush(heap, (t, order, uart, data))
        order += 1

    n_imu = round(duration_s * cfg.imu_rate_hz)
    next_gnss = 1
    next_psns = 1.0 / cfg.psns_rate_hz
    psns_seq = 0
    counter = 0
    for k in range(1, n_imu + 1):
        t = k * T
        # GNSS epochs up to this trigger
        while cfg.gnss and next_gnss <= t:
            out = cfg.gnss_outage_s is not None and cfg.gnss_outage_s[0] <= next_gnss < cfg.gnss_outage_s[1]
            if not out:
                push(next_gnss + cfg.gnss_latency_s, UART_GNSS, _gnss_epoch(truth, err, cfg, next_gnss, rng))
            next_gnss += 1
        while cfg.psns and next_psns <= t:
            frame = _psns_frame(truth, err, cfg, next_psns, psns_seq, rng)
            t_rx = next_psns + cfg.psns_latency_us * 1e-6 + len(frame) * 10 / cfg.psns_baud
            push(t_rx, UART_PSNS, frame)
            psns_seq += 1
            next_psns += 1.0 / cfg.psns_rate_hz
        w = w_b + rng.normal(0.0, arw / math.sqrt(T), 3) if arw > 0 else w_b
        f = f_b + rng.normal(0.0, vrw / math.sqrt(T), 3) if vrw > 0 else f_b
        if cfg.gyro_output == "rate":
            gyro = tuple(round(x / DEG / GYRO_RATE_LSB_DPS) for x in w)
        else:
            gyro = tuple(round(x * T / DEG / GYRO_ANGLE_LSB_DEG) for x in w)
        accel = tuple(round(fi / G_STD * vpg / ADC_VOLTS_PER_LSB) for fi, vpg in zip(f, ACCEL_VOLTS_PER_G))
        pps = math.floor(t + 1e-9)
        counter = (counter + 10) & 0xFF
        fr = ImuFrame(seq=k & 0xFFFF, t_trigger_us=round(t * 1e6) & 0xFFFFFFFF,
                      t_pps_us=(pps * 1_000_000) & 0xFFFFFFFF, pps_count=pps & 0xFF, gyro=gyro,
                      gyro_status=0, gyro_counter=counter, gyro_latency_us=500,
                      accel=accel, fpga_status=int(FpgaStatus.PPS_VALID) if pps >= 1 and cfg.pps else 0)
        push(t + 40 * 10 / 460800 + 0.0004, UART_IMU, fmt.build(fr))
        while heap and heap[0][0] <= t:
            tt, _, uart, data = heapq.heappop(heap)
            yield tt, uart, data
    while heap:
        tt, _, uart, data = heapq.heappop(heap)
        yield tt, uart, data


def _gnss_epoch(truth: StaticTruth, err: SensorErrors, cfg: StreamConfig, k: int, rng: np.random.Generator) -> bytes:
    out = b""
    if cfg.gnss_output in ("nmea", "both"):
        out += _nmea(truth, err, k, rng)
    if cfg.gnss_output in ("ubx", "both"):
        out += _nav_pvt(truth, err, cfg, k, rng)
    return out


def _nav_pvt(truth: StaticTruth, err: SensorErrors, cfg: StreamConfig, k: int, rng: np.random.Generator) -> bytes:
    from protocols.ubx import NavPvt, encode_nav_pvt

    utc = truth.epoch + dt.timedelta(seconds=k)
    rm, rn = earth.radii(truth.lat_deg * DEG)
    dn, de, du = rng.normal(0.0, err.gnss_pos_sigma_m, 3) if err.gnss_pos_sigma_m > 0 else (0.0, 0.0, 0.0)
    ve, vn, vu = rng.normal(0.0, err.gnss_vel_sigma_mps, 3) if err.gnss_vel_sigma_mps > 0 else (0.0, 0.0, 0.0)
    vu += cfg.gnss_vel_up_error_mps
    lat = truth.lat_deg + dn / (rm + truth.height_m) / DEG
    lon = truth.lon_deg + de / ((rn + truth.height_m) * math.cos(truth.lat_deg * DEG)) / DEG
    p = NavPvt(iTOW=(k * 1000) % 604800000, year=utc.year, month=utc.month, day=utc.day, hour=utc.hour,
               min=utc.minute, sec=utc.second, valid=0x07, tAcc=50, nano=0, fixType=3, flags=0x01, flags2=0xE0,
               numSV=12, lon=round(lon * 1e7), lat=round(lat * 1e7), height=round((truth.height_m + du) * 1e3),
               hMSL=round((truth.height_m + du - 10.0) * 1e3), hAcc=3000, vAcc=5000, velN=round(vn * 1e3),
               velE=round(ve * 1e3), velD=round(-vu * 1e3), gSpeed=round(math.hypot(ve, vn) * 1e3), headMot=0,
               sAcc=100, headAcc=1000000, pDOP=150, flags3=0, reserved0=0, headVeh=0, magDec=0, magAcc=0)
    return encode_nav_pvt(p)


def _nmea(truth: StaticTruth, err: SensorErrors, k: int, rng: np.random.Generator) -> bytes:
    utc = truth.epoch + dt.timedelta(seconds=k)
    rm, rn = earth.radii(truth.lat_deg * DEG)
    dn, de, du = rng.normal(0.0, err.gnss_pos_sigma_m, 3) if err.gnss_pos_sigma_m > 0 else (0.0, 0.0, 0.0)
    lat = truth.lat_deg + dn / (rm + truth.height_m) / DEG
    lon = truth.lon_deg + de / ((rn + truth.height_m) * math.cos(truth.lat_deg * DEG)) / DEG
    ve, vn = rng.normal(0.0, err.gnss_vel_sigma_mps, 2) if err.gnss_vel_sigma_mps > 0 else (0.0, 0.0)
    speed = math.hypot(ve, vn)
    course = math.degrees(math.atan2(ve, vn)) % 360.0
    return (build_gga(utc.time(), lat, lon, truth.height_m + du - 10.0, 10.0)
            + build_rmc(utc.time(), utc.date(), lat, lon, speed, course))


def _small_rotation(rng: np.random.Generator, sigma_rad: float) -> np.ndarray:
    from firmware_model.attitude import q2mat, rv2q

    return q2mat(rv2q(rng.normal(0.0, sigma_rad, 3)))


def _psns_frame(truth: StaticTruth, err: SensorErrors, cfg: StreamConfig, t_exp: float, seq: int,
                rng: np.random.Generator) -> bytes:
    s_n = truth.sun_n(t_exp)
    s_b = truth.cbn.T @ s_n
    s_c = cfg.psns_mounting.T @ s_b
    hdr = PsnsHeader(seq=seq, exposure_us=2000, latency_us=cfg.psns_latency_us, status=int(PsnsStatus.VALID), count=0)
    if cfg.psns == "solar_vector":
        if err.psns_sigma_deg > 0:
            s_c = _small_rotation(rng, err.psns_sigma_deg * DEG / math.sqrt(2.0)) @ s_c
        sign = 1.0 if rng.random() < 0.5 else -1.0  # the sensor cannot tell sun from anti-sun
        s = sign * s_c
        return encode_solar_vector(hdr, (float(s[0]), float(s[1]), float(s[2])), 0.01)
    obs = observe_sky(s_c, cfg.camera, stride_px=cfg.obs_stride_px, rng=rng if err.psns_sigma_deg > 0 else None)
    pts = [PolarizationPoint(int(x), int(y), round(a * 100), round(d * 65535), int(i))
           for x, y, a, d, i in zip(obs.x_px, obs.y_px, obs.aop_deg, obs.dop, obs.s0_dn)]
    return encode_polarization_obs(hdr, pts)


def gnss_updates_seen(fw: Any, pick: Callable[[Any], Any], gnss_chunks: list[tuple[float, int, bytes]] | None = None,
                      stream: StreamConfig | None = None, duration_s: float = 8.0) -> list[Any]:
    """Feed ``fw`` a static stream (IMU on UART1, serviced per frame; ``stream`` chooses what else it carries) merged
    with ``gnss_chunks`` ``(t_rx, uart, bytes)``, and return ``pick(measurement)`` for every GNSS update the filter
    made: what of a receiver's message reached the update."""
    seen: list[Any] = []
    update = fw.filter.update_gnss

    def spy(nav: Any, meas: Any, p_ins: Any, v_ins: Any) -> Any:
        seen.append(pick(meas))
        return update(nav, meas, p_ins, v_ins)

    fw.filter.update_gnss = spy
    cfg = stream if stream is not None else StreamConfig(gnss=False, psns=None, pps=False)
    imu = list(static_stream(StaticTruth(), SensorErrors(), cfg, duration_s))
    for t_rx, uart, data in heapq.merge(imu, gnss_chunks or [], key=lambda x: x[0]):
        fw.receive(uart, data, t_rx)
        if uart == 1:
            fw.service()
    return seen
