"""The DSP firmware's main loop as a pure, synchronous state machine.

The virtual DSP (``emulator.devices.dsp``) hosts one :class:`Firmware`: the UART ISRs hand bytes to
:meth:`Firmware.receive` (with the reception time of the last byte); the cyclic executive runs in
:meth:`Firmware.service`, driven by the FPGA's 200 Hz IMU frames, and returns per tick the bytes to
transmit and the cycles charged, which the DSP turns into time.

UART map (DESIGN.md section 2): UART0 host (navigation out, commands in), UART1 IMU frames from the
FPGA, UART2 PSNS (POLARIZATION_OBS / SOLAR_VECTOR / COMPASS frames), UART3 GNSS (the FPGA's 16550
core, read over EMIFA).

Mode manager (one state per tick)::

    COARSE_ALIGN --(levelling window done, GNSS fix, heading source ready)--> FINE_ALIGN
    FINE_ALIGN   --(fine_align_time_s of KF updates)-------------------------> NAVIGATE

Heading source of the coarse alignment (``alignment_heading``): ``"psns"`` = gravity + solar vector
(TRIAD, :mod:`firmware_model.alignment`), ``"config"`` = the configured heading, ``"auto"`` = PSNS
when a valid solar vector has arrived by the end of the levelling window, else the configured heading.

Tasks of one IMU tick (the whole tick is the task ``imu_tick``), each metered (``meter.table()``):

* ``imu``: decode the IMU frame, convert to SI, coarse-align accumulation or bias compensation,
  coning/sculling (two-sample with angle increments) and strapdown (:mod:`firmware_model.strapdown`);
* ``kf_predict`` (inside ``imu``): every ``kf_predict_every`` ticks, the filter's time update;
* ``gnss_update``: a fix is pending (1 Hz): Eqs. 23-30 at the PPS time of validity (2 s INS history);
* ``psns_update``: a PSNS frame is pending (frame rate): E-vectors -> K -> ``+-S^b``
  (:mod:`firmware_model.psns`), ephemeris (:mod:`firmware_model.sun`) at the exposure time, Eqs. 31-42;
* ``output``: NAV_SOLUTION at ``output_rate_hz``.

The filter itself is a variant (:mod:`firmware_model.filters`), picked by ``FirmwareConfig.filter``.
"""

from __future__ import annotations

import datetime as _dt
import math
from collections import deque
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from protocols.host import (
    FILTER_VARIANT_NAMES,
    Ack,
    AckResult,
    HostFormat,
    HostFrame,
    HostStatus,
    NavMode,
    RequestStatus,
    ResetFilter,
    SelectVariant,
    SetOutputRate,
    encode_ack,
    encode_status,
    nav_solution_frame,
)
from protocols.imu_frame import ACCEL_VOLTS_PER_G, ADC_VOLTS_PER_LSB, FpgaFrameFormat, FpgaStatus, ImuFrame, MagFrame
from protocols.nmea import Gga, NmeaFormat, Rmc
from protocols.ubx import NavPvt, UbxFormat
from protocols.psns import CompassFrame, PolarizationObs, PsnsFormat, PsnsStatus, SolarVectorFrame
from protocols.stim import GYRO_ANGLE_LSB_DEG, GYRO_RATE_LSB_DPS
from protocols.stream import StreamDecoder

from . import c674x, earth, psns, sun
from .alignment import level_from_specific_force, solar_heading_alignment
from .attitude import a2mat, heading_from_yaw, m2att, mat2q, q2mat, rv2q, yaw_from_heading
from .errors import FirmwareError
from .filters import FILTER_VARIANTS, GnssMeasurement, NavFilter, SolarObservation, UpdateReport
from .variants.params import VariantParams  # importing the package registers the issue-6 variants
from .psns_geometry import CameraGeometry
from .precision import rounder
from .strapdown import NavState, coning_sculling, strapdown_step_f32, strapdown_step_f64

__all__ = ["UART_HOST", "UART_IMU", "UART_PSNS", "UART_GNSS", "FirmwareConfig", "TickResult", "Firmware",
           "FirmwareState", "tick_kernel_cycles"]

UART_HOST, UART_IMU, UART_PSNS, UART_GNSS = 0, 1, 2, 3

DEG = math.pi / 180.0
G_STD = 9.80665
DPH = DEG / 3600.0  # deg/h in rad/s
_sqrt = math.sqrt


def tick_kernel_cycles(c: c674x.KernelCosts, nav_dp: bool = True) -> dict[str, int]:
    """Cycle charges of the per-tick kernels in the build's precision (branch-free code paths).

    * ``imu_decode``: CRC-16 over 36 bytes by table (~4 cycles/byte) + field unpack (integer work) [E].
    * ``imu_convert``: raw words to SI, 6 INT->float conversions + 6 multiplies [D].
    * ``coning1``: single-sample rotation compensation (one cross product) [D];
      ``coning2``: two-sample coning/sculling, 4 cross products and the 2/3, 1/2 scalings [D].
    * ``strapdown``: the Earth model in double precision whatever the build (latitude is a float64
      variable: sindp, cosdp, sqrtdp, 3 divdp and DP position update [S, R2]), two rv2q (sqrt, sin,
      cos, div), quaternion normalisation (rsqrt) and ~260 FLOPs (c6747_cycles.md section 4) [S/D];
      with ``nav_dp`` (the attitude quaternion and velocity accumulators in double precision,
      docs/decisions.md D-L.1) the rv2q, normalisation and FLOPs are charged at DP prices.
    * ``nav_output``: m2att (asin, 2 atan2), 9 sqrt for the sigmas, pack 102 bytes, CRC-16 over 109 [S/E].
    * ``level``, ``triad``: :mod:`firmware_model.alignment`.
    """
    from .alignment import level_cycles, triad_cycles

    return {
        "imu_decode": 36 * 4 + c674x.flops(12, 6),
        "imu_convert": c.flops(12, 6),
        "coning1": c.flops(12, 12),
        "coning2": c.flops(30, 30),
        "strapdown": (c674x.mathlib("sindp") + c674x.mathlib("cosdp") + c674x.mathlib("sqrtdp")
                      + 3 * c674x.mathlib("divdp") + c674x.dp_flops(12, 12)
                      + (2 * (c674x.mathlib("sqrtdp") + c674x.mathlib("sindp") + c674x.mathlib("cosdp")
                              + c674x.mathlib("divdp")) + c674x.mathlib("rsqrtdp") + c674x.dp_flops(140, 120)
                         if nav_dp else
                         2 * (c.math("sqrt") + c.math("sin") + c.math("cos") + c.math("div"))
                         + c.math("rsqrt") + c.flops(140, 120))),
        "nav_output": c.math("asin") + 2 * c.math("atan2") + 9 * c.math("sqrt") + 102 * 2 + 109 * 4 + c674x.CALL_OVERHEAD,
        "level": level_cycles(c),
        "triad": triad_cycles(c),
        "mounting": c.flops(9, 6),
        "normalise": c.math("rsqrt") + c.flops(6, 2),
    }


