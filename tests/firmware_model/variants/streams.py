"""Synthetic byte streams for the variant tests: any trajectory, the sensors the variants need.

Truth comes from ``emulator.world`` (the manoeuvring trajectory model checked against the firmware's
strapdown to millimetres, and the NREL SPA sun through pvlib): independent of the firmware's Grena
ephemeris. The sensor models here are deliberately simple and seeded (constant biases, white noise,
Rayleigh sky), written for these tests and independent of the firmware's solve:

* IMU frames on UART1 (average-rate gyro words, accelerometer ADC words) from exact increments;
* MAG frames after every 2nd IMU frame (100 Hz), ``B^b = C_n^b B^n`` + white noise;
* GNSS as UBX NAV-PVT at PPS + 50 ms (position, 3-D velocity), with glitches (offsets) and outages;
* PSNS: ``solar_vector`` (on-sensor solve, noise per component), ``compass`` (single-direction units with
  the AOP convention, AOP noise ``sigma * dop_ref / DOP``, blocked units: DOP ~ 0, random AOP) or
  ``camera`` (POLARIZATION_OBS of a fisheye/pinhole camera: Rayleigh sky, unpolarized ground below the
  horizon, points near the sun saturated and dropped).

Events come out in reception order as ``(t_rx_s, uart, bytes)``, as the virtual DSP hands them over.
"""

from __future__ import annotations

import datetime as dt
import heapq
import math
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np

from emulator.world.build import trajectory_from_segments
from emulator.world.sun import SunModel
from emulator.world.trajectory import StaticTrajectory, Trajectory
from firmware_model import earth
from firmware_model.psns_geometry import CameraGeometry
from protocols.constants import DEG, DPH, G_STD
from protocols.imu_frame import (
    ACCEL_VOLTS_PER_G,
    ADC_VOLTS_PER_LSB,
    FpgaStatus,
    ImuFrame,
    ImuFrameFormat,
    MagFrame,
    encode_mag_frame,
)
from protocols.psns import (
    CompassUnit,
    PolarizationPoint,
    PsnsHeader,
    PsnsStatus,
    encode_compass,
    encode_polarization_obs,
    encode_solar_vector,
)
from protocols.stim import GYRO_RATE_LSB_DPS
from protocols.ubx import NavPvt, encode_nav_pvt

UART_HOST, UART_IMU, UART_PSNS, UART_GNSS = 0, 1, 2, 3
EPOCH = dt.datetime(2019, 9, 18, 8, 14, 0, tzinfo=dt.UTC)  # Zhang et al.'s Beijing test (16:14 local)
BEIJING = (39.979, 116.339, 50.0)


@dataclass
class ImuErrors:
    gyro_bias_dph: tuple[float, float, float] = (0.0, 0.0, 0.0)
    gyro_arw_deg_rt_h: float = 0.0
    accel_bias_ug: tuple[float, float, float] = (0.0, 0.0, 0.0)
    accel_noise_ug_rt_hz: float = 0.0


@dataclass
class GnssSpec:
    enabled: bool = True
    pos_sigma_m: float = 0.0
    vel_sigma_mps: float = 0.0
    #: (start_s, duration_s, (dE, dN, dU) m)
    glitches: tuple[tuple[float, float, tuple[float, float, float]], ...] = ()
    #: (start_s, end_s): no fix and no PPS
    outages: tuple[tuple[float, float], ...] = ()
    #: during outages the receiver still sends NAV-PVT with its clock's date/time, no fix (as u-blox receivers do)
    time_during_outage: bool = False


@dataclass
class CompassSpec:
    mountings: np.ndarray
    aop_sigma_deg: float = 0.1
    dop_ref: float = 0.5
    p_max: float = 0.7
    #: (units, start_s, end_s)
    blocked: tuple[tuple[tuple[int, ...], float, float], ...] = ()


@dataclass
class CameraSpec:
    cam: CameraGeometry
    stride_px: int = 96
    max_theta_deg: float = 85.0
    p_max: float = 0.7
    aop_sigma_deg: float = 0.5  # at DOP 0.5, growing as 0.5/DOP
    dop_sigma: float = 0.005
    glare_deg: float = 3.0


