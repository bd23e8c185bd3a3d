"""The hostile-input corpus (docs/hostile-input.md): each case rewrites a clean synthetic stream (``synth.py``) inside
a time window, as a peer on a port or a recorded log could; :func:`run_case` feeds it to a :class:`Firmware` and
measures the errors after the window and the recovery time.

Used by ``test_hostile_input.py`` (every case x every filter variant) and by ``tests/fuzz/fuzz_inputs.py``.
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field

import numpy as np

from firmware_model import Firmware, FirmwareConfig, earth
from firmware_model.attitude import heading_from_yaw, m2att, q2mat
from protocols.constants import DEG
from protocols.crc import nmea_checksum
from protocols.host import HostFormat, NavSolution
from protocols.imu_frame import ImuFrame, ImuFrameFormat
from protocols.stim import StimStatus
from protocols.stream import StreamDecoder
from protocols.ubx import NavPvt, encode_nav_pvt

from .synth import SensorErrors, StaticTruth, StreamConfig, static_stream

UART_IMU, UART_GNSS = 1, 3
Stream = Iterator[tuple[float, int, bytes]]

#: the window (s of stream time) in which a case's hostile input is sent
T_BAD = (20.0, 21.0)


def sentence(body: str) -> bytes:
    """A well-framed NMEA sentence (valid checksum) around ``body`` (without ``$`` and ``*hh``)."""
    return f"${body}*{nmea_checksum(body.encode()):02X}\r\n".encode()


def _gnss_time(t: float, truth: StaticTruth) -> dt.datetime:
    return truth.epoch + dt.timedelta(seconds=round(t))


def _gga(truth: StaticTruth, t: float, lat: str = "", alt: str = "") -> bytes:
    u = _gnss_time(t, truth)
    d = int(truth.lat_deg)
    lat = lat or f"{d * 100 + (truth.lat_deg - d) * 60:010.5f}"
    d2 = int(truth.lon_deg)
    lon = f"{d2 * 100 + (truth.lon_deg - d2) * 60:011.5f}"
    alt = alt or f"{truth.height_m - 10.0:.3f}"
    return sentence(f"GPGGA,{u:%H%M%S}.00,{lat},N,{lon},E,1,12,0.8,{alt},M,10.000,M,,")


def _rmc(truth: StaticTruth, t: float, speed: str = "0.000", course: str = "0.0") -> bytes:
    u = _gnss_time(t, truth)
    d = int(truth.lat_deg)
    lat = f"{d * 100 + (truth.lat_deg - d) * 60:010.5f}"
    d2 = int(truth.lon_deg)
    lon = f"{d2 * 100 + (truth.lon_deg - d2) * 60:011.5f}"
    return sentence(f"GPRMC,{u:%H%M%S}.00,A,{lat},N,{lon},E,{speed},{course},{u:%d%m%y},,,A")


def _pvt(truth: StaticTruth, t: float, **over: int) -> bytes:
    u = _gnss_time(t, truth)
    p = NavPvt(iTOW=0, year=u.year, month=u.month, day=u.day, hour=u.hour, min=u.minute, sec=u.second, valid=0x07,
               tAcc=50, nano=0, fixType=3, flags=0x01, flags2=0xE0, numSV=12, lon=round(truth.lon_deg * 1e7),
               lat=round(truth.lat_deg * 1e7), height=round(truth.height_m * 1e3),
               hMSL=round((truth.height_m - 10) * 1e3), hAcc=3000, vAcc=5000, velN=0, velE=0, velD=0, gSpeed=0,
               headMot=0, sAcc=100, headAcc=1000000, pDOP=150, flags3=0, reserved0=0, headVeh=0, magDec=0, magAcc=0)
    return encode_nav_pvt(dataclasses.replace(p, **over))


def _lat_minus_5km(tr: StaticTruth) -> str:
    return f"{int(tr.lat_deg) * 100 + (tr.lat_deg % 1) * 60 - 2.7:010.5f}"  # 2.7' of latitude: 5.0 km south


def _replace_gnss(make: Callable[[StaticTruth, float], bytes]) -> Callable[[Stream, StaticTruth], Stream]:
    """Replace every GNSS epoch inside :data:`T_BAD` by ``make(truth, t)``."""
    def apply(s: Stream, truth: StaticTruth) -> Stream:
        for t, uart, data in s:
            if uart == UART_GNSS and T_BAD[0] <= t < T_BAD[1] + 1.0:
                yield t, uart, make(truth, t)
            else:
                yield t, uart, data
    return apply


def _rewrite_imu(change: Callable[[ImuFrame, float], ImuFrame], t0: float, t1: float
                 ) -> Callable[[Stream, StaticTruth], Stream]:
    fmt = ImuFrameFormat()

    def apply(s: Stream, truth: StaticTruth) -> Stream:
        for t, uart, data in s:
            if uart == UART_IMU and t0 <= t < t1:
                (fr,) = StreamDecoder([fmt]).feed(data)
                yield t, uart, fmt.build(change(fr, t))
            else:
                yield t, uart, data
    return apply


def _imu_jump(fr: ImuFrame, t: float) -> ImuFrame:
    return dataclasses.replace(fr, t_trigger_us=(fr.t_trigger_us + 1_000_000_000) & 0xFFFFFFFF)


#: name -> stream rewriter. The GNSS epochs of the window carry the bad value (GNSS stream rate: 1 Hz).
CASES: dict[str, Callable[[Stream, StaticTruth], Stream]] = {
    "gga_altitude_nan": _replace_gnss(lambda tr, t: _gga(tr, t, alt="nan") + _rmc(tr, t)),
    "gga_jump_5km": _replace_gnss(lambda tr, t: _gga(tr, t, lat=_lat_minus_5km(tr)) + _rmc(tr, t)),
    "gga_latitude_91": _replace_gnss(lambda tr, t: _gga(tr, t, lat="9100.00000") + _rmc(tr, t)),
    "gga_height_minus_1e6": _replace_gnss(lambda tr, t: _gga(tr, t, alt="-1000000.0") + _rmc(tr, t)),
    "rmc_course_inf": _replace_gnss(lambda tr, t: _gga(tr, t) + _rmc(tr, t, course="inf")),
    "rmc_speed_1e300": _replace_gnss(lambda tr, t: _gga(tr, t) + _rmc(tr, t, speed="1e300")),
    "pvt_leap_second": _replace_gnss(lambda tr, t: _pvt(tr, t, hour=23, min=59, sec=60)),
    "pvt_month_13": _replace_gnss(lambda tr, t: _pvt(tr, t, month=13)),
    "pvt_height_minus_1e6": _replace_gnss(lambda tr, t: _pvt(tr, t, height=-1_000_000_000)),
    "imu_gyro_saturated_1s": _rewrite_imu(lambda fr, t: dataclasses.replace(fr, gyro=(2**23 - 1, -(2**23), 2**23 - 1)),
                                         *T_BAD),
    # one LSB inside the rail (512 deg/s, beyond the STIM210's +-400 deg/s): passed the rail check before issue 41
    "imu_gyro_near_rail_1s": _rewrite_imu(lambda fr, t: dataclasses.replace(fr, gyro=(2**23 - 2, -(2**23) + 1,
                                                                                      2**23 - 2)), *T_BAD),
    # in range (300 deg/s about z) but flagged by the STIM's STATUS byte (overload on Z, TS1524 Table 5-23): the
    # firmware did not read STATUS before issue 41
    "imu_gyro_overload_status_1s": _rewrite_imu(lambda fr, t: dataclasses.replace(
        fr, gyro=(fr.gyro[0], fr.gyro[1], 300 * 2**14), gyro_status=int(StimStatus.OVERLOAD | StimStatus.Z_CHANNEL)),
        *T_BAD),
    "imu_accel_saturated_1s": _rewrite_imu(lambda fr, t: dataclasses.replace(fr, accel=(2**23 - 1,) * 3), *T_BAD),
    "imu_time_jump_1000s": _rewrite_imu(_imu_jump, T_BAD[0], T_BAD[0] + 0.004),
}


def _flip_heading(fw: Firmware) -> None:
    """The navigation attitude turned 150 deg about the vertical (what 1 s of clipped gyro words did before the
    IMU words were screened): only the divergence detection and the re-alignment bring it back."""
    from firmware_model.attitude import qmul, rv2q

    nav = fw.nav
    assert nav is not None
    nav.q = qmul(rv2q(np.array([0.0, 0.0, 150.0 * DEG])), nav.q.astype(np.float64)).astype(nav.q.dtype)


def _poison_covariance(fw: Firmware) -> None:
    """A non-finite covariance (the state a NaN measurement left before validation existed)."""
    fw.filter.P = fw.filter.P * np.nan


#: name -> a corruption of the firmware's own state at T_BAD[0] (the effect of a hostile input that got through):
#: these exercise detection and recovery rather than validation
STATE_UPSETS: dict[str, Callable[[Firmware], None]] = {
    "state_heading_flip_150deg": _flip_heading,
    "state_covariance_nan": _poison_covariance,
}


@dataclass
class CaseResult:
    name: str
    variant: str
    counters: dict[str, int]
    events: list[dict]
    #: (t, heading error deg, level error deg, horizontal position error m) once per second after alignment
    samples: list[tuple[float, float, float, float]]
    any_nan: bool
    #: (time of validity, gnss_status byte) of every NAV_SOLUTION frame the firmware sent
    gnss_status: list[tuple[float, int]] = field(default_factory=list)

    def worst_after(self, t0: float) -> tuple[float, float, float]:
        tail = [s for s in self.samples if s[0] >= t0]
        return (max(abs(s[1]) for s in tail), max(abs(s[2]) for s in tail), max(s[3] for s in tail))

    def recovery_s(self, heading_deg: float, level_deg: float, pos_m: float) -> float:
        """Seconds after the end of the hostile window until every later sample is within the bounds."""
        t_ok = T_BAD[1]
        for s in self.samples:
            if s[0] >= T_BAD[0] and (abs(s[1]) > heading_deg or abs(s[2]) > level_deg or s[3] > pos_m):
                t_ok = max(t_ok, s[0])
        return t_ok - T_BAD[1]


def _wrap180(x: float) -> float:
    return (x + 180.0) % 360.0 - 180.0


def run_case(name: str, variant: str = "base", duration_s: float = 70.0, gnss_output: str | None = None,
             seed: int = 1) -> CaseResult:
    """Run one corpus case (``name`` in :data:`CASES`, or ``"clean"``) on ``variant``."""
    truth = StaticTruth()
    out = gnss_output or ("ubx" if name.startswith("pvt_") else "nmea")
    scfg = StreamConfig(gnss_output=out)
    err = SensorErrors(gyro_bias_dph=(0.05, -0.03, 0.04), gyro_arw_deg_rt_h=0.01, accel_bias_mg=(0.2, -0.1, 0.1),
                       accel_noise_ug_rt_hz=20.0, gnss_pos_sigma_m=1.0, gnss_vel_sigma_mps=0.02, psns_sigma_deg=0.05)
    cfg = FirmwareConfig(filter=variant, fine_align_time_s=5.0, psns_enabled=True)
    fw = Firmware(cfg)
    fw.raise_faults = True  # every case must be handled by validation, gates and recovery, not by containment
    s: Stream = static_stream(truth, err, scfg, duration_s, seed=seed)
    if name in CASES:
        s = CASES[name](s, truth)
    upset = STATE_UPSETS.get(name)
    rm, rn = earth.radii(truth.lat_deg * DEG)
    samples: list[tuple[float, float, float, float]] = []
    events: list[dict] = []
    any_nan = False
    next_sample = 1.0
    host = StreamDecoder([HostFormat()])
    gnss_status: list[tuple[float, int]] = []
    for t_rx, uart, data in s:
        fw.receive(uart, data, t_rx)
        if uart != UART_IMU:
            continue
        if upset is not None and fw.nav is not None and fw.clock.now_s() >= T_BAD[0]:
            upset(fw)
            upset = None
        for r in fw.service():
            events.extend(r.events)
            for out_uart, frame, _cycles in r.outputs:
                if out_uart == 0:
                    gnss_status.extend((f.time_s, f.gnss_status) for f in host.feed(frame)
                                       if isinstance(f, NavSolution))
            if r.t_fpga_s < next_sample - 1e-9:
                continue
            next_sample = math.floor(r.t_fpga_s) + 1.0
            nav = fw.nav
            if nav is None:
                samples.append((r.t_fpga_s, 180.0, 90.0, 1e9))  # aligning: no solution counts as not recovered
                continue
            x = np.concatenate([nav.q.astype(np.float64), nav.v.astype(np.float64), nav.pos])
            if not np.isfinite(x).all():
                any_nan = True
                samples.append((r.t_fpga_s, 180.0, 90.0, 1e9))
                continue
            p, ro, y = m2att(q2mat(nav.q.astype(np.float64)))
            dn = (nav.pos[0] - truth.lat_deg * DEG) * (rm + truth.height_m)
            de = (nav.pos[1] - truth.lon_deg * DEG) * (rn + truth.height_m) * math.cos(truth.lat_deg * DEG)
            samples.append((r.t_fpga_s, _wrap180(heading_from_yaw(y) / DEG - truth.heading_deg),
                            max(abs(p / DEG - truth.pitch_deg), abs(ro / DEG - truth.roll_deg)), math.hypot(dn, de)))
    return CaseResult(name, variant, dict(fw.counters), events, samples, any_nan, gnss_status)
