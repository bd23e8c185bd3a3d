"""The DSP firmware's main loop as a pure, synchronous state machine.

The virtual DSP (``emulator.devices.dsp``) hosts one :class:`Firmware`: the UART ISRs hand bytes to
:meth:`Firmware.receive` (with the reception time of the last byte); the cyclic executive runs in
:meth:`Firmware.service`, driven by the FPGA's 200 Hz IMU frames, and returns per tick the bytes to
transmit and the cycles charged, which the DSP turns into time.

UART map: :mod:`firmware_model.config`. The tasks of the loop are objects, one module each in
:mod:`firmware_model.tasks`, built here with their collaborators; this module is the loop itself (no base class):
reception into the decoders, IMU screening and conversion, the tick's schedule and the measurement updates'
bookkeeping.

Mode manager (one state per tick)::

    COARSE_ALIGN --(levelling window done, GNSS fix, heading source ready)--> FINE_ALIGN
    FINE_ALIGN   --(fine_align_time_s of KF updates)-------------------------> NAVIGATE

Heading source of the coarse alignment (``alignment_heading``): ``"psns"`` = gravity + solar vector
(TRIAD, :mod:`firmware_model.alignment`), ``"config"`` = the configured heading, ``"auto"`` = PSNS
when a valid solar vector has arrived by the end of the levelling window, else the configured heading.

Tasks of one IMU tick (the whole tick is the task ``imu_tick``), each metered (``meter.table()``):

* ``imu``: decode the IMU frame, convert to SI, coarse-align accumulation (``alignment``, :mod:`.tasks.alignment`)
  or bias compensation, coning/sculling (two-sample with angle increments) and strapdown (``core``,
  :mod:`.tasks.navigation`);
* ``kf_predict`` (inside ``imu``): every ``kf_predict_every`` ticks, the filter's time update;
* ``gnss_update``: a fix is pending (1 Hz): Eqs. 23-30 at the PPS time of validity (2 s INS history);
* ``psns_update``: a PSNS frame is pending (frame rate): E-vectors -> K -> ``+-S^b``
  (:mod:`firmware_model.psns`), ephemeris (:mod:`firmware_model.sun`) at the exposure time, Eqs. 31-42;
* ``output``: NAV_SOLUTION at ``output_rate_hz``.
* ``nmea_output``: the NMEA 0183 sentences of ``nmea_sentences`` at ``nmea_rate_hz`` / ``nmea_attitude_rate_hz``
  on the host UART after NAV_SOLUTION (off by default).

The filter itself is a variant (:mod:`firmware_model.filters`), picked by ``FirmwareConfig.filter``.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections import deque
from typing import Any

import numpy as np

from protocols.host import HostFormat, NavMode
from protocols.imu_frame import ADC_VOLTS_PER_LSB, FpgaFrameFormat, FpgaStatus, ImuFrame, MagFrame
from protocols.nmea import NMEA_RX_MAX_LEN, NmeaFormat
from protocols.psns import PsnsFormat
from protocols.stim import GYRO_ANGLE_LSB_DEG, GYRO_RATE_LSB_DPS, STATUS_SAMPLE_INVALID
from protocols.stream import StreamDecoder
from protocols.ubx import UbxFormat

from . import c674x, input_guard
from .alignment import level_cycles, triad_cycles
from .arrays import FloatArray, FloatDtype
from .config import UART_GNSS, UART_HOST, UART_IMU, UART_PSNS, FirmwareConfig
from .filters.interface import NavFilter
from .kf import N_STATES
from .nav_state import NavState
from .precision import rounder
from .registry import FirmwareSnapshot, register_firmware
from .tasks.alignment import AlignmentTask
from .tasks.gnss import GnssTask
from .tasks.host import HostTask
from .tasks.navigation import NavCore
from .tasks.output import OutputTask
from .tasks.psns import PsnsTask, psns_frame_len
from .tasks.state import CpuLoad, FirmwareState, LoopStatus, TickResult, count_rejection
from .tasks.timekeeping import Clock
from .units import DEG, G_STD
from .variants import dual_vector, federated, kmeans_3d, sun_elevation  # noqa: F401  (the variants of this build)

__all__ = ["Firmware", "tick_kernel_cycles"]


def tick_kernel_cycles(c: c674x.KernelCosts, nav_dp: bool = True) -> dict[str, int]:
    """Cycle charges of the per-tick kernels in the build's precision (branch-free code paths).

    * ``imu_decode``: CRC-16 over 36 bytes by table (~4 cycles/byte) + field unpack (integer work) [E].
    * ``imu_convert``: raw words to SI, 6 INT->float conversions + 6 multiplies [D].
    * ``coning1``: single-sample rotation compensation (one cross product) [D];
      ``coning2``: two-sample coning/sculling, 4 cross products and the 2/3, 1/2 scalings [D].
    * ``strapdown``: the Earth model in double precision whatever the build (latitude is a float64
      variable: sindp, cosdp, sqrtdp, 3 divdp and DP position update [S, R2]), two rv2q (sqrt, sin,
      cos, div), quaternion normalisation (rsqrt) and ~260 FLOPs (docs/reference/c674x-cycles.md section 4) [S/D];
      with ``nav_dp`` (the attitude quaternion and velocity accumulators in double precision,
      docs/decisions/firmware.md D-L.1) the rv2q, normalisation and FLOPs are charged at DP prices.
    * ``nav_output``: m2att (asin, 2 atan2), 9 sqrt for the sigmas, pack 102 bytes, CRC-16 over 109 [S/E].
    * ``level``, ``triad``: :mod:`firmware_model.alignment`.
    """
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
        "nav_output": (c.math("asin") + 2 * c.math("atan2") + 9 * c.math("sqrt") + 102 * 2 + 109 * 4
                       + c674x.CALL_OVERHEAD),
        "level": level_cycles(c),
        "triad": triad_cycles(c),
        "mounting": c.flops(9, 6),
        "normalise": c.math("rsqrt") + c.flops(6, 2),
    }


_PPS_VALID = int(FpgaStatus.PPS_VALID)
_GYRO_MISSING = int(FpgaStatus.GYRO_MISSING)
_STATUS_INVALID = int(STATUS_SAMPLE_INVALID)
#: consecutive IMU frames with an out-of-range time-stamp step after which the new time base is taken
_IMU_RESYNC = 5


class Firmware:
    """The firmware (see module docstring). Interface to the DSP host (docs/architecture.md, section "Firmware
    interface"): :meth:`receive`, :meth:`service`, :meth:`note_deadline_miss`, :attr:`meter`, :attr:`counters`,
    :meth:`decoder_stats`."""

    def __init__(self, cfg: FirmwareConfig | None = None) -> None:
        self.cfg = cfg = cfg or FirmwareConfig()
        #: working precision of the filters and kernels
        self.dtype: FloatDtype = np.float32 if cfg.precision == "float32" else np.float64
        #: dtype of the strapdown state (q, v); position is always float64
        self.nav_dtype: FloatDtype = np.float64 if cfg.nav_state_precision == "float64" else self.dtype
        self.meter = c674x.CycleMeter(cfg.clock_hz, cfg.imu_rate_hz)
        self.cost = c674x.KernelCosts(cfg.precision)
        self._cyc = tick_kernel_cycles(self.cost, nav_dp=self.nav_dtype is np.float64)
        self._cyc_decode, self._cyc_convert = self._cyc["imu_decode"], self._cyc["imu_convert"]
        self.T = 1.0 / cfg.imu_rate_hz
        # IMU conversion constants in the working precision (Python floats holding dtype values)
        self._kv = ADC_VOLTS_PER_LSB * G_STD
        self._round3 = rounder(self.dtype, 3)
        self._dec_imu = StreamDecoder([FpgaFrameFormat()])
        self._dec_gnss = StreamDecoder([NmeaFormat(NMEA_RX_MAX_LEN), UbxFormat()])
        self._dec_host = StreamDecoder([HostFormat()])
        self.last_mag: MagFrame | None = None
        self._dec_psns = StreamDecoder([PsnsFormat(packed_points=True)])  # the points' bytes: no object per point
        self._pending_imu: deque[ImuFrame] = deque()
        self._pending_psns: deque[tuple[float, Any]] = deque(maxlen=8)  # (t_rx_s, frame)
        self._rx_other: dict[int, int] = {}
        self._last_counter: int | None = None  # the STIM datagram counter of the last IMU frame
        # mode manager and aiding times (written by the alignment and the measurement tasks, reported by the output)
        self.status = LoopStatus(heading_sigma0=cfg.initial_heading_sigma_deg * DEG)
        self._tick = 0
        self.load = CpuLoad(self.meter.tick_budget)
        self.counters: dict[str, int] = {"imu_frames": 0, "gnss_fixes": 0, "gnss_updates": 0, "gyro_counter_jumps": 0,
                         "fpga_gyro_missing": 0, "imu_time_gaps": 0, "psns_frames": 0, "psns_solutions": 0,
                         "psns_updates": 0, "psns_rejected": 0, "psns_invalid": 0, "psns_sun_low": 0,
                         "psns_dropped": 0, "compass_frames": 0, "mag_frames": 0,
                         "gnss_pvt": 0, "commands_accepted": 0, "commands_rejected": 0, "commands_dropped": 0,
                         "status_frames": 0, "input_rejected": 0, "input_faults": 0, "imu_time_resync": 0,
                         "imu_resync_refused": 0, "psns_stale": 0, "commands_rejected_output_rate": 0}
        self.clock = Clock(cfg, self.counters)
        self.core = NavCore(cfg, self.meter, self.clock, self._cyc, self.dtype, self.nav_dtype)
        #: True: an exception while handling one input message propagates (tests of the emulator itself set
        #: ``PSNS_HIL_STRICT=1``); False (the box): it is contained, counted (``input_faults``) and reported
        self.raise_faults = os.environ.get("PSNS_HIL_STRICT", "") not in ("", "0")
        self._fault_events: list[dict[str, Any]] = []
        self._imu_hold: tuple[tuple[int, int, int], tuple[int, int, int]] | None = None
        #: the run of frames whose time-stamp step was refused: (unwrapped time us, seq, gyro counter)
        self._imu_resync_run: list[tuple[int, int, int]] = []
        #: unwrapped time (us) of the first frame of the current time base: [first, last] is time lived through
        self._t_base_first_us = 0
        # the largest word magnitudes of the fitted units' ranges (cfg.gyro_range_dps, cfg.accel_range_g), 1 LSB
        # of rounding allowed: a word beyond them is refused even below the 24-bit rail (D-5.46)
        gyro_lsb_dps = GYRO_RATE_LSB_DPS if cfg.gyro_output == "rate" else GYRO_ANGLE_LSB_DEG / self.T
        self._gyro_word_max = int(cfg.gyro_range_dps / gyro_lsb_dps) + 1
        amax = [int(r * v / ADC_VOLTS_PER_LSB) + 1 for r, v in zip(cfg.accel_range_g, cfg.accel_volts_per_g)]
        self._accel_code_max = (amax[0], amax[1], amax[2])
        # the same bounds inside the rails, for the one-expression acceptance of _screen_imu
        inside = input_guard.S24_MAX - 1
        self._gyro_fast_max = min(self._gyro_word_max, inside)
        self._accel_fast_max = (min(amax[0], inside), min(amax[1], inside), min(amax[2], inside))
        self._gnss_reject_run = 0
        self._psns_reject_since: float | None = None
        self.gnss = GnssTask(cfg, self.counters, self.clock, self._fault)
        self.psns = PsnsTask(cfg, self.meter, self.cost, self._cyc, self.counters, self.core, self.clock, self.status,
                             self._fault_events, self.dtype)
        self.alignment = AlignmentTask(cfg, self.meter, self._cyc, self.core, self.gnss, self.clock, self.psns,
                                       self.status, self.dtype, self.nav_dtype)
        self.output = OutputTask(cfg, self.meter, self.core, self.gnss, self.clock, self.status, self.load,
                                 self._cyc["nav_output"])
        self.host = HostTask(cfg, self.meter, self.counters, self.core, self.alignment, self.output, self.status,
                             self.load, self._uart_counts)

    # -- input validation and fault containment (docs/hostile-input.md) --------------------------------
    def _reject(self, reason: str) -> None:
        """Count one message refused by :mod:`firmware_model.input_guard` (``input_rejected_<reason>``)."""
        count_rejection(self.counters, reason)

    def _fault(self, where: str, exc: BaseException) -> None:
        """An exception while handling one input message: counted, reported as an event, the run goes on."""
        if self.raise_faults:
            raise exc
        self.counters["input_faults"] += 1
        if len(self._fault_events) < 16:
            self._fault_events.append({"event": "firmware_fault", "where": where, "error": type(exc).__name__,
                                       "t_fpga_s": self.clock.now_s()})

    # -- ISR side -------------------------------------------------------------------------------------
    def receive(self, uart: int, data: bytes, t_rx_s: float | None = None) -> None:
        """Bytes received on ``uart`` (the ISR copies the 16550 FIFO into the ring buffer).

        ``t_rx_s`` is the DSP's time (s, FPGA time base) when the last byte arrived, as the ISR
        reads it from the time-stamp counter; PSNS frames are time-tagged from it (docs/architecture.md "Conventions").
        """
        try:
            self._receive(uart, data, t_rx_s)
        except Exception as e:
            self._fault(f"receive uart{uart}", e)

    def _receive(self, uart: int, data: bytes, t_rx_s: float | None) -> None:
        if uart == UART_IMU:
            for f in self._dec_imu.feed(data):
                if isinstance(f, ImuFrame):
                    self._pending_imu.append(f)
                else:  # MAG frame (same FPGA framing); kept for the variants that use a magnetometer
                    self.last_mag = f
                    self.counters["mag_frames"] += 1
                    if not f.status & 0x01:  # not over range: into the history a variant may average
                        self.core.add_mag(self.clock.unwrap_near(f.t_sample_us) / 1e6, f.field)
        elif uart == UART_GNSS:
            self.gnss.on_bytes(self._dec_gnss, data, t_rx_s)
        elif uart == UART_HOST:
            for c in self._dec_host.feed(data):
                self.host.queue(c)
        elif uart == UART_PSNS:
            frames = self._dec_psns.feed(data)
            if frames:
                t_end = t_rx_s if t_rx_s is not None else self.clock.now_s()
                # the last frame ended with the chunk; earlier ones ended earlier by the later frames' bytes
                byte_s = self.cfg.psns_bits_per_byte / self.cfg.psns_baud
                tags = []
                for f in reversed(frames):
                    tags.append((t_end, f))
                    t_end -= psns_frame_len(f) * byte_s
                for tag in reversed(tags):
                    if len(self._pending_psns) == self._pending_psns.maxlen:
                        self.counters["psns_dropped"] += 1  # the solve cannot keep up: oldest frame lost
                    self._pending_psns.append(tag)
        else:
            self._rx_other[uart] = self._rx_other.get(uart, 0) + len(data)

    def decoder_stats(self) -> dict[str, dict[str, Any]]:
        return {"uart0": self._dec_host.stats.as_dict(), "uart1": self._dec_imu.stats.as_dict(),
                "uart2": self._dec_psns.stats.as_dict(), "uart3": self.gnss.decoder_stats(self._dec_gnss)}

    def _uart_counts(self) -> tuple[int, int, int, int, int, int]:
        """Frames and errors (CRC, length, parse) of the UART1, UART2 and UART3 decoders, for STATUS."""
        out: list[int] = []
        for d in (self._dec_imu, self._dec_psns, self._dec_gnss):
            st = d.stats
            out += [st.frames, st.crc_errors + st.length_errors + st.parse_errors]
        return out[0], out[1], out[2], out[3], out[4], out[5]

    def note_deadline_miss(self) -> None:
        """Called by the host DSP when a tick started after its deadline."""
        self.load.note_miss()

    def snapshot(self) -> FirmwareSnapshot:
        """What the recorder and the report read (:class:`firmware_model.registry.FirmwareSnapshot`)."""
        flt = self.filter
        gb, ab = flt.gyro_bias, flt.accel_bias
        return FirmwareSnapshot(
            state=str(self.status.state), mode=int(self.status.mode), filter=self.cfg.filter,
            precision=self.cfg.precision,
            covariance_diag=tuple(float(v) for v in np.asarray(flt.P).diagonal()),
            gyro_bias_rad_s=(float(gb[0]), float(gb[1]), float(gb[2])),
            accel_bias_mps2=(float(ab[0]), float(ab[1]), float(ab[2])),
            counters=dict(self.counters), decoders=self.decoder_stats(), cycles=self.meter.table(),
            tick_budget_cycles=self.meter.tick_budget, spec_sheet=self.cfg.spec_sheet,
            innovation={k: dict(v) for k, v in getattr(flt, "innovation_stats", {}).items()})

    # -- the cyclic executive ---------------------------------------------------------------------------
    def service(self) -> list[TickResult]:
        """Run the cyclic executive over every pending IMU frame."""
        out: list[TickResult] = []
        while self._pending_imu:
            fr = self._screen_imu(self._pending_imu.popleft())
            if fr is None:
                continue
            try:
                out.append(self._imu_tick(fr))
            except Exception as e:
                self.meter._stack.clear()
                self._fault("imu tick", e)
        if self._fault_events and out:
            out[-1].events.extend(self._fault_events)
            self._fault_events.clear()
        return out

    def _screen_imu(self, fr: ImuFrame) -> ImuFrame | None:
        """Validate one IMU frame (:mod:`.input_guard`, docs/hostile-input.md).

        Time stamp: a corrupt step drops the frame; after ``_IMU_RESYNC`` consecutive frames that form a new time
        base of their own (valid steps between them, sequence and gyro counter advancing) the new base is taken
        (:meth:`_imu_resync_candidate`); a frame whose stamp lies in the span the current base has already lived
        through is a replay and never counts toward a resync.

        Words: a gyro sample flagged invalid by its STATUS byte (overload, channel error, start-up, integrity),
        beyond the fitted gyro's range or at a 24-bit rail, and an accelerometer code beyond its range or at a
        rail, are replaced by that triad's last good sample (hold, D-5.46), so the strapdown never integrates a
        clipped or flagged value; with no good sample yet the frame is dropped."""
        t_last_opt = self.clock.last_us()
        if t_last_opt is not None:
            t_last = t_last_opt
            t_new = self.clock.unwrap_near(fr.t_trigger_us)
            reason = input_guard.check_imu_step(t_new - t_last, 1e6 * self.T)
            if reason is not None:
                if not self._imu_resync_candidate(fr, t_new, t_last):
                    return None
                # the FPGA time base really moved (a reset): take it, without a KF interval across the jump
                self.counters["imu_time_resync"] += 1
                epoch = self.clock.rebase(t_new, fr.t_trigger_us)
                self._t_base_first_us = t_new
                t_s = (epoch + fr.t_trigger_us) / 1e6
                self.core.rebase(t_s, self._tick % self.cfg.kf_predict_every)
                self._fault_events.append({"event": "imu_time_resync", "t_fpga_s": t_s})
            self._imu_resync_run.clear()
        else:
            self._t_base_first_us = self.clock.epoch_us() + fr.t_trigger_us
        # the common case in one expression (every word inside the range, which lies inside the rails; STATUS clear)
        g0, g1, g2 = fr.gyro
        a0, a1, a2 = fr.accel
        gm = self._gyro_fast_max
        am0, am1, am2 = self._accel_fast_max
        if (not fr.gyro_status & _STATUS_INVALID and -gm <= g0 <= gm and -gm <= g1 <= gm and -gm <= g2 <= gm
                and -am0 <= a0 <= am0 and -am1 <= a1 <= am1 and -am2 <= a2 <= am2):
            self._imu_hold = (fr.gyro, fr.accel)
            return fr
        g_reason = (input_guard.check_gyro_status(fr.gyro_status)
                    or input_guard.check_imu_words(fr.gyro, (0, 0, 0)))
        a_reason = input_guard.check_imu_words((0, 0, 0), fr.accel)
        g_range, a_range = input_guard.check_imu_range(fr.gyro, fr.accel, self._gyro_word_max, self._accel_code_max)
        g_reason = g_reason or g_range
        a_reason = a_reason or a_range
        hold = self._imu_hold
        if g_reason is None and a_reason is None:
            self._imu_hold = (fr.gyro, fr.accel)
            return fr
        gyro, accel = fr.gyro, fr.accel
        if g_reason is not None:
            self._reject(g_reason)
            if hold is None:
                return None
            gyro = hold[0]
        if a_reason is not None:
            self._reject(a_reason)
            if hold is None:
                return None
            accel = hold[1]
        if hold is None:  # one triad good, the other without a good sample yet: nothing to hold
            return None
        self._imu_hold = (gyro, accel)
        return dataclasses.replace(fr, gyro=gyro, accel=accel)

    def _imu_resync_candidate(self, fr: ImuFrame, t_new: int, t_last: int) -> bool:
        """One frame whose time-stamp step is refused: True when it completes a run of ``_IMU_RESYNC`` frames that
        form a new time base (the caller takes it), False when it is dropped (counted).

        A frame whose stamp (unwrapped near the current time) lies in ``[first, last]`` of the current time base
        is a replay of time already lived through (a duplicate, a looped capture): refused as ``imu_time_replay``
        and counted in ``imu_resync_refused``; it never counts toward a resync. An FPGA that restarted begins again
        at sequence 0, which a run starting at ``seq == 0`` is taken for (a replay of the run's first frames cannot
        be told from it). The run's frames must step validly among themselves, with the frame sequence and the
        STIM datagram counter advancing (a repeated counter is a duplicated datagram, not a live gyro)."""
        run = self._imu_resync_run
        from_zero = (run[0][1] if run else fr.seq) == 0  # the run (or this frame, starting one) begins at seq 0
        if self._t_base_first_us <= t_new <= t_last and not from_zero:
            self.counters["imu_resync_refused"] += 1
            self._reject("imu_time_replay")
            run.clear()
            return False
        if run:
            t_prev, seq_prev, ctr_prev = run[-1]
            ok = (input_guard.check_imu_step(t_new - t_prev, 1e6 * self.T) is None
                  and 1 <= (fr.seq - seq_prev) % 65536 <= input_guard.IMU_STEP_MAX_FACTOR
                  and fr.gyro_counter != ctr_prev)
            if not ok:
                self.counters["imu_resync_refused"] += 1
                run.clear()
        run.append((t_new, fr.seq, fr.gyro_counter))
        if len(run) < _IMU_RESYNC:
            self._reject("imu_time_step")
            return False
        return True

    def _imu_tick(self, fr: ImuFrame) -> TickResult:
        cfg = self.cfg
        m = self.meter
        m.begin("imu_tick", self.T)
        m.begin("imu", self.T)
        m.charge("imu_decode", self._cyc_decode)
        t_us = self.clock.unwrap_us(fr.t_trigger_us)
        t = t_us / 1e6
        res = TickResult(t, 0)
        self.counters["imu_frames"] += 1
        if fr.fpga_status & _PPS_VALID:
            self.clock.pps_edge(t_us, fr.pps_count, fr.t_pps_us)
        self.gnss.hold(t)
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

        if self.status.state == FirmwareState.COARSE_ALIGN:
            self.alignment.accumulate(t, np.array(f_b, dtype=self.dtype), res)
            m.end()
        else:
            core = self.core
            core.mechanize(t, g, f_b)
            if self._tick % cfg.kf_predict_every == 0 and core.predict_due():
                core.predict(t)
            m.end()
            self._measurement_tasks(t, res)
            if self.status.state == FirmwareState.FINE_ALIGN and t - self.status.t_aligned >= cfg.fine_align_time_s:
                self.status.state = FirmwareState.NAVIGATE
                self.status.mode = NavMode.NAVIGATING
                res.events.append({"event": "fine_alignment_done", "t_fpga_s": t})
        if self.status.state == FirmwareState.COARSE_ALIGN:
            while self._pending_psns:  # solved and kept for the TRIAD heading
                t_rx, f = self._pending_psns.popleft()
                self.alignment.psns_frame(t_rx, f)
        self._tick += 1
        self.output.run(t, self._tick, res)
        ev = self.filter.drain_events()
        if ev:
            res.events.extend(ev)
            self.counters.update(self.filter.counters)
        if self.host.due(t):
            m.begin("host", 1.0)
            self.host.run(t, res)
            m.end()
        res.cycles = m.end()
        if self.psns.has_solves():  # the solves of this tick, for the host (contract C3)
            res.solar_solves = self.psns.take_solves()
        self.load.record(t, res.cycles)  # worst tick of the last second and since start, for NAV_SOLUTION / STATUS
        return res

    def _measurement_tasks(self, t: float, res: TickResult) -> None:
        cfg = self.cfg
        m = self.meter
        nav = self.nav
        assert nav is not None  # measurement tasks run after the coarse alignment
        updated = False
        g = self.gnss.pending(t)
        if g is not None and (g.pos is not None or g.vel is not None) and self.core.has_history():
            self.gnss.take()
            if t - g.t_fpga_s > cfg.gnss_max_age_s:
                self.counters["gnss_tag_stale"] += 1  # grew too old waiting for the loop (docs/icd.md 5.1.3)
            else:
                m.begin("gnss_update", 1.0)
                p_ins, v_ins, _ = self.core.ins_at(g.t_fpga_s)
                rep = self.filter.update_gnss(nav, g, p_ins, v_ins)
                m.end()
                self.status.gnss_gated = not rep.accepted or bool((rep.detail or {}).get("gated_rows"))
                if not rep.accepted:
                    self._gnss_reject_run += 1
                    self.counters["gnss_rejected"] = self.counters.get("gnss_rejected", 0) + 1
                else:
                    self._gnss_reject_run = 0
                if rep.accepted:  # a variant may refuse a fix (federated: chi-square isolation)
                    self.counters["gnss_updates"] += 1
                    self.status.last_gnss_update_t = t
                    updated = True
                    res.events.append({"event": "gnss_update", "t_fpga_s": t, "t_meas_s": g.t_fpga_s,
                                       "n_meas": rep.n_rows, "max_norm_innov": rep.max_norm_innov})
        while self._pending_psns and self.core.has_history():
            t_rx, f = self._pending_psns.popleft()
            m.begin("psns_update", 0.0)
            prep = self.psns.update(t, t_rx, f)
            m.end()
            if prep is not None:
                if prep.accepted:
                    updated = True
                    self.counters["psns_updates"] += 1
                    self.status.last_psns_t = t
                    self._psns_reject_since = None
                else:
                    # divergence evidence only from an innovation test (a geometric refusal, e.g. the sun outside
                    # the field of view, says nothing about the state)
                    if self._psns_reject_since is None and prep.max_norm_innov > 0.0:
                        self._psns_reject_since = t
                    self.counters["psns_rejected"] += 1
                    if t - self.status.last_psns_reject_t >= 1.0:  # at most one event per second
                        res.events.append({"event": "psns_rejected", "t_fpga_s": t, "measurement": prep.kind,
                                           "norm_innov": prep.max_norm_innov, **(prep.detail or {})})
                    self.status.last_psns_reject_t = t
        if updated:
            m.begin("kf_feedback", 0.0)
            self.filter.feedback(nav)
            m.end()
        if self.filter.counters:
            self.counters.update(self.filter.counters)
        self._divergence_check(t, res)

    def _divergence_check(self, t: float, res: TickResult) -> None:
        """Fault detection and recovery (docs/hostile-input.md): sustained refusal of GNSS fixes or of solar
        vectors, or a navigation state / covariance that is no longer finite, mean the filter diverged; the loop
        re-aligns (coarse alignment: gravity + sun or configured heading, position from the next GNSS fix)."""
        cfg = self.cfg
        reason = None
        if cfg.fdir_gnss_reject_limit and self._gnss_reject_run >= cfg.fdir_gnss_reject_limit:
            reason = "gnss_rejected"
        elif (cfg.fdir_psns_reject_s and self._psns_reject_since is not None
              and t - self._psns_reject_since >= cfg.fdir_psns_reject_s and t - self.status.last_gnss_update_t < 5.0
              and self._at_rest_for_realign()):
            reason = "psns_rejected"
        elif self._tick % cfg.kf_predict_every == 0:
            nav = self.nav
            assert nav is not None
            if not (np.isfinite(nav.q).all() and np.isfinite(nav.v).all() and np.isfinite(nav.pos).all()
                    and np.isfinite(self.filter.P).all()) or abs(float(nav.pos[0])) > 1.6:
                reason = "state_not_finite"
        if reason is None:
            return
        self.counters["fdir_recoveries"] = self.counters.get("fdir_recoveries", 0) + 1
        res.events.append({"event": "filter_recovery", "t_fpga_s": t, "reason": reason,
                           "action": "re-alignment", "filter": self.cfg.filter})
        self._gnss_reject_run = 0
        self._psns_reject_since = None
        self.alignment.restart()

    def _at_rest_for_realign(self) -> bool:
        """Whether the solar criterion may re-align: the navigation solution's horizontal speed under
        ``fdir_psns_realign_max_speed_mps`` (D-5.43; 0 = always)."""
        vmax = self.cfg.fdir_psns_realign_max_speed_mps
        nav = self.nav
        if vmax <= 0.0 or nav is None:
            return True
        return math.hypot(float(nav.v[0]), float(nav.v[1])) < vmax

    # -- introspection (tests, reports) ----------------------------------------------------------------
    @property
    def x(self) -> FloatArray:
        """The filter's error state (layout: :mod:`firmware_model.kf`), zeros for a variant without one."""
        x: FloatArray = getattr(self.filter, "x", np.zeros(N_STATES, dtype=self.dtype))
        return x

    @property
    def P(self) -> FloatArray:
        return self.filter.P

    @property
    def nav(self) -> NavState | None:
        """The navigation state (:attr:`.tasks.navigation.NavCore.nav`; None before the coarse alignment)."""
        return self.core.nav

    @nav.setter
    def nav(self, value: NavState | None) -> None:
        self.core.nav = value

    @property
    def filter(self) -> NavFilter:
        """The filter of the selected variant (:attr:`.tasks.navigation.NavCore.filter`)."""
        return self.core.filter

    @property
    def state(self) -> str:
        """The mode manager's state (:class:`~.tasks.state.FirmwareState`)."""
        return self.status.state

    @property
    def mode(self) -> NavMode:
        """The NavMode bits of the mode manager (NAV_SOLUTION adds the aiding bits)."""
        return self.status.mode

    @property
    def deadline_misses(self) -> int:
        """Ticks the DSP host found late (:meth:`note_deadline_miss`)."""
        return self.load.deadline_misses


register_firmware("psns_hil", Firmware)