@dataclass
class MagSpec:
    declination_deg: float = -7.133
    inclination_deg: float = 59.215
    intensity_nt: float = 54769.0
    noise_nt: float = 15.0


@dataclass
class StreamSpec:
    trajectory: Trajectory
    duration_s: float
    epoch: dt.datetime = EPOCH
    imu: ImuErrors = field(default_factory=ImuErrors)
    gnss: GnssSpec = field(default_factory=GnssSpec)
    psns: str | None = None  # None, "solar_vector", "compass", "camera"
    psns_rate_hz: float = 5.0
    sun_sigma: float = 0.0  # solar_vector: noise per component
    compass: CompassSpec | None = None
    camera: CameraSpec | None = None
    mag: MagSpec | None = None
    imu_rate_hz: float = 200.0
    psns_latency_us: int = 20000


def static_trajectory(heading_deg: float = 30.0, pitch_deg: float = 0.0, roll_deg: float = 0.0,
                      where: tuple[float, float, float] = BEIJING) -> StaticTrajectory:
    return StaticTrajectory(where[0], where[1], where[2], heading_deg, pitch_deg, roll_deg)


def segment_trajectory(segments: list[dict], heading_deg: float = 30.0, duration: float | None = None,
                       where: tuple[float, float, float] = BEIJING) -> Trajectory:
    from emulator.scenario.world_schema import MotionSegment

    segs = [MotionSegment.model_validate(s) for s in segments]
    return trajectory_from_segments(segs, where[0], where[1], where[2], heading_deg, 0.0, 0.0, duration)


def field_enu(m: MagSpec) -> np.ndarray:
    d, i = m.declination_deg * DEG, m.inclination_deg * DEG
    return m.intensity_nt * np.array([math.cos(i) * math.sin(d), math.cos(i) * math.cos(d), -math.sin(i)])


def wire_aop(e_x: np.ndarray, e_y: np.ndarray) -> np.ndarray:
    """AOP convention: psi = atan2(E_y, E_x) (from +x towards +y), wire AOP = 90 deg - psi wrapped to (-90, 90] deg
    (rad)."""
    a = 0.5 * math.pi - np.arctan2(e_y, e_x)
    return a - math.pi * np.ceil((a - 0.5 * math.pi) / math.pi)


def rayleigh(s: np.ndarray, v: np.ndarray, p_max: float) -> tuple[np.ndarray, np.ndarray]:
    """DOP (n,) and unit E-vectors (n, 3) of rays ``v`` (n, 3) for the sun ``s`` (3,), same frame."""
    cg = v @ s
    dop = p_max * (1.0 - cg * cg) / (1.0 + cg * cg)
    e = np.cross(s[None, :], v)
    n = np.linalg.norm(e, axis=1, keepdims=True)
    return dop, e / np.maximum(n, 1e-12)