#: Firmware version in STATUS (major << 8 | minor).
FW_VERSION = 0x0105
_PPS_VALID = int(FpgaStatus.PPS_VALID)
_GNSS_AIDED, _PSNS_AIDED, _DEGRADED = int(NavMode.GNSS_AIDED), int(NavMode.PSNS_AIDED), int(NavMode.DEGRADED)
_GYRO_MISSING = int(FpgaStatus.GYRO_MISSING)


class FirmwareState:
    """Mode-manager states."""

    COARSE_ALIGN = "coarse_align"
    FINE_ALIGN = "fine_align"
    NAVIGATE = "navigate"


@dataclass
class FirmwareConfig:
    """Firmware build/run-time parameters (units in the names)."""

    clock_hz: float = 300e6
    imu_rate_hz: float = 200.0
    gyro_output: str = "rate"  # "rate" (2^-14 deg/s) or "angle" (2^-21 deg per sample)
    gyro_counter_step: int = 10
    coning_samples: int = 0  # 0: automatic (2 with angle increments, 1 with rate output), or 1 / 2
    kf_predict_every: int = 20
    output_rate_hz: float = 100.0
    align_time_s: float = 2.0
    alignment_heading: str = "auto"  # "auto", "psns" or "config"
    psns_align_timeout_s: float = 10.0
    psns_heading_sigma_deg: float = 0.5
    fine_align_time_s: float = 60.0
    initial_heading_deg: float = 0.0
    initial_heading_sigma_deg: float = 1.0
    precision: str = "float32"
    #: Precision of the strapdown's attitude quaternion and velocity accumulators (D-L.1): float64 keeps
    #: the 200 Hz increments (1e-7 rad of Earth rate per step) from being rounded away in float32.
    nav_state_precision: str = "float64"
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
    # GNSS measurement noise (1 sigma per axis)
    gnss_pos_sigma_h_m: float = 4.08
    gnss_pos_sigma_v_m: float = 7.5
    gnss_vel_sigma_h_mps: float = 0.041
    gnss_vel_sigma_v_mps: float = 0.1
    gnss_max_age_s: float = 1.5
    # PSNS
    psns_enabled: bool = True
    psns_baud: int = 115200  # DSP UART2 baud (for the exposure time tag, C1)
    psns_bits_per_byte: int = 10
    psns_sigma_deg: float = 0.1  # solar-vector noise per axis, 1 sigma
    psns_dop_min: float = 0.05
    psns_quality_max: float = 0.2
    psns_min_sun_elevation_deg: float = 5.0
    psns_gate_chi2: float = 16.27  # chi-square(3), alpha = 0.001 (algorithms.md 5.2)
    psns_max_age_s: float = 1.0
    camera: CameraGeometry = field(default_factory=CameraGeometry)
    #: multi-unit compass mountings C_u^b (n, 3, 3) as the firmware knows them; None: the default 9 units
    compass_mountings: np.ndarray | None = None
    #: misalignment (E, N, U; deg, C_b^{n'} = (I - [phi x]) C_b^n) added to the coarse alignment: reproduces a
    #: paper's initial condition (e.g. Ge et al.: -0.9, 0.6, 0.7 deg)
    initial_misalignment_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)
    #: parameters of the issue-6 variants and their mode manager
    variants: VariantParams = field(default_factory=VariantParams)

    def __post_init__(self) -> None:
        if self.precision not in ("float32", "float64"):
            raise FirmwareError(f"precision must be float32 or float64, got {self.precision!r}")
        if self.nav_state_precision not in ("float32", "float64"):
            raise FirmwareError(f"nav_state_precision must be float32 or float64, got {self.nav_state_precision!r}")
        if self.gyro_output not in ("rate", "angle"):
            raise FirmwareError(f"gyro_output must be 'rate' or 'angle', got {self.gyro_output!r}")
        if self.filter not in FILTER_VARIANTS:
            raise FirmwareError(f"filter variant {self.filter!r} is not available in this firmware build "
                                f"(available: {', '.join(sorted(FILTER_VARIANTS))})")
        if self.alignment_heading not in ("auto", "psns", "config"):
            raise FirmwareError(f"alignment_heading must be auto, psns or config, got {self.alignment_heading!r}")
        if self.coning_samples not in (0, 1, 2):
            raise FirmwareError(f"coning_samples must be 0 (auto), 1 or 2, got {self.coning_samples}")
        ratio = self.imu_rate_hz / self.output_rate_hz
        if ratio < 1 or abs(ratio - round(ratio)) > 1e-9:
            raise FirmwareError("output_rate_hz must divide imu_rate_hz")
        if self.kf_predict_every % self.subsamples:
            raise FirmwareError("kf_predict_every must be a multiple of the coning subsamples")

    @property
    def subsamples(self) -> int:
        """IMU samples per strapdown update (two-sample coning/sculling needs increments)."""
        if self.coning_samples:
            return self.coning_samples
        return 2 if self.gyro_output == "angle" else 1


@dataclass
class TickResult:
    """What one run of the cyclic executive produced.

    ``cycles`` is the total charged; each output is ``(uart, bytes, cycles_at_emit)``.
    """

    t_fpga_s: float
    cycles: int
    outputs: list[tuple[int, bytes, int]] = field(default_factory=list)
    events: list[dict[str, Any]] = field(default_factory=list)


