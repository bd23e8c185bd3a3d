"""The DSP firmware's main loop as a pure, synchronous state machine.

The virtual DSP (``emulator.devices.dsp``) hosts one :class:`Firmware`: the UART ISRs hand
bytes to :meth:`Firmware.receive`; the cyclic executive runs in :meth:`Firmware.service`,
driven by the FPGA's 200 Hz IMU frames, and returns per tick the bytes to transmit and the
cycles charged, which the DSP turns into time.

UART map (DESIGN.md section 2): UART0 host (navigation out, commands in), UART1 IMU frames
from the FPGA, UART2 PSNS, UART3 GNSS (the FPGA's 16550 core, read over EMIFA).

Tasks per IMU tick (base filter, Liang & Bai): decode and convert the IMU frame; while
aligning, accumulate the specific force for coarse levelling; while navigating, strapdown
(:mod:`firmware_model.strapdown`), a KF time update every ``kf_predict_every`` ticks, a GNSS
position/velocity update (Eqs. 23-30) when a fix is pending, and the NAV_SOLUTION output at
``output_rate_hz``.
"""

from __future__ import annotations

import datetime as _dt
import math
from collections import deque
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from protocols.host import NavMode, NavSolution, encode_nav_solution
from protocols.imu_frame import ACCEL_VOLTS_PER_G, ADC_VOLTS_PER_LSB, FpgaStatus, ImuFrame, ImuFrameFormat
from protocols.nmea import Gga, NmeaFormat, Rmc
from protocols.stim import GYRO_ANGLE_LSB_DEG, GYRO_RATE_LSB_DPS
from protocols.stream import StreamDecoder

from . import c674x, earth
from .attitude import a2mat, cross3, heading_from_yaw, m2att, mat2q, q2mat, rv2q, qmul, qnormalize, yaw_from_heading
from .errors import FirmwareError
from .kf import IDX_ACC, IDX_GYRO, N_STATES, error_transition_matrix, kf_predict, kf_update_scalar
from .strapdown import NavState, strapdown_step

__all__ = ["UART_HOST", "UART_IMU", "UART_PSNS", "UART_GNSS", "FirmwareConfig", "TickResult", "Firmware"]

UART_HOST, UART_IMU, UART_PSNS, UART_GNSS = 0, 1, 2, 3

DEG = math.pi / 180.0
G_STD = 9.80665
DPH = DEG / 3600.0  # deg/h in rad/s


@dataclass
class FirmwareConfig:
    """Firmware build/run-time parameters (units in the names)."""

    clock_hz: float = 300e6
    imu_rate_hz: float = 200.0
    gyro_output: str = "rate"  # "rate" (2^-14 deg/s) or "angle" (2^-21 deg per sample)
    gyro_counter_step: int = 10
    kf_predict_every: int = 20
    output_rate_hz: float = 100.0
    align_time_s: float = 2.0
    initial_heading_deg: float = 0.0
    initial_heading_sigma_deg: float = 1.0
    precision: str = "float32"
    filter: str = "base"
    accel_volts_per_g: tuple[float, float, float] = ACCEL_VOLTS_PER_G
    # process noise (sensor specifications)
    gyro_arw_deg_rt_h: float = 0.15
    gyro_bias_sigma_deg_h: float = 40.0 / 3.0
    gyro_bias_instability_deg_h: float = 20.0 / 3.0
    accel_noise_ug_rt_hz: float = 100.0
    accel_bias_sigma_mg: float = 7.0 / 3.0
    accel_bias_instability_mg: float = 4.0 / 3.0
    bias_corr_time_s: float = 600.0
    # measurement noise (1 sigma per axis)
    gnss_pos_sigma_h_m: float = 4.08
    gnss_pos_sigma_v_m: float = 7.5
    gnss_vel_sigma_h_mps: float = 0.041
    gnss_max_age_s: float = 1.5

    def __post_init__(self) -> None:
        if self.precision not in ("float32", "float64"):
            raise FirmwareError(f"precision must be float32 or float64, got {self.precision!r}")
        if self.gyro_output not in ("rate", "angle"):
            raise FirmwareError(f"gyro_output must be 'rate' or 'angle', got {self.gyro_output!r}")
        if self.filter != "base":
            raise FirmwareError(f"filter variant {self.filter!r} is not available in this firmware build")
        ratio = self.imu_rate_hz / self.output_rate_hz
        if ratio < 1 or abs(ratio - round(ratio)) > 1e-9:
            raise FirmwareError("output_rate_hz must divide imu_rate_hz")