def stream(spec: StreamSpec, seed: int = 1) -> Iterator[tuple[float, int, bytes]]:
    """Yield ``(t_rx_s, uart, bytes)`` in time order (see module docstring)."""
    rng = np.random.default_rng(seed)
    traj = spec.trajectory
    sun = SunModel(spec.epoch, 69.0)
    T = 1.0 / spec.imu_rate_hz
    e = spec.imu
    bg = np.array(e.gyro_bias_dph) * DPH
    ba = np.array(e.accel_bias_ug) * 1e-6 * G_STD
    arw = e.gyro_arw_deg_rt_h * DEG / 60.0
    vrw = e.accel_noise_ug_rt_hz * 1e-6 * G_STD
    b_n = field_enu(spec.mag) if spec.mag is not None else None
    fmt = ImuFrameFormat()
    heap: list[tuple[float, int, int, bytes]] = []
    order = 0

    def push(t: float, uart: int, data: bytes) -> None:
        nonlocal order
        heapq.heappush(heap, (t, order, uart, data))
        order += 1

    def gnss_out(tk: float) -> bool:
        return any(a <= tk < b for a, b in spec.gnss.outages)

    n_imu = round(spec.duration_s * spec.imu_rate_hz)
    next_gnss = 1
    next_psns = 1.0 / spec.psns_rate_hz
    psns_seq = 0
    pps_last = 0
    mag_seq = 0
    for k in range(1, n_imu + 1):
        t = k * T
        while spec.gnss.enabled and next_gnss <= t:
            if not gnss_out(next_gnss):
                push(next_gnss + 0.05, UART_GNSS, _nav_pvt(spec, traj, next_gnss, rng))
                pps_last = next_gnss
            elif spec.gnss.time_during_outage:
                push(next_gnss + 0.05, UART_GNSS, _nav_pvt(spec, traj, next_gnss, rng, fix=False))
            next_gnss += 1
        while spec.psns and next_psns <= t:
            frame = _psns_frame(spec, traj, sun, next_psns, psns_seq, rng)
            if frame:
                push(next_psns + spec.psns_latency_us * 1e-6 + len(frame) * 10 / 115200, UART_PSNS, frame)
            psns_seq += 1
            next_psns += 1.0 / spec.psns_rate_hz
        dth, dv = traj.imu_increments(t - T, t)
        w = dth / T + bg + (rng.normal(0.0, arw / math.sqrt(T), 3) if arw > 0 else 0.0)
        f = dv / T + ba + (rng.normal(0.0, vrw / math.sqrt(T), 3) if vrw > 0 else 0.0)
        gyro = tuple(round(x / DEG / GYRO_RATE_LSB_DPS) for x in w)
        accel = tuple(round(fi / G_STD * vpg / ADC_VOLTS_PER_LSB) for fi, vpg in zip(f, ACCEL_VOLTS_PER_G))
        fr = ImuFrame(seq=k & 0xFFFF, t_trigger_us=round(t * 1e6) & 0xFFFFFFFF,
                      t_pps_us=(pps_last * 1_000_000) & 0xFFFFFFFF, pps_count=pps_last & 0xFF, gyro=gyro,  # type: ignore[arg-type]
                      gyro_status=0, gyro_counter=(10 * k) & 0xFF, gyro_latency_us=500, accel=accel,  # type: ignore[arg-type]
                      fpga_status=int(FpgaStatus.PPS_VALID) if pps_last >= 1 else 0)
        data = fmt.build(fr)
        if b_n is not None and k % 2 == 0:
            st = traj.state(t)
            m = st.c_bn.T @ b_n + rng.normal(0.0, spec.mag.noise_nt, 3)  # type: ignore[union-attr]
            words = tuple(round(x / 0.1) for x in m)
            data += encode_mag_frame(MagFrame(seq=mag_seq & 0xFFFF, t_sample_us=round(t * 1e6) & 0xFFFFFFFF,
                                              field=words, status=0))  # type: ignore[arg-type]
            mag_seq += 1
        push(t + len(data) * 10 / 460800 + 0.0004, UART_IMU, data)
        while heap and heap[0][0] <= t:
            tt, _, uart, d = heapq.heappop(heap)
            yield tt, uart, d
    while heap:
        tt, _, uart, d = heapq.heappop(heap)
        yield tt, uart, d


def _nav_pvt(spec: StreamSpec, traj: Trajectory, k: int, rng: np.random.Generator, fix: bool = True) -> bytes:
    g = spec.gnss
    st = traj.state(float(k))
    lat, lon, h = (float(v) for v in st.pos)
    rm, rn = earth.radii(lat)
    off = np.zeros(3)
    for start, dur, d in g.glitches:
        if start <= k < start + dur:
            off += np.array(d)
    de, dn, du = (rng.normal(0.0, g.pos_sigma_m, 3) if g.pos_sigma_m > 0 else np.zeros(3)) + off
    ve, vn, vu = st.v_enu + (rng.normal(0.0, g.vel_sigma_mps, 3) if g.vel_sigma_mps > 0 else 0.0)
    lat_m = lat + dn / (rm + h)
    lon_m = lon + de / ((rn + h) * math.cos(lat))
    utc = spec.epoch + dt.timedelta(seconds=k)
    p = NavPvt(iTOW=(k * 1000) % 604800000, year=utc.year, month=utc.month, day=utc.day, hour=utc.hour,
               min=utc.minute, sec=utc.second, valid=0x07, tAcc=50, nano=0, fixType=3 if fix else 0,
               flags=0x01 if fix else 0x00, flags2=0xE0,
               numSV=12, lon=round(lon_m / DEG * 1e7), lat=round(lat_m / DEG * 1e7), height=round((h + du) * 1e3),
               hMSL=round((h + du) * 1e3), hAcc=3000, vAcc=5000, velN=round(vn * 1e3), velE=round(ve * 1e3),
               velD=round(-vu * 1e3), gSpeed=round(math.hypot(ve, vn) * 1e3), headMot=0, sAcc=100, headAcc=1000000,
               pDOP=150, flags3=0, reserved0=0, headVeh=0, magDec=0, magAcc=0)
    return encode_nav_pvt(p)