class Firmware:
    """The firmware (see module docstring). Interface to the DSP host (CONTRACTS C3):
    :meth:`receive`, :meth:`service`, :meth:`note_deadline_miss`, :attr:`meter`, :attr:`counters`,
    :meth:`decoder_stats`."""

    def __init__(self, cfg: FirmwareConfig | None = None) -> None:
        self.cfg = cfg = cfg or FirmwareConfig()
        self.dtype = np.float32 if cfg.precision == "float32" else np.float64
        #: dtype of the strapdown state (q, v); position is always float64
        self.nav_dtype = np.float64 if cfg.nav_state_precision == "float64" else self.dtype
        self.meter = c674x.CycleMeter(cfg.clock_hz, cfg.imu_rate_hz)
        self.cost = c674x.KernelCosts(cfg.precision)
        self._cyc = tick_kernel_cycles(self.cost, nav_dp=self.nav_dtype is np.float64)
        self._cyc_decode, self._cyc_convert = self._cyc["imu_decode"], self._cyc["imu_convert"]
        self._cyc_coning1, self._cyc_strapdown = self._cyc["coning1"], self._cyc["strapdown"]
        self.T = 1.0 / cfg.imu_rate_hz
        self._nsub = cfg.subsamples
        # IMU conversion constants in the working precision (Python floats holding dtype values)
        dt = self.dtype
        lsb = GYRO_RATE_LSB_DPS * DEG * self.T if cfg.gyro_output == "rate" else GYRO_ANGLE_LSB_DEG * DEG
        self._gyro_k = float(dt(lsb))
        self._T_w = float(dt(self.T))
        self._kv = ADC_VOLTS_PER_LSB * G_STD
        self._round3 = rounder(dt, 3)
        self._pack6, self._unpack6 = rounder(dt, 6).pack, rounder(dt, 6).unpack
        self._bias_cache: tuple[Any, Any, tuple[float, ...]] = (None, None, ())
        self._out_every = int(round(cfg.imu_rate_hz / cfg.output_rate_hz))
        self._dec_imu = StreamDecoder([FpgaFrameFormat()])
        self._dec_gnss = StreamDecoder([NmeaFormat(), UbxFormat()])
        self._dec_host = StreamDecoder([HostFormat()])
        self._pending_cmd: deque[Any] = deque(maxlen=16)
        self.last_mag: MagFrame | None = None
        self._dec_psns = StreamDecoder([PsnsFormat()])
        self._pending_imu: deque[ImuFrame] = deque()
        self._pending_psns: deque[tuple[float, Any]] = deque(maxlen=8)
        self._rx_other: dict[int, int] = {}
        # time keeping (FPGA time base; UTC from GNSS)
        self._t_last_us: int | None = None
        self._t_epoch_us = 0
        self._t_pps_s: float | None = None
        self._pps_count: int | None = None
        self._last_counter: int | None = None
        self._utc_days_ref: float | None = None  # Grena days (UT) at _utc_t_ref
        self._utc_t_ref = 0.0
        self._date: _dt.date | None = None
        # mode manager
        self.state = FirmwareState.COARSE_ALIGN
        self.mode = NavMode.ALIGNING
        self._align_sum = np.zeros(3)
        self._align_n = 0
        self._align_t0: float | None = None
        self._align_sun: list[SolarObservation] = []
        self._t_aligned = 0.0
        self._t_last_predict = 0.0
        # navigation
        self.nav: NavState | None = None
        self.filter: NavFilter = self._new_filter(cfg.filter)
        self._mag_hist: deque[tuple[float, tuple[int, int, int]]] = deque(maxlen=128)  # (t_sample_s, field)
        self._tick = 0
        self._sub: list[tuple[np.ndarray, np.ndarray]] = []
        self._fn_sum = [0.0, 0.0, 0.0]  # sum of f^n over the KF interval (Python floats, float64)
        self._fn_n = 0
        self._hist: deque[tuple[float, tuple[float, ...]]] = deque(maxlen=int(2 * cfg.imu_rate_hz))
        self._gnss_pending: GnssMeasurement | None = None
        self._last_fix: tuple[float, float, float, int] | None = None
        self._last_gnss_update_t = -1e9
        self._last_psns_t = -1e9
        self._last_psns_reject_t = -1e9
        self._out_seq = 0
        self.deadline_misses = 0
        self._load_window: deque[tuple[float, int]] = deque()
        self._load_max = 0
        self._next_status_t = 1.0
        self._status_seq = 0
        self._heading_sigma0 = cfg.initial_heading_sigma_deg * DEG
        self.counters = {"imu_frames": 0, "gnss_fixes": 0, "gnss_updates": 0, "gyro_counter_jumps": 0,
                         "fpga_gyro_missing": 0, "imu_time_gaps": 0, "psns_frames": 0, "psns_solutions": 0,
                         "psns_updates": 0, "psns_rejected": 0, "psns_invalid": 0, "psns_sun_low": 0,
                         "psns_dropped": 0, "compass_frames": 0, "mag_frames": 0,
                         "gnss_pvt": 0, "commands_accepted": 0, "commands_rejected": 0, "commands_dropped": 0,
                         "status_frames": 0}

    # -- ISR side -------------------------------------------------------------------------------
    def receive(self, uart: int, data: bytes, t_rx_s: float | None = None) -> None:
        """Bytes received on ``uart`` (the ISR copies the 16550 FIFO into the ring buffer).

        ``t_rx_s`` is the DSP's time (s, FPGA time base) when the last byte arrived, as the ISR
        reads it from the time-stamp counter; PSNS frames are time-tagged from it (C1).
        """
        if uart == UART_IMU:
            for f in self._dec_imu.feed(data):
                if isinstance(f, ImuFrame):
                    self._pending_imu.append(f)
                else:  # MAG frame (same FPGA framing); kept for the variants that use a magnetometer
                    self.last_mag = f
                    self.counters["mag_frames"] += 1
                    if not f.status & 0x01:  # not over range: into the history a variant may average
                        self._mag_hist.append((self._unwrap_near(f.t_sample_us) / 1e6, f.field))
        elif uart == UART_GNSS:
            for s in self._dec_gnss.feed(data):
                if isinstance(s, NavPvt):
                    self._on_nav_pvt(s)
                else:
                    self._on_nmea(s)
        elif uart == UART_HOST:
            for c in self._dec_host.feed(data):
                if len(self._pending_cmd) == self._pending_cmd.maxlen:
                    self.counters["commands_dropped"] += 1
                self._pending_cmd.append(c)
        elif uart == UART_PSNS:
            frames = self._dec_psns.feed(data)
            if frames:
                t_end = t_rx_s if t_rx_s is not None else self._now_s()
                # the last frame ended with the chunk; earlier ones ended earlier by the later frames' bytes
                byte_s = self.cfg.psns_bits_per_byte / self.cfg.psns_baud
                tags = []
                for f in reversed(frames):
                    tags.append((t_end, f))
                    t_end -= _psns_frame_len(f) * byte_s
                for tag in reversed(tags):
                    if len(self._pending_psns) == self._pending_psns.maxlen:
                        self.counters["psns_dropped"] += 1  # the solve cannot keep up: oldest frame lost
                    self._pending_psns.append(tag)
        else:
            self._rx_other[uart] = self._rx_other.get(uart, 0) + len(data)

    def decoder_stats(self) -> dict[str, dict[str, Any]]:
        return {"uart0": self._dec_host.stats.as_dict(), "uart1": self._dec_imu.stats.as_dict(),
                "uart2": self._dec_psns.stats.as_dict(), "uart3": self._dec_gnss.stats.as_dict()}

    # -- services for the filter variants (filters.FilterHost) -----------------------------------------
    def _new_filter(self, name: str) -> NavFilter:
        flt = FILTER_VARIANTS[name](self.cfg, self.meter, self.dtype)
        flt.attach(self)
        return flt

    def ins_at(self, t_meas: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """INS position, velocity and attitude quaternion at ``t_meas`` (2 s history, nearest entry)."""
        return self._ins_at(t_meas)

    def now_s(self) -> float:
        """FPGA time of the latest IMU frame, s."""
        return self._now_s()

    def mag_mean_nt(self, t_center_s: float, half_window_s: float = 0.025) -> tuple[np.ndarray, int] | None:
        """Mean MAG field (nT, body axes) of the frames sampled within ``t_center_s +- half_window_s``
        (FPGA time; e.g. a camera exposure) and their number; None when there is none."""
        acc = [0, 0, 0]
        n = 0
        for ts, fld in reversed(self._mag_hist):
            if ts < t_center_s - half_window_s:
                break
            if ts <= t_center_s + half_window_s:
                acc[0] += fld[0]
                acc[1] += fld[1]
                acc[2] += fld[2]
                n += 1
        self.meter.charge("mag_mean", c674x.flops(3, 3 * max(n, 1)) + len(self._mag_hist))
        if n == 0:
            return None
        return np.array(acc, dtype=np.float64) * (0.1 / n), n  # MAG words are 0.1 nT

    def _unwrap_near(self, t_us: int) -> int:
        """A 32-bit FPGA time stamp near the latest IMU time, unwrapped like :meth:`_unwrap_us`."""
        base = self._t_epoch_us + (self._t_last_us or 0)
        full = (base & ~0xFFFFFFFF) | (t_us & 0xFFFFFFFF)
        if full - base > 2**31:
            full -= 2**32
        elif base - full > 2**31:
            full += 2**32
        return full

    def note_deadline_miss(self) -> None:
        """Called by the host DSP when a tick started after its deadline."""
        self.deadline_misses += 1

    # -- main loop --------------------------------------------------------------------------------
    def service(self) -> list[TickResult]:
        """Run the cyclic executive over every pending IMU frame."""
        out: list[TickResult] = []
        while self._pending_imu:
            out.append(self._imu_tick(self._pending_imu.popleft()))
        return out

    # -- time -------------------------------------------------------------------------------------
    def _now_s(self) -> float:
        if self._t_last_us is None:
            return 0.0
        return (self._t_epoch_us + self._t_last_us) / 1e6

    def _unwrap_us(self, t_us: int) -> int:
        if self._t_last_us is not None and t_us < self._t_last_us and self._t_last_us - t_us > 2**31:
            self._t_epoch_us += 2**32
        self._t_last_us = t_us
        return self._t_epoch_us + t_us

    def utc_days(self, t_fpga_s: float) -> float | None:
        """Grena days (UT since 2060-01-01) at FPGA time ``t_fpga_s``, once GNSS gave date and time."""
        if self._utc_days_ref is None:
            return None
        return self._utc_days_ref + (t_fpga_s - self._utc_t_ref) / 86400.0

    # -- GNSS (ISR side: parse and stage) -------------------------------------------------------------
    def _on_nmea(self, s: Any) -> None:
        """GGA gives a position fix, RMC a horizontal velocity and the date; both valid at the last PPS."""
        t_meas = self._t_pps_s if self._t_pps_s is not None else self._now_s()
        if isinstance(s, Gga):
            if s.quality == 0 or s.lat_deg is None or s.lon_deg is None or s.altitude_msl_m is None:
                return
            pos = (s.lat_deg * DEG, s.lon_deg * DEG, s.altitude_msl_m + (s.geoid_sep_m or 0.0))
            self.counters["gnss_fixes"] += 1
            m = self._stage_gnss(t_meas)
            m.pos, m.quality = pos, s.quality
            self._last_fix = (pos[0], pos[1], pos[2], s.quality)
            if s.time_utc is not None and self._date is not None:
                self._set_utc(t_meas, self._date, s.time_utc)
        elif isinstance(s, Rmc):
            if s.date is not None:
                self._date = s.date
                if s.time_utc is not None:
                    self._set_utc(t_meas, s.date, s.time_utc)
            if not s.valid or s.speed_mps is None:
                return
            c = (s.course_deg or 0.0) * DEG
            m = self._stage_gnss(t_meas)
            m.vel = np.array([s.speed_mps * math.sin(c), s.speed_mps * math.cos(c), 0.0])
            m.vel_up = False

    def _on_nav_pvt(self, p: NavPvt) -> None:
        """UBX NAV-PVT: position, full 3-D velocity (velD) and UTC, valid at the PPS edge + ``nano``."""
        self.counters["gnss_pvt"] += 1
        t_pps = self._t_pps_s if self._t_pps_s is not None else self._now_s()
        t_meas = t_pps + p.nano * 1e-9 if abs(p.nano) < 500_000_000 else t_pps
        if p.valid & 0x03 == 0x03:  # validDate | validTime
            date = _dt.date(p.year, p.month, p.day)
            self._date = date
            self._set_utc(t_pps, date, _dt.time(p.hour, p.min, p.sec))
        if not p.flags & 0x01 or p.fixType not in (3, 4):  # gnssFixOK and a 3-D (or GNSS + DR) fix
            return
        quality = {1: 5, 2: 4}.get((p.flags >> 6) & 0x03, 2 if p.flags & 0x02 else 1)  # RTK float/fixed, DGNSS
        pos = (p.lat * 1e-7 * DEG, p.lon * 1e-7 * DEG, p.height * 1e-3)
        m = self._stage_gnss(t_meas)
        m.pos, m.quality = pos, quality
        m.vel = np.array([p.velE * 1e-3, p.velN * 1e-3, -p.velD * 1e-3])
        m.vel_up = True
        self.counters["gnss_fixes"] += 1
        self._last_fix = (pos[0], pos[1], pos[2], quality)

    def _stage_gnss(self, t_meas: float) -> GnssMeasurement:
        m = self._gnss_pending
        if m is None or abs(m.t_fpga_s - t_meas) > 1e-6:
            m = self._gnss_pending = GnssMeasurement(t_fpga_s=t_meas)
        return m

    def _set_utc(self, t_meas: float, date: _dt.date, tm: _dt.time) -> None:
        if self._now_s() - t_meas > 1.5:
            # no PPS for this epoch (an outage: the receiver still sends its clock's time without a fix or a
            # pulse): tagging it to the last, stale PPS edge would make UTC gain a second per second
            self.counters["utc_stale_pps"] = self.counters.get("utc_stale_pps", 0) + 1
            return
        hour = tm.hour + tm.minute / 60.0 + (tm.second + tm.microsecond * 1e-6) / 3600.0
        self._utc_days_ref = sun.grena_days(date.year, date.month, date.day, hour)
        self._utc_t_ref = t_meas

    # -- IMU tick -----------------------------------------------------------------------------------
    def _imu_tick(self, fr: ImuFrame) -> TickResult:
        cfg = self.cfg
        m = self.meter
        m.begin("imu_tick", self.T)
        m.begin("imu", self.T)
        m.charge("imu_decode", self._cyc_decode)
        t_us = self._unwrap_us(fr.t_trigger_us)
        t = t_us / 1e6
        res = TickResult(t, 0)
        self.counters["imu_frames"] += 1
        if fr.fpga_status & _PPS_VALID and fr.pps_count != self._pps_count:
            self._pps_count = fr.pps_count
            full = (t_us & ~0xFFFFFFFF) | fr.t_pps_us
            if full > t_us:
                full -= 2**32
            self._t_pps_s = full / 1e6
        if fr.fpga_status & _GYRO_MISSING:
            self.counters["fpga_gyro_missing"] += 1
        if self._last_counter is not None and (fr.gyro_counter - self._last_counter) % 256 != cfg.gyro_counter_step:
            self.counters["gyro_counter_jumps"] += 1
        self._last_counter = fr.gyro_counter
        # raw words to SI: 6 INTSP + 6 MPYSP [D] (Python floats rounded to the working precision,
        # firmware_model.precision): gyro words (s24, exact) times the LSB; ADC codes to m/s^2
        g = fr.gyro
        a = fr.accel
        kv, vpg = self._kv, self.cfg.accel_volts_per_g
        r3 = self._round3
        f_b = r3.unpack(r3.pack(a[0] * kv / vpg[0], a[1] * kv / vpg[1], a[2] * kv / vpg[2]))
        m.charge("imu_convert", self._cyc_convert)

        if self.state == FirmwareState.COARSE_ALIGN:
            self._align(t, np.array(f_b, dtype=self.dtype), res)
            m.end()
        else:
            self._mechanize(t, g, f_b)
            if self._tick % cfg.kf_predict_every == 0 and self._fn_n:
                m.begin("kf_predict", cfg.kf_predict_every * self.T)
                n = self._fn_n
                fn = np.array([x / n for x in self._fn_sum])
                self._fn_sum = [0.0, 0.0, 0.0]
                self._fn_n = 0
                Tk = t - self._t_last_predict  # the first interval after alignment may be shorter
                self._t_last_predict = t
                self.filter.predict(self.nav, fn, Tk)  # type: ignore[arg-type]
                m.end()
            m.end()
            self._measurement_tasks(t, res)
            if self.state == FirmwareState.FINE_ALIGN and t - self._t_aligned >= cfg.fine_align_time_s:
                self.state = FirmwareState.NAVIGATE
                self.mode = NavMode.NAVIGATING
                res.events.append({"event": "fine_alignment_done", "t_fpga_s": t})
        if self.state == FirmwareState.COARSE_ALIGN:
            self._drain_psns_for_alignment(t)
        self._tick += 1
        if self._out_every and self._tick % self._out_every == 0:
            m.begin("output", self._out_every * self.T)
            frame = self._nav_output(t)
            m.charge("nav_output", self._cyc["nav_output"])
            m.end()
            res.outputs.append((UART_HOST, frame, m.elapsed))
        ev = self.filter.drain_events()
        if ev:
            res.events.extend(ev)
            self.counters.update(self.filter.counters)
        if self._pending_cmd or t >= self._next_status_t:
            m.begin("host", 1.0)
            self._host_task(t, res)
            m.end()
        res.cycles = m.end()
        # worst tick of the last second (sliding maximum) and since start, for NAV_SOLUTION / STATUS
        while self._load_window and self._load_window[-1][1] <= res.cycles:
            self._load_window.pop()
        self._load_window.append((t, res.cycles))
        while self._load_window[0][0] <= t - 1.0:
            self._load_window.popleft()
        self._load_max = max(self._load_max, res.cycles)
        return res

    # -- coarse alignment ---------------------------------------------------------------------------
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
        lat, lon, h, _ = self._last_fix
        source = "config"
        heading_sigma = cfg.initial_heading_sigma_deg * DEG
        cbn = None
        want_psns = cfg.psns_enabled and cfg.alignment_heading in ("auto", "psns")
        if want_psns and self._align_sun and self.utc_days(t) is not None:
            cbn, sun_el = self._solar_alignment(fm, lat, lon)
            if cbn is not None:
                source = "psns"
                heading_sigma = cfg.psns_heading_sigma_deg * DEG
        if cbn is None and cfg.psns_enabled and cfg.alignment_heading == "psns" \
                and t - self._align_t0 < cfg.align_time_s + cfg.psns_align_timeout_s:
            return  # wait for a solar vector
        pitch, roll = level_from_specific_force(fm)
        self.meter.charge("coarse_level", self._cyc["level"])
        if cbn is None:
            cbn = a2mat(pitch, roll, yaw_from_heading(cfg.initial_heading_deg * DEG))
        if any(cfg.initial_misalignment_deg):  # C_b^{n'} = rv2m(-phi) C_b^n: the computed frame is off by phi
            cbn = q2mat(rv2q(-np.asarray(cfg.initial_misalignment_deg, dtype=np.float64) * DEG)) @ cbn
        dt = self.dtype
        nd = self.nav_dtype
        self.nav = NavState(q=mat2q(cbn).astype(nd), v=np.zeros(3, dtype=nd), pos=np.array([lat, lon, h]), t=t,
                            a_prev=np.zeros(3, dtype=nd))
        self.filter.initialise(self.nav, heading_sigma)
        self._heading_sigma0 = heading_sigma
        self.state = FirmwareState.FINE_ALIGN
        self.mode = NavMode.NAVIGATING | NavMode.ALIGNING
        self._t_aligned = t
        self._t_last_predict = t
        self._gnss_pending = None
        p, r, y = m2att(cbn)
        res.events.append({"event": "alignment_done", "t_fpga_s": t, "pitch_deg": p / DEG, "roll_deg": r / DEG,
                           "heading_deg": heading_from_yaw(y) / DEG, "heading_source": source,
                           "samples": self._align_n, "solar_vectors": len(self._align_sun)})

    def _drain_psns_for_alignment(self, t: float) -> None:
        """During coarse alignment PSNS frames are solved and kept for the TRIAD heading."""
        while self._pending_psns:
            t_rx, f = self._pending_psns.popleft()
            self.meter.begin("psns_update", 0.0)
            obs = self._psns_observation(t_rx, f)
            self.meter.end()
            if obs is not None and self._align_t0 is not None and obs.t_exposure_s >= self._align_t0 - 1.0:
                self._align_sun.append(obs)
                del self._align_sun[:-32]

    def _solar_alignment(self, f_b: np.ndarray, lat: float, lon: float) -> tuple[np.ndarray | None, float]:
        """TRIAD from gravity and the mean solar vector of the levelling window."""
        up = f_b / np.linalg.norm(f_b)
        acc = np.zeros(3)
        t_mean = 0.0
        for o in self._align_sun:
            s = o.s_b.astype(np.float64)
            acc += s if float(s @ up) >= 0 else -s
            t_mean += o.t_exposure_s
        t_mean /= len(self._align_sun)
        days = self.utc_days(t_mean)
        assert days is not None
        s_n = sun.sun_vector_enu(days, lat, lon, dtype=self.dtype).astype(np.float64)
        self.meter.charge("sun_ephemeris", sun.ephemeris_cycles())
        el = math.asin(max(-1.0, min(1.0, float(s_n[2]))))
        if el < self.cfg.psns_min_sun_elevation_deg * DEG or el > 80.0 * DEG:
            return None, el
        try:
            cbn, _ = solar_heading_alignment(f_b, acc / np.linalg.norm(acc), s_n)
        except ValueError:
            return None, el
        self.meter.charge("triad", self._cyc["triad"])
        return cbn, el

    # -- navigation ---------------------------------------------------------------------------------
    def _mechanize(self, t: float, gyro: tuple[int, int, int], f_b: tuple[float, float, float]) -> None:
        """Bias compensation, coning/sculling and one strapdown step per ``subsamples`` IMU samples.

        ``gyro``: the raw STIM words; ``f_b``: specific force (m/s^2, body, in the working precision).
        Every operation in the working precision (``self._round*``, :mod:`firmware_model.precision`).
        """
        m = self.meter
        s = self.nav
        assert s is not None
        k, T_w = self._gyro_k, self._T_w
        pack6, unpack6 = self._pack6, self._unpack6  # round 6 values to the working precision
        # dtheta = gyro * LSB, dv = f_b * T
        dth_x, dth_y, dth_z, dv_x, dv_y, dv_z = unpack6(pack6(gyro[0] * k, gyro[1] * k, gyro[2] * k,
                                                              f_b[0] * T_w, f_b[1] * T_w, f_b[2] * T_w))
        if self._nsub == 1:
            flt = self.filter
            bias = self._bias_cache
            if bias[0] is not flt.gyro_bias or bias[1] is not flt.accel_bias:
                bias = self._update_bias_cache()
            gb_x, gb_y, gb_z, ab_x, ab_y, ab_z = bias[2]
            px, py, pz, ux, uy, uz = unpack6(pack6(dth_x - gb_x, dth_y - gb_y, dth_z - gb_z,
                                                   dv_x - ab_x, dv_y - ab_y, dv_z - ab_z))  # phi_m, dv_c
            # single-sample rotation compensation dv_m = dv_c + 1/2 phi_m x dv_c (algorithms.md 1.2, step 1)
            c0, c1, c2, c3, c4, c5 = unpack6(pack6(py * uz, pz * ux, px * uy, pz * uy, px * uz, py * ux))
            r3 = self._round3
            c0, c1, c2 = r3.unpack(r3.pack(c0 - c3, c1 - c4, c2 - c5))
            phi_m = (px, py, pz)
            dv_m = r3.unpack(r3.pack(ux + 0.5 * c0, uy + 0.5 * c1, uz + 0.5 * c2))
            m.charge("coning_sculling", self._cyc_coning1)
            Tm = self.T
        else:
            dt = self.dtype
            self._sub.append((np.array((dth_x, dth_y, dth_z), dtype=dt), np.array((dv_x, dv_y, dv_z), dtype=dt)))
            if len(self._sub) < self._nsub:
                return
            th = np.stack([x[0] for x in self._sub])
            vv = np.stack([x[1] for x in self._sub])
            self._sub.clear()
            phi, dvm = coning_sculling(th, vv)
            Tm = self.T * self._nsub
            flt = self.filter
            phi_m = (phi - flt.gyro_bias * dt(Tm)).astype(dt).tolist()
            dv_m = (dvm - flt.accel_bias * dt(Tm)).astype(dt).tolist()
            m.charge("coning_sculling", self._cyc["coning2"])
        if self.nav_dtype is np.float64:
            strapdown_step_f64(s, phi_m, dv_m, Tm)
        else:
            strapdown_step_f32(s, phi_m, dv_m, Tm)
        s.t = t
        m.charge("strapdown", self._cyc_strapdown)
        # specific force in n of the step, averaged for the KF's F (Eq. 17)
        x = s.as_floats()
        acc = self._fn_sum
        acc[0] += x[13]
        acc[1] += x[14]
        acc[2] += x[15]
        self._fn_n += 1
        self._hist.append((t, x))  # the state as floats (q, v, pos, ...; NavState.as_floats)

    def _update_bias_cache(self) -> tuple[Any, Any, tuple[float, ...]]:
        """``(gyro_bias, accel_bias, gyro_bias * T + accel_bias * T)``: the bias increments in the working
        precision, recomputed when the filter's estimates change (feedback replaces the arrays); the same
        products every tick otherwise."""
        flt = self.filter
        gb, ab = flt.gyro_bias, flt.accel_bias
        T_w = self.dtype(self.T)
        self._bias_cache = (gb, ab, tuple((gb * T_w).tolist() + (ab * T_w).tolist()))
        return self._bias_cache

    def _ins_at(self, t_meas: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """INS position (float64), velocity and attitude quaternion at ``t_meas`` (nearest history entry)."""
        best = None
        for e in reversed(self._hist):
            if best is None or abs(e[0] - t_meas) < abs(best[0] - t_meas):
                best = e
            if e[0] < t_meas:
                break
        assert best is not None
        x, nd = best[1], self.nav_dtype
        return np.array(x[7:10]), np.array(x[4:7], dtype=nd), np.array(x[0:4], dtype=nd)

    def _measurement_tasks(self, t: float, res: TickResult) -> None:
        cfg = self.cfg
        m = self.meter
        updated = False
        g = self._gnss_pending
        if g is not None and (g.pos is not None or g.vel is not None) and self._hist:
            self._gnss_pending = None
            if t - g.t_fpga_s <= cfg.gnss_max_age_s:
                m.begin("gnss_update", 1.0)
                p_ins, v_ins, _ = self._ins_at(g.t_fpga_s)
                rep = self.filter.update_gnss(self.nav, g, p_ins, v_ins)  # type: ignore[arg-type]
                m.end()
                if rep.accepted:  # a variant may refuse a fix (federated: chi-square isolation)
                    self.counters["gnss_updates"] += 1
                    self._last_gnss_update_t = t
                    updated = True
                    res.events.append({"event": "gnss_update", "t_fpga_s": t, "t_meas_s": g.t_fpga_s,
                                       "n_meas": rep.n_rows, "max_norm_innov": rep.max_norm_innov})
        while self._pending_psns and self._hist:
            t_rx, f = self._pending_psns.popleft()
            m.begin("psns_update", 0.0)
            rep = self._psns_update(t, t_rx, f)
            m.end()
            if rep is not None:
                if rep.accepted:
                    updated = True
                    self.counters["psns_updates"] += 1
                    self._last_psns_t = t
                else:
                    self.counters["psns_rejected"] += 1
                    if t - self._last_psns_reject_t >= 1.0:  # at most one event per second
                        res.events.append({"event": "psns_rejected", "t_fpga_s": t, "measurement": rep.kind,
                                           "norm_innov": rep.max_norm_innov, **(rep.detail or {})})
                    self._last_psns_reject_t = t
        if updated:
            m.begin("kf_feedback", 0.0)
            self.filter.feedback(self.nav)  # type: ignore[arg-type]
            m.end()

    # -- PSNS -------------------------------------------------------------------------------------------
    def _psns_frame_in(self, t_rx: float, f: Any) -> float:
        """Count and charge a decoded PSNS frame; return its mid-exposure time (C1, D-5.8)."""
        cfg = self.cfg
        self.counters["psns_frames"] += 1
        if isinstance(f, CompassFrame):
            self.counters["compass_frames"] += 1
        n_bytes = _psns_frame_len(f)
        self.meter.charge("psns_decode", n_bytes * 4 + c674x.CALL_OVERHEAD)  # CRC-16 by table + copy [E]
        return psns.exposure_time_s(t_rx, n_bytes, cfg.psns_baud, f.header.latency_us, cfg.psns_bits_per_byte)

    def _psns_observation(self, t_rx: float, f: Any) -> SolarObservation | None:
        """Decode-side work for one PSNS frame: exposure time, solve (POLARIZATION_OBS), body frame."""
        cfg = self.cfg
        m = self.meter
        dt = self.dtype
        t_exp = self._psns_frame_in(t_rx, f)
        if isinstance(f, CompassFrame):
            return None
        h = f.header
        if not h.status & PsnsStatus.VALID:
            self.counters["psns_invalid"] += 1
            return None
        cam = cfg.camera
        if isinstance(f, PolarizationObs):
            n = len(f.points)
            if n < 3:
                self.counters["psns_invalid"] += 1
                return None
            pts = np.array([(p.x_px, p.y_px, p.aop_cdeg, p.dop) for p in f.points], dtype=np.float64)
            aop = (pts[:, 2] * (0.01 * DEG)).astype(dt)
            dop = (pts[:, 3] * (1.0 / 65535.0)).astype(dt)
            e = psns.evectors_camera(pts[:, 0], pts[:, 1], aop, cam, dtype=dt)
            sol = psns.solve_solar_vector(e, dop, cfg.psns_dop_min, max_quality=cfg.psns_quality_max)
            m.charge("psns_evectors", psns.evector_cycles(n, self.cost))
            m.charge("psns_solve", psns.solve_cycles(n, self.cost))
            if not sol.valid:
                self.counters["psns_invalid"] += 1
                return None
            s_c, quality, n_used, source = sol.s, sol.quality, sol.n_used, "camera"
        elif isinstance(f, SolarVectorFrame):
            s_c = np.array(f.s, dtype=dt)
            nrm = float(np.sqrt(s_c @ s_c))
            if not (0.5 < nrm < 1.5) or f.quality > cfg.psns_quality_max:
                self.counters["psns_invalid"] += 1
                return None
            s_c = s_c / dt(nrm)
            quality, n_used, source = float(f.quality), h.count, "sensor"
            m.charge("psns_normalise", self._cyc["normalise"])
        else:
            return None
        self.counters["psns_solutions"] += 1
        s_b = (cam.c_c_b.astype(dt) @ s_c).astype(dt)
        m.charge("psns_mounting", self._cyc["mounting"])
        return SolarObservation(t_exp, s_b, quality, n_used, source)

    def _psns_update(self, t: float, t_rx: float, f: Any) -> UpdateReport | None:
        cfg = self.cfg
        if isinstance(f, CompassFrame):
            t_exp = self._psns_frame_in(t_rx, f)
            return self.filter.update_compass(self.nav, f, t_exp) if cfg.psns_enabled else None  # type: ignore[arg-type]
        if self.filter.raw_polarization_obs and isinstance(f, PolarizationObs):
            t_exp = self._psns_frame_in(t_rx, f)
            if not cfg.psns_enabled or t - t_exp > cfg.psns_max_age_s:
                return None
            return self.filter.update_polarization_obs(self.nav, f, t_exp)  # type: ignore[arg-type]
        obs = self._psns_observation(t_rx, f)
        if obs is None or not cfg.psns_enabled:
            return None
        if t - obs.t_exposure_s > cfg.psns_max_age_s:
            return None
        days = self.utc_days(obs.t_exposure_s)
        if days is None:
            return None
        p_ins, _, q_exp = self._ins_at(obs.t_exposure_s)
        s_n = sun.sun_vector_enu(days, float(p_ins[0]), float(p_ins[1]), dtype=self.dtype)
        self.meter.charge("sun_ephemeris", sun.ephemeris_cycles())
        if float(s_n[2]) < math.sin(cfg.psns_min_sun_elevation_deg * DEG):
            self.counters["psns_sun_low"] += 1  # night or twilight: not an error, no update
            return None
        return self.filter.update_solar(self.nav, obs, s_n, q2mat(q_exp))  # type: ignore[arg-type]

    # -- output -------------------------------------------------------------------------------------------
    def cpu_load_pct(self) -> float:
        """Worst tick of the last second, % of the tick budget (NAV_SOLUTION / STATUS ``cpu_load``)."""
        worst = self._load_window[0][1] if self._load_window else 0
        return 100.0 * worst / self.meter.tick_budget

    # -- host port: commands, acknowledgements, status ----------------------------------------------------
    def _host_task(self, t: float, res: TickResult) -> None:
        """Execute pending host commands (one ACK each) and send STATUS at 1 Hz (protocols/host.py, D-3.2)."""
        m = self.meter
        while self._pending_cmd:
            c = self._pending_cmd.popleft()
            m.charge("host_command", 40 * 4 + c674x.CALL_OVERHEAD)  # CRC + dispatch [E]
            reply = self._command(c)
            if reply is None:
                continue
            cmd_id, token, result = reply
            if result == AckResult.ACCEPTED:
                self.counters["commands_accepted"] += 1
            else:
                self.counters["commands_rejected"] += 1
            res.outputs.append((UART_HOST, encode_ack(Ack(cmd_id, token, int(result))), m.elapsed))
            res.events.append({"event": "host_command", "t_fpga_s": t, "command": type(c).__name__,
                               "result": AckResult(result).name})
            if isinstance(c, RequestStatus) and result == AckResult.ACCEPTED:
                res.outputs.append((UART_HOST, self._status_frame(t), m.elapsed))
        if t >= self._next_status_t:
            self._next_status_t = math.floor(t) + 1.0
            res.outputs.append((UART_HOST, self._status_frame(t), m.elapsed))

    def _command(self, c: Any) -> tuple[int, int, int] | None:
        """Apply one command; ``(command_id, token, AckResult)``, or None for frames that are not commands."""
        from protocols.host import CMD_REQUEST_STATUS, CMD_RESET_FILTER, CMD_SELECT_VARIANT, CMD_SET_OUTPUT_RATE

        if isinstance(c, ResetFilter):
            if c.scope == 0:
                self._restart_alignment()
                return CMD_RESET_FILTER, c.token, AckResult.ACCEPTED
            if c.scope == 1:
                if self.nav is None:
                    return CMD_RESET_FILTER, c.token, AckResult.NOT_ALLOWED
                self.filter.initialise(self.nav, self._heading_sigma0)
                return CMD_RESET_FILTER, c.token, AckResult.ACCEPTED
            return CMD_RESET_FILTER, c.token, AckResult.BAD_ARGUMENT
        if isinstance(c, SelectVariant):
            names = {int(v): k for k, v in FILTER_VARIANT_NAMES.items()}
            name = names.get(c.variant)
            if name is None:
                return CMD_SELECT_VARIANT, c.token, AckResult.BAD_ARGUMENT
            if name not in FILTER_VARIANTS:
                return CMD_SELECT_VARIANT, c.token, AckResult.NOT_ALLOWED  # not in this firmware build
            self.filter = self._new_filter(name)
            self.cfg.filter = name
            if self.nav is not None:  # the new filter starts from the current navigation state
                self.filter.initialise(self.nav, self._heading_sigma0)
            return CMD_SELECT_VARIANT, c.token, AckResult.ACCEPTED
        if isinstance(c, SetOutputRate):
            r = float(c.rate_hz)
            if r == 0.0:
                self._out_every = 0
                return CMD_SET_OUTPUT_RATE, c.token, AckResult.ACCEPTED
            k = self.cfg.imu_rate_hz / r if r > 0 and math.isfinite(r) else 0.0
            if k < 1.0 - 1e-9 or abs(k - round(k)) > 1e-6:
                return CMD_SET_OUTPUT_RATE, c.token, AckResult.BAD_ARGUMENT
            self._out_every = int(round(k))
            return CMD_SET_OUTPUT_RATE, c.token, AckResult.ACCEPTED
        if isinstance(c, RequestStatus):
            return CMD_REQUEST_STATUS, c.token, AckResult.ACCEPTED
        if isinstance(c, HostFrame) and c.msg_id >= 0x80:
            return c.msg_id, c.payload[0] if c.payload else 0, AckResult.UNKNOWN_COMMAND
        return None  # our own outputs echoed back, or host frames that need no answer

    def _restart_alignment(self) -> None:
        """RESET_FILTER scope 0: back to coarse alignment with a fresh filter (biases included)."""
        self.state = FirmwareState.COARSE_ALIGN
        self.mode = NavMode.ALIGNING
        self.nav = None
        self.filter = self._new_filter(self.cfg.filter)
        self._align_sum[:] = 0.0
        self._align_n = 0
        self._align_t0 = None
        self._align_sun.clear()
        self._sub.clear()
        self._fn_sum = [0.0, 0.0, 0.0]
        self._fn_n = 0
        self._hist.clear()
        self._gnss_pending = None

    def _status_frame(self, t: float) -> bytes:
        self.counters["status_frames"] += 1
        vs = self.filter.variant_status()
        if vs is not None:
            self.counters.update(self.filter.counters)
        self.meter.charge("status", 64 * 2 + 71 * 4 + c674x.CALL_OVERHEAD)  # pack + CRC-16 by table [E]

        def errs(d: StreamDecoder) -> int:
            st = d.stats
            return st.crc_errors + st.length_errors + st.parse_errors

        st = HostStatus(
            seq=self._status_seq, time_s=t, filter_variant=self.filter.variant_id, mode=int(self.mode),
            output_rate_hz=self.cfg.imu_rate_hz / self._out_every if self._out_every else 0.0,
            gnss_status=self._last_fix[3] if self._last_fix is not None else 0,
            psns_status=self._psns_status_now(t), cpu_load_pct=self.cpu_load_pct(),
            cpu_load_max_pct=100.0 * self._load_max / self.meter.tick_budget, fw_version=FW_VERSION,
            deadline_misses=self.deadline_misses,
            uart1_frames=self._dec_imu.stats.frames, uart1_errors=errs(self._dec_imu),
            uart2_frames=self._dec_psns.stats.frames, uart2_errors=errs(self._dec_psns),
            uart3_frames=self._dec_gnss.stats.frames, uart3_errors=errs(self._dec_gnss),
            commands_accepted=self.counters["commands_accepted"], commands_rejected=self.counters["commands_rejected"],
            variant_mode=vs[0] if vs is not None else 0,
        )
        self._status_seq += 1
        return encode_status(st)

    def _psns_status_now(self, t: float) -> int:
        return 1 if t - self._last_psns_t < 2.0 else 2 if t - self._last_psns_reject_t < 2.0 else 0

    def _nav_output(self, t: float) -> bytes:
        s = self.nav
        mode = int(self.mode) | (self.filter.variant_id & 0xF) << 8
        if s is None:
            lat = lon = h = 0.0
            if self._last_fix is not None:
                lat, lon, h = self._last_fix[0], self._last_fix[1], self._last_fix[2]
            vel = (0.0, 0.0, 0.0)
            roll = pitch = heading = 0.0
            sigma = (0.0,) * 9
        else:
            if t - self._last_gnss_update_t < 2.0:
                mode |= _GNSS_AIDED
            elif self.state != FirmwareState.COARSE_ALIGN and t - self._t_aligned > 3.0:
                mode |= _DEGRADED  # GNSS missing or stale
            if t - self._last_psns_t < 2.0:
                mode |= _PSNS_AIDED
            if t - self._last_psns_reject_t < 2.0:
                mode |= _DEGRADED
            x = s.as_floats()
            lat, lon, h = x[7:10]
            vel = x[4:7]
            # PSINS m2att from the quaternion directly: C32, C31, C33, C12, C22 of C_b^n
            q0, q1, q2, q3 = x[0:4]
            c32 = 2.0 * (q2 * q3 + q0 * q1)
            pitch = math.asin(max(-1.0, min(1.0, c32))) / DEG
            roll = math.atan2(-2.0 * (q1 * q3 - q0 * q2), q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3) / DEG
            yaw = math.atan2(-2.0 * (q1 * q2 - q0 * q3), q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3)
            heading = heading_from_yaw(yaw) / DEG
            d = [_sqrt(0.0 if v < 0.0 else v) for v in self.filter.P.diagonal()[:9].tolist()]  # sqrt(max(v, 0))
            rm, rn = earth.radii(lat)
            sigma = (
                d[0] / DEG, d[1] / DEG, d[2] / DEG, d[3], d[4], d[5],
                d[6] * (rm + h), d[7] * (rn + h) * math.cos(lat), d[8],
            )
        fix = self._last_fix
        vs = self.filter.variant_status()
        if vs is not None:  # VARIANT block: pack 4 bytes + CRC over 6 more [E]
            self.meter.charge("nav_variant_block", 6 * 4 + 4 * 2)
        seq = self._out_seq
        self._out_seq = seq + 1
        # the NavSolution fields in order (protocols.host.nav_solution_frame), without building the object
        return nav_solution_frame(
            seq, t, lat / DEG, lon / DEG, h, vel, roll, pitch, heading, sigma, int(mode),
            fix[3] if fix is not None else 0, self._psns_status_now(t), self.cpu_load_pct(), self.deadline_misses,
            *(vs if vs is not None else (None, 0, 0)))

    # -- introspection (tests, reports) ----------------------------------------------------------------
    @property
    def x(self) -> np.ndarray:
        return getattr(self.filter, "x", np.zeros(15, dtype=self.dtype))

    @property
    def P(self) -> np.ndarray:
        return self.filter.P


def _psns_frame_len(f: Any) -> int:
    """Wire length of a decoded PSNS frame (sync, id, length, header, body, CRC)."""
    if isinstance(f, PolarizationObs):
        return 7 + 13 + 10 * len(f.points)
    if isinstance(f, CompassFrame):
        return 7 + 13 + 5 * len(f.units)
    return 7 + 13 + 16