@dataclass
class TickResult:
    """What one run of the cyclic executive produced.

    ``cycles`` is the total charged; each output is ``(uart, bytes, cycles_at_emit)``.
    """

    t_fpga_s: float
    cycles: int
    outputs: list[tuple[int, bytes, int]] = field(default_factory=list)
    events: list[dict[str, Any]] = field(default_factory=list)


@dataclass
class _GnssFix:
    t_fpga_s: float
    utc: _dt.time
    lat: float
    lon: float
    h: float
    quality: int


class Firmware:
    """The base-variant firmware (see module docstring)."""

    def __init__(self, cfg: FirmwareConfig | None = None) -> None:
        self.cfg = cfg = cfg or FirmwareConfig()
        self.dtype = np.float32 if cfg.precision == "float32" else np.float64
        self.meter = c674x.CycleMeter(cfg.clock_hz, cfg.imu_rate_hz)
        self.T = 1.0 / cfg.imu_rate_hz
        self._dec_imu = StreamDecoder([ImuFrameFormat()])
        self._dec_gnss = StreamDecoder([NmeaFormat()])
        self._pending_imu: deque[ImuFrame] = deque()
        self._rx_other: dict[int, int] = {}
        # time keeping
        self._t_last_us: int | None = None
        self._t_epoch_us = 0  # unwrapped high part
        self._t_pps_s: float | None = None
        self._pps_count: int | None = None
        self._last_counter: int | None = None
        # navigation
        self.mode = NavMode.ALIGNING
        self._align_sum = np.zeros(3)
        self._align_n = 0
        self._align_t0: float | None = None
        self.nav: NavState | None = None
        self.x = np.zeros(N_STATES, dtype=self.dtype)
        self.P = np.zeros((N_STATES, N_STATES), dtype=self.dtype)
        self.gyro_bias = np.zeros(3, dtype=self.dtype)  # rad/s, body
        self.accel_bias = np.zeros(3, dtype=self.dtype)  # m/s^2, body
        self._tick = 0
        self._fn_sum = np.zeros(3)
        self._fn_n = 0
        self._hist: deque[tuple[float, np.ndarray, np.ndarray]] = deque(maxlen=int(2 * cfg.imu_rate_hz))
        self._pos_pending: _GnssFix | None = None
        self._vel_pending: tuple[float, float, float] | None = None
        self._last_fix: _GnssFix | None = None
        self._last_gnss_update_t = -1e9
        self._out_seq = 0
        self.deadline_misses = 0
        self._load_window: deque[tuple[float, int]] = deque()
        self._load_sum = 0
        self.counters = {"imu_frames": 0, "gnss_fixes": 0, "gnss_updates": 0, "gyro_counter_jumps": 0,
                         "fpga_gyro_missing": 0, "imu_time_gaps": 0}

    # -- ISR side ----------------------------------------------------------------------
    def receive(self, uart: int, data: bytes, t_rx_s: float | None = None) -> None:
        """Bytes received on ``uart`` (the ISR copies the 16550 FIFO into the ring buffer).

        ``t_rx_s`` is the DSP's time (s, FPGA time base) when the last byte arrived, as the ISR
        reads it from the time-stamp counter; frames that carry a latency (PSNS) are time-tagged
        from it.
        """
        if uart == UART_IMU:
            for f in self._dec_imu.feed(data):
                self._pending_imu.append(f)
        elif uart == UART_GNSS:
            for s in self._dec_gnss.feed(data):
                self._on_nmea(s)
        else:
            self._rx_other[uart] = self._rx_other.get(uart, 0) + len(data)

    def decoder_stats(self) -> dict[str, dict[str, Any]]:
        return {"uart1": self._dec_imu.stats.as_dict(), "uart3": self._dec_gnss.stats.as_dict()}

    def note_deadline_miss(self) -> None:
        """Called by the host DSP when a tick started after its deadline."""
        self.deadline_misses += 1

    # -- main loop -----------------------------------------------------------------------
    def service(self) -> list[TickResult]:
        """Run the cyclic executive over every pending IMU frame."""
        out: list[TickResult] = []
        while self._pending_imu:
            out.append(self._imu_tick(self._pending_imu.popleft()))
        return out

    # -- GNSS ---------------------------------------------------------------------------
    def _on_nmea(self, s: Any) -> None:
        """GGA gives a position fix, RMC a horizontal velocity; both valid at the last PPS edge."""
        t_meas = self._t_pps_s if self._t_pps_s is not None else self._now_s()
        if isinstance(s, Gga):
            if s.quality == 0 or s.lat_deg is None or s.lon_deg is None or s.altitude_msl_m is None:
                return
            fix = _GnssFix(
                t_fpga_s=t_meas,
                utc=s.time_utc or _dt.time(0),
                lat=s.lat_deg * DEG,
                lon=s.lon_deg * DEG,
                h=s.altitude_msl_m + (s.geoid_sep_m or 0.0),
                quality=s.quality,
            )
            self.counters["gnss_fixes"] += 1
            self._pos_pending = fix
            self._last_fix = fix
        elif isinstance(s, Rmc):
            if not s.valid or s.speed_mps is None:
                return
            c = (s.course_deg or 0.0) * DEG
            self._vel_pending = (t_meas, s.speed_mps * math.sin(c), s.speed_mps * math.cos(c))

    def _now_s(self) -> float:
        if self._t_last_us is None:
            return 0.0
        return (self._t_epoch_us + self._t_last_us) / 1e6

    # -- IMU tick ---------------------------------------------------------------------------
    def _unwrap_us(self, t_us: int) -> int:
        if self._t_last_us is not None and t_us < self._t_last_us and self._t_last_us - t_us > 2**31:
            self._t_epoch_us += 2**32
        self._t_last_us = t_us
        return self._t_epoch_us + t_us

    def _imu_tick(self, fr: ImuFrame) -> TickResult:
        cfg = self.cfg
        m = self.meter
        m.begin("imu_tick")
        # decode: CRC-16 over 36 bytes by table (~4 cycles/byte) + field unpack [E]
        m.charge("imu_decode", 36 * 4 + c674x.flops(12, 6))
        t_us = self._unwrap_us(fr.t_trigger_us)
        t = t_us / 1e6
        res = TickResult(t_fpga_s=t, cycles=0)
        self.counters["imu_frames"] += 1
        # PPS latch
        if fr.fpga_status & FpgaStatus.PPS_VALID and fr.pps_count != self._pps_count:
            self._pps_count = fr.pps_count
            pps_us = fr.t_pps_us
            # unwrap against the trigger time
            full = (t_us & ~0xFFFFFFFF) | pps_us
            if full > t_us:
                full -= 2**32
            self._t_pps_s = full / 1e6
        if fr.fpga_status & FpgaStatus.GYRO_MISSING:
            self.counters["fpga_gyro_missing"] += 1
        if self._last_counter is not None and (fr.gyro_counter - self._last_counter) % 256 != cfg.gyro_counter_step:
            self.counters["gyro_counter_jumps"] += 1
        self._last_counter = fr.gyro_counter
        # convert to SI [E: 6 MPYSP]
        dt = self.dtype
        if cfg.gyro_output == "rate":
            w = np.array(fr.gyro, dtype=dt) * dt(GYRO_RATE_LSB_DPS * DEG)
            dtheta = w * dt(self.T)
        else:
            dtheta = np.array(fr.gyro, dtype=dt) * dt(GYRO_ANGLE_LSB_DEG * DEG)
        volts = np.array(fr.accel, dtype=np.float64) * ADC_VOLTS_PER_LSB
        f_b = (volts / np.array(cfg.accel_volts_per_g) * G_STD).astype(dt)
        m.charge("imu_convert", c674x.flops(9, 0))

        if self.mode & NavMode.ALIGNING:
            self._align(t, f_b, res)
        else:
            self._navigate(t, dtheta, f_b, res)
        self._tick += 1
        ratio = int(round(cfg.imu_rate_hz / cfg.output_rate_hz))
        if self._tick % ratio == 0:
            frame = self._nav_output(t)
            m.charge("nav_output", 102 * 2 + 109 * 4 + c674x.CALL_OVERHEAD)  # pack + CRC [E]
            res.outputs.append((UART_HOST, frame, m._acc))  # noqa: SLF001
        res.cycles = m.end()
        # sliding one-second CPU load (what the firmware reads from its TSC)
        self._load_window.append((t, res.cycles))
        self._load_sum += res.cycles
        while self._load_window and self._load_window[0][0] <= t - 1.0:
            self._load_sum -= self._load_window.popleft()[1]
        return res

    # -- alignment ----------------------------------------------------------------------------
    def _align(self, t: float, f_b: np.ndarray, res: TickResult) -> None:
        cfg = self.cfg
        if self._align_t0 is None:
            self._align_t0 = t
        self._align_sum += f_b
        self._align_n += 1
        self.meter.charge("align_accumulate", c674x.flops(0, 3))
        if t - self._align_t0 < cfg.align_time_s or self._last_fix is None:
            return
        fm = self._align_sum / self._align_n
        g = float(np.linalg.norm(fm))
        # Coarse levelling: f^b = C_n^b [0, 0, g] = g [-cos(p) sin(r), sin(p), cos(p) cos(r)]
        pitch = math.asin(max(-1.0, min(1.0, float(fm[1]) / g)))
        roll = math.atan2(-float(fm[0]), float(fm[2]))
        yaw = yaw_from_heading(cfg.initial_heading_deg * DEG)
        self.meter.charge("coarse_align", c674x.mathlib("asinsp") + c674x.mathlib("atan2sp") + c674x.mathlib("sqrtsp"))
        fix = self._last_fix
        dt = self.dtype
        q = mat2q(a2mat(pitch, roll, yaw)).astype(dt)
        self.nav = NavState(q=q, v=np.zeros(3, dtype=dt), pos=np.array([fix.lat, fix.lon, fix.h]), t=t)
        self.P = np.diag(self._p0()).astype(dt)
        self.x = np.zeros(N_STATES, dtype=dt)
        self.mode = NavMode.NAVIGATING
        self._pos_pending = None
        self._vel_pending = None
        res.events.append({"event": "alignment_done", "t_fpga_s": t, "pitch_deg": pitch / DEG,
                           "roll_deg": roll / DEG, "heading_deg": cfg.initial_heading_deg,
                           "samples": self._align_n})

    def _p0(self) -> np.ndarray:
        cfg = self.cfg
        lat = self.nav.pos[0] if self.nav is not None else 0.0
        rm, rn = earth.radii(float(lat))
        lvl = cfg.accel_bias_sigma_mg * 1e-3  # rad, level error from accelerometer bias
        return np.array(
            [lvl**2, lvl**2, (cfg.initial_heading_sigma_deg * DEG) ** 2]
            + [0.1**2] * 3
            + [(cfg.gnss_pos_sigma_h_m / rm) ** 2, (cfg.gnss_pos_sigma_h_m / (rn * math.cos(lat))) ** 2,
               cfg.gnss_pos_sigma_v_m**2]
            + [(cfg.gyro_bias_sigma_deg_h * DPH) ** 2] * 3
            + [(cfg.accel_bias_sigma_mg * 1e-3 * G_STD) ** 2] * 3
        )

    def _qt(self) -> np.ndarray:
        """Continuous process-noise spectral densities (diagonal), per second."""
        cfg = self.cfg
        arw = cfg.gyro_arw_deg_rt_h * DEG / 60.0  # rad/sqrt(s)
        vrw = cfg.accel_noise_ug_rt_hz * 1e-6 * G_STD  # m/s^2/sqrt(Hz)
        tau = cfg.bias_corr_time_s
        qg = 2 * (cfg.gyro_bias_instability_deg_h * DPH) ** 2 / tau
        qa = 2 * (cfg.accel_bias_instability_mg * 1e-3 * G_STD) ** 2 / tau
        return np.array([arw**2] * 3 + [vrw**2] * 3 + [0.0] * 3 + [qg] * 3 + [qa] * 3)

    # -- navigation -------------------------------------------------------------------------
    def _navigate(self, t: float, dtheta: np.ndarray, f_b: np.ndarray, res: TickResult) -> None:
        cfg = self.cfg
        m = self.meter
        s = self.nav
        assert s is not None
        T = self.T
        dt = self.dtype
        # bias compensation, single-sample rotation compensation (algorithms.md 1.2 steps 1-2)
        phi_m = (dtheta - self.gyro_bias * dt(T)).astype(dt)
        dv = ((f_b - self.accel_bias) * dt(T)).astype(dt)
        dv_m = dv + dt(0.5) * cross3(phi_m, dv)
        m.charge("bias_coning", c674x.flops(12, 12))
        strapdown_step(s, phi_m, dv_m, T, dtype=dt)
        s.t = t
        # strapdown: DP sin/cos/sqrt for the Earth model (lat in float64), rv2q x2, normalize,
        # ~260 SP flops (algorithms in c6747_cycles.md section 4) [D/E]
        m.charge(
            "strapdown",
            c674x.mathlib("sindp") + c674x.mathlib("cosdp") + c674x.mathlib("sqrtdp") + 3 * c674x.mathlib("divdp")
            + c674x.dp_flops(12, 12)
            + 2 * (c674x.mathlib("sqrtsp") + c674x.mathlib("sinsp") + c674x.mathlib("cossp") + c674x.mathlib("divsp"))
            + c674x.mathlib("rsqrtsp")
            + c674x.flops(140, 120),
        )
        cbn = q2mat(s.q)
        self._fn_sum += cbn @ (f_b - self.accel_bias)
        self._fn_n += 1
        self._hist.append((t, s.pos.copy(), s.v.astype(np.float64)))
        # KF time update every N ticks
        if self._tick % cfg.kf_predict_every == 0:
            Tk = cfg.kf_predict_every * T
            fn = self._fn_sum / max(self._fn_n, 1)
            self._fn_sum[:] = 0.0
            self._fn_n = 0
            F = error_transition_matrix(cbn, s.v, s.pos, fn, dtype=dt)
            Phi = (np.eye(N_STATES, dtype=dt) + F * dt(Tk)).astype(dt)
            Qk = (self._qt() * Tk).astype(dt)
            self.x, self.P = kf_predict(self.x, self.P, Phi, Qk)
            m.charge(
                "kf_predict",
                c674x.flops(40, 40) + c674x.mathlib("divdp", 4)  # F elements
                + c674x.w_vec(225)  # Phi = I + F T
                + 2 * c674x.mat_mul(15, 15, 15) + c674x.mat_trans(15, 15) + c674x.w_vec(225) + c674x.flops(0, 225),
            )
        # GNSS measurement update
        pos, vel = self._pos_pending, self._vel_pending
        if pos is not None or vel is not None:
            self._pos_pending = self._vel_pending = None
            if pos is not None and t - pos.t_fpga_s > cfg.gnss_max_age_s:
                pos = None
            if vel is not None and t - vel[0] > cfg.gnss_max_age_s:
                vel = None
            if pos is not None or vel is not None:
                self._gnss_update(pos, vel, res)

    def _ins_at(self, t_meas: float) -> tuple[np.ndarray, np.ndarray]:
        """INS position (float64) and velocity at ``t_meas`` from the history ring (nearest tick)."""
        best = None
        for t, p, v in reversed(self._hist):
            if best is None or abs(t - t_meas) < abs(best[0] - t_meas):
                best = (t, p, v)
            if t < t_meas:
                break
        assert best is not None
        return best[1], best[2]

    def _gnss_update(self, fix: _GnssFix | None, vel: tuple[float, float, float] | None, res: TickResult) -> None:
        cfg = self.cfg
        m = self.meter
        s = self.nav
        assert s is not None
        dt = self.dtype
        meas: list[tuple[int, float, float, float]] = []
        if fix is not None:
            p_ins, _ = self._ins_at(fix.t_fpga_s)
            lat = float(p_ins[0])
            rm, rn = earth.radii(lat)
            rmh, rnh = rm + p_ins[2], rn + p_ins[2]
            cl = math.cos(lat)
            # Eq. 23-24: Z_p = [R_Mh dL, R_Nh cosL dlambda, dh], H_p = [0 diag(R_Mh, R_Nh cosL, 1) 0]
            meas += [
                (6, rmh, (p_ins[0] - fix.lat) * rmh, cfg.gnss_pos_sigma_h_m**2),
                (7, rnh * cl, (p_ins[1] - fix.lon) * rnh * cl, cfg.gnss_pos_sigma_h_m**2),
                (8, 1.0, p_ins[2] - fix.h, cfg.gnss_pos_sigma_v_m**2),
            ]
        if vel is not None:
            # Eq. 28-29, horizontal only: NMEA RMC carries no vertical velocity
            _, v_ins = self._ins_at(vel[0])
            meas.append((3, 1.0, v_ins[0] - vel[1], cfg.gnss_vel_sigma_h_mps**2))
            meas.append((4, 1.0, v_ins[1] - vel[2], cfg.gnss_vel_sigma_h_mps**2))
        innov = []
        for idx, hval, z, r in meas:
            h = np.zeros(N_STATES, dtype=dt)
            h[idx] = hval
            self.x, self.P, nu, sv = kf_update_scalar(self.x, self.P, h, z, r)
            innov.append(nu / math.sqrt(sv))
            m.charge("kf_update", 15 * c674x.dotprod(15) + c674x.dotprod(15) + c674x.mathlib("divsp")
                     + c674x.flops(3 * 225, 3 * 225) + c674x.flops(0, 225))
        self._feedback()
        m.charge("kf_feedback", c674x.flops(30, 30) + c674x.mathlib("sinsp") + c674x.mathlib("cossp"))
        self.counters["gnss_updates"] += 1
        self._last_gnss_update_t = s.t
        t_meas = fix.t_fpga_s if fix is not None else vel[0] if vel is not None else s.t
        res.events.append({"event": "gnss_update", "t_fpga_s": s.t, "t_meas_s": t_meas,
                           "n_meas": len(meas), "max_norm_innov": float(max(abs(v) for v in innov))})

    def _feedback(self) -> None:
        """Closed-loop correction of the navigation state; resets the error state to zero."""
        s = self.nav
        assert s is not None
        x = self.x.astype(np.float64)
        # attitude: C_b^n = (I + [phi x]) C_b^n'  ->  q <- rv2q(phi) (x) q
        s.q = qnormalize(qmul(rv2q(x[0:3]), s.q.astype(np.float64))).astype(self.dtype)
        s.v = (s.v - x[3:6]).astype(self.dtype)
        s.pos = s.pos - x[6:9]
        self.gyro_bias = (self.gyro_bias + x[IDX_GYRO]).astype(self.dtype)
        self.accel_bias = (self.accel_bias + x[IDX_ACC]).astype(self.dtype)
        self.x = np.zeros(N_STATES, dtype=self.dtype)

    # -- output ------------------------------------------------------------------------------
    def cpu_load_pct(self) -> float:
        """Busy share of the last second, % (cycles / clock)."""
        return 100.0 * self._load_sum / self.cfg.clock_hz

    def _nav_output(self, t: float) -> bytes:
        s = self.nav
        mode = self.mode
        if s is None:
            lat = lon = h = 0.0
            if self._last_fix is not None:
                lat, lon, h = self._last_fix.lat, self._last_fix.lon, self._last_fix.h
            vel = (0.0, 0.0, 0.0)
            roll = pitch = heading = 0.0
            sigma = (0.0,) * 9
        else:
            if t - self._last_gnss_update_t < 2.0:
                mode |= NavMode.GNSS_AIDED
            lat, lon, h = (float(x) for x in s.pos)
            vel = tuple(float(x) for x in s.v)
            pitch, roll, yaw = m2att(q2mat(s.q.astype(np.float64)))
            heading = heading_from_yaw(yaw)
            d = np.sqrt(np.maximum(np.diag(self.P).astype(np.float64), 0.0))
            rm, rn = earth.radii(lat)
            sigma = (
                d[0] / DEG, d[1] / DEG, d[2] / DEG, d[3], d[4], d[5],
                d[6] * (rm + h), d[7] * (rn + h) * math.cos(lat), d[8],
            )
            pitch, roll = pitch / DEG, roll / DEG
            heading = heading / DEG
        fix = self._last_fix
        n = NavSolution(
            seq=self._out_seq,
            time_s=t,
            lat_deg=lat / DEG,
            lon_deg=lon / DEG,
            height_m=h,
            vel_enu_mps=vel,  # type: ignore[arg-type]
            roll_deg=roll,
            pitch_deg=pitch,
            heading_deg=heading,
            sigma=sigma,
            mode=int(mode),
            gnss_status=fix.quality if fix is not None else 0,
            psns_status=0,
            cpu_load_pct=self.cpu_load_pct(),
            deadline_misses=self.deadline_misses,
        )
        self._out_seq += 1
        return encode_nav_solution(n)