def _psns_frame(spec: StreamSpec, traj: Trajectory, sun: SunModel, t_exp: float, seq: int,
                rng: np.random.Generator) -> bytes | None:
    st = traj.state(t_exp)
    s_n = sun.sun_enu(t_exp, float(st.pos[0]), float(st.pos[1]), float(st.pos[2]))
    c_nb = st.c_bn.T
    s_b = c_nb @ s_n
    if spec.psns == "solar_vector":
        s = s_b + (rng.normal(0.0, spec.sun_sigma, 3) if spec.sun_sigma > 0 else 0.0)
        s = s / np.linalg.norm(s) * (1.0 if rng.random() < 0.5 else -1.0)
        hdr = PsnsHeader(seq & 0xFFFF, 2000, spec.psns_latency_us, int(PsnsStatus.VALID), 0)
        return encode_solar_vector(hdr, (float(s[0]), float(s[1]), float(s[2])), 0.01)
    if spec.psns == "compass":
        c = spec.compass
        assert c is not None
        m = c.mountings
        rays = m[:, :, 2]
        dop, e_b = rayleigh(s_b, rays, c.p_max)
        e_u = np.einsum("uji,uj->ui", m, e_b)
        aop = wire_aop(e_u[:, 0], e_u[:, 1])
        sig = c.aop_sigma_deg * DEG * c.dop_ref / np.maximum(dop, 0.02)
        aop = aop + rng.normal(0.0, 1.0, len(aop)) * sig
        dop = dop + rng.normal(0.0, 0.002, len(dop))
        for units, a, b in c.blocked:
            if a <= t_exp < b:
                for u in units:
                    dop[u] = abs(rng.normal(0.0, 0.003))
                    aop[u] = rng.uniform(-0.5 * math.pi, 0.5 * math.pi)
        aop = aop - math.pi * np.ceil((aop - 0.5 * math.pi) / math.pi)
        units = [CompassUnit(i, round(aop[i] / DEG * 100), int(np.clip(round(dop[i] * 65535), 0, 65535)))
                 for i in range(len(m))]
        status = int(PsnsStatus.VALID) if np.count_nonzero(dop >= 0.05) >= 2 else int(PsnsStatus.LOW_DOP)
        hdr = PsnsHeader(seq & 0xFFFF, 10000, spec.psns_latency_us, status, len(units))
        return encode_compass(hdr, units)
    if spec.psns == "camera":
        return camera_frame(spec.camera, c_nb, s_n, seq, spec.psns_latency_us, rng)  # type: ignore[arg-type]
    return None


def camera_observation(cs: CameraSpec, c_nb: np.ndarray, s_n: np.ndarray, rng: np.random.Generator | None
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Points of an all-sky image: (x_px, y_px, wire AOP rad, DOP); ground points unpolarized, glare dropped."""
    cam = cs.cam
    xs = np.arange(1 + cs.stride_px // 2, cam.nx + 1, cs.stride_px)
    ys = np.arange(1 + cs.stride_px // 2, cam.ny + 1, cs.stride_px)
    xx, yy = np.meshgrid(xs, ys)
    x, y = xx.ravel().astype(np.float64), yy.ravel().astype(np.float64)
    v = cam.view_rays(x, y)
    keep = np.arccos(np.clip(v[:, 2], -1, 1)) <= cs.max_theta_deg * DEG
    x, y, v = x[keep], y[keep], v[keep]
    c_cb = cam.c_c_b
    s_c = c_cb.T @ (c_nb @ s_n)
    up_c = c_cb.T @ c_nb[:, 2]
    glare = v @ s_c > math.cos(cs.glare_deg * DEG)
    x, y, v = x[~glare], y[~glare], v[~glare]
    dop, e = rayleigh(s_c, v, cs.p_max)
    aop = wire_aop(e[:, 0], e[:, 1])
    ground = v @ up_c < 0.0
    if rng is not None:
        aop = aop + rng.normal(0.0, 1.0, len(aop)) * cs.aop_sigma_deg * DEG * 0.5 / np.maximum(dop, 0.02)
        dop = dop + rng.normal(0.0, cs.dop_sigma, len(dop))
        aop = np.where(ground, rng.uniform(-0.5 * math.pi, 0.5 * math.pi, len(aop)), aop)
        dop = np.where(ground, np.abs(rng.normal(0.0, 0.01, len(dop))), dop)
    else:
        dop = np.where(ground, 0.0, dop)
    aop = aop - math.pi * np.ceil((aop - 0.5 * math.pi) / math.pi)
    return x, y, aop, np.clip(dop, 0.0, 1.0)


def camera_frame(cs: CameraSpec, c_nb: np.ndarray, s_n: np.ndarray, seq: int, latency_us: int,
                 rng: np.random.Generator | None) -> bytes:
    x, y, aop, dop = camera_observation(cs, c_nb, s_n, rng)
    pts = [PolarizationPoint(int(a), int(b), round(c / DEG * 100), round(d * 65535), 2000)
           for a, b, c, d in zip(x, y, aop, dop)]
    hdr = PsnsHeader(seq & 0xFFFF, 1000, latency_us, int(PsnsStatus.VALID), len(pts))
    return encode_polarization_obs(hdr, pts)


@dataclass
class Sample:
    """Errors of the navigation solution against truth at one instant."""

    t: float
    att_err_deg: np.ndarray  # E, N, U misalignment (computed vs truth), deg
    heading_err_deg: float
    pitch_err_deg: float
    roll_err_deg: float
    pos_err_m: np.ndarray  # N, E, U
    vel_err_mps: np.ndarray


def run(fw, spec: StreamSpec, seed: int = 1, sample_every_s: float = 1.0, on_tick=None):
    """Drive ``fw`` with the stream; sample errors against truth every ``sample_every_s``. Returns (samples, events)."""
    from firmware_model.attitude import heading_from_yaw, m2att, q2mat
    from firmware_model.variants.common import misalignment_between

    traj = spec.trajectory
    samples: list[Sample] = []
    events: list[dict] = []
    next_t = sample_every_s
    for t_rx, uart, data in stream(spec, seed):
        fw.receive(uart, data, t_rx)
        if uart != UART_IMU:
            continue
        for r in fw.service():
            events.extend(r.events)
            if on_tick is not None:
                on_tick(fw, r)
            if fw.nav is not None and r.t_fpga_s >= next_t - 1e-9:
                next_t += sample_every_s
                st = traj.state(r.t_fpga_s)
                cbn = q2mat(fw.nav.q.astype(np.float64))
                phi = misalignment_between(cbn, st.c_bn) / DEG
                p, ro, y = m2att(cbn)
                hd = (heading_from_yaw(y) - st.heading) / DEG
                rm, rn = earth.radii(float(st.pos[0]))
                dp = fw.nav.pos - st.pos
                pos = np.array([dp[0] * (rm + st.pos[2]), dp[1] * (rn + st.pos[2]) * math.cos(st.pos[0]), dp[2]])
                samples.append(Sample(r.t_fpga_s, phi, (hd + 180.0) % 360.0 - 180.0, (p - st.pitch) / DEG,
                                      (ro - st.roll) / DEG, pos, fw.nav.v.astype(np.float64) - st.v_enu))
    return samples, events
