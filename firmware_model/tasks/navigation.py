"""The navigation core: the navigation state, the filter, the mechanization per IMU sample and the INS history.

:class:`NavCore` is not a task of the loop's schedule but the collaborator the tasks share: the executive runs its
mechanization and time update every tick, the measurement tasks update its filter, the alignment starts it, the
output reads it. It is also what a filter variant asks of the loop
(:class:`firmware_model.filters.interface.FilterHost`): the INS state at a measurement's time (2 s history), the mean
of the MAG frames around a given time, the time.
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from protocols.stim import GYRO_ANGLE_LSB_DEG, GYRO_RATE_LSB_DPS

from .. import c674x
from ..arrays import F64Array, FloatArray, FloatDtype
from ..config import FILTER_VARIANTS, FirmwareConfig
from ..filters.interface import NavFilter
from ..nav_state import FE, FN, FU, POS, NavFloats, NavState, Q, V
from ..precision import rounder
from ..strapdown import coning_sculling, coning_sculling_fast, strapdown_kernel
from ..units import DEG
from .timekeeping import Clock

__all__ = ["NavCore"]


class NavCore:
    """Mechanization per IMU sample, the filter's time update, the INS and MAG histories; a ``FilterHost``.

    Collaborators: ``cfg`` (rates, sub-samples, gyro output, filter, magnetometer calibration), ``meter`` (the
    cycle meter), ``clock`` (the time a variant asks for), ``cyc`` (the per-tick kernel cycles,
    ``firmware.tick_kernel_cycles``); ``dtype`` / ``nav_dtype``: the working precision and that of the strapdown
    state (q, v). Public state the tasks use: :attr:`nav` and :attr:`filter`."""

    def __init__(self, cfg: FirmwareConfig, meter: c674x.CycleMeter, clock: Clock, cyc: dict[str, int],
                 dtype: FloatDtype, nav_dtype: FloatDtype) -> None:
        self.cfg = cfg
        self.meter = meter
        self.clock = clock
        self.dtype = dtype
        self.nav_dtype = nav_dtype
        #: the strapdown step in nav_dtype (strapdown.strapdown_kernel): step(state, phi_m, dv_m, T)
        self._strapdown: Callable[[NavState, Sequence[float], Sequence[float], float], NavState] = \
            strapdown_kernel(nav_dtype)
        self._cyc_coning1, self._cyc_coning2 = cyc["coning1"], cyc["coning2"]
        self._cyc_strapdown = cyc["strapdown"]
        self.T = 1.0 / cfg.imu_rate_hz  # IMU sample interval, s
        self._nsub = cfg.subsamples  # IMU samples per strapdown update
        # IMU conversion constants in the working precision (Python floats holding dtype values)
        lsb = GYRO_RATE_LSB_DPS * DEG * self.T if cfg.gyro_output == "rate" else GYRO_ANGLE_LSB_DEG * DEG
        self._gyro_k = float(dtype(lsb))
        self._T_w = float(dtype(self.T))
        self._pack6, self._unpack6 = rounder(dtype, 6).pack, rounder(dtype, 6).unpack
        self._bias_cache: tuple[Any, Any, tuple[float, ...]] = (None, None, ())
        #: the navigation state (None until the coarse alignment made it) and the filter of the build's variant
        self.nav: NavState | None = None
        self.filter: NavFilter = self.new_filter(cfg.filter)
        self._mag_hist: deque[tuple[float, tuple[int, int, int]]] = deque(maxlen=128)  # (t_sample_s, field)
        # magnetometer calibration: W^-1 and h, inverted once at start-up (docs/calibration.md)
        self._mag_w_inv = np.asarray(np.linalg.inv(np.asarray(cfg.mag_soft_iron, dtype=np.float64).reshape(3, 3)),
                                     dtype=np.float64)
        self._mag_h = np.asarray(cfg.mag_hard_iron_nt, dtype=np.float64)
        self._sub: list[tuple[FloatArray, FloatArray]] = []
        self._fn_sum = [0.0, 0.0, 0.0]  # sum of f^n over the KF interval (Python floats, float64)
        self._rot_sum = [0.0, 0.0, 0.0]  # sum of |phi_m| per body axis over the KF interval (rad)
        self._fn_n = 0
        self._hist: deque[tuple[float, NavFloats]] = deque(maxlen=int(2 * cfg.imu_rate_hz))  # (t, as_floats())
        self._t_last_predict = 0.0

    # -- the filter --------------------------------------------------------------------------------------
    def new_filter(self, name: str) -> NavFilter:
        """A fresh filter of the build's variant ``name``, attached to this core (it does not replace
        :attr:`filter`)."""
        cls: type[NavFilter] = FILTER_VARIANTS[name]
        flt = cls(self.cfg, self.meter, self.dtype)
        flt.attach(self)
        return flt

    def start(self, nav: NavState, heading_sigma: float, t: float) -> None:
        """The coarse alignment made ``nav`` at ``t`` (s): the filter starts from it with ``heading_sigma`` (rad)
        and the first KF interval begins."""
        self.nav = nav
        self.filter.initialise(nav, heading_sigma)
        self._t_last_predict = t

    def reset(self) -> None:
        """Back to before the coarse alignment: no navigation state, a fresh filter (biases included), the
        accumulators and the INS history empty."""
        self.nav = None
        self.filter = self.new_filter(self.cfg.filter)
        self._sub.clear()
        self._fn_sum = [0.0, 0.0, 0.0]
        self._rot_sum = [0.0, 0.0, 0.0]
        self._fn_n = 0
        self._hist.clear()

    def rebase(self, t: float, ticks_into_interval: int) -> None:
        """The FPGA time base moved (a reset) and the tick at ``t`` (s) is ``ticks_into_interval`` ticks into
        its KF interval: no KF interval across the jump, no history from the old base."""
        self._t_last_predict = t - ticks_into_interval * self.T
        self._hist.clear()

    def predict_due(self) -> bool:
        """Whether a strapdown step has entered the KF interval since the last time update."""
        return self._fn_n > 0

    def predict(self, t: float) -> None:
        """The filter's time update at tick time ``t`` (s) over the interval since the last (metered as
        ``kf_predict``), with the mean specific force and the rotation of the interval."""
        assert self.nav is not None  # the coarse alignment made it
        m = self.meter
        m.begin("kf_predict", self.cfg.kf_predict_every * self.T)
        n = self._fn_n
        fn = np.array([x / n for x in self._fn_sum])
        rot = (self._rot_sum[0], self._rot_sum[1], self._rot_sum[2])
        self._fn_sum = [0.0, 0.0, 0.0]
        self._rot_sum = [0.0, 0.0, 0.0]
        self._fn_n = 0
        Tk = t - self._t_last_predict  # the first interval after alignment may be shorter
        self._t_last_predict = t
        self.filter.rotation_b_rad = rot
        self.filter.predict(self.nav, fn, Tk)
        m.end()

    # -- mechanization -----------------------------------------------------------------------------------
    def mechanize(self, t: float, gyro: tuple[int, int, int], f_b: tuple[float, float, float]) -> None:
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
            # single-sample rotation compensation dv_m = dv_c + 1/2 phi_m x dv_c (docs/reference/algorithms.md 1.2,
            # step 1)
            phi_m, dv_m = coning_sculling_fast((px, py, pz), (ux, uy, uz), self.dtype)
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
            m.charge("coning_sculling", self._cyc_coning2)
        self._strapdown(s, phi_m, dv_m, Tm)  # strapdown_step_fast in nav_dtype (the kernel picked once)
        s.t = t
        m.charge("strapdown", self._cyc_strapdown)
        # specific force in n of the step, averaged for the KF's F (Eq. 17)
        x = s.as_floats()
        acc = self._fn_sum
        acc[0] += x[FE]
        acc[1] += x[FN]
        acc[2] += x[FU]
        rot = self._rot_sum  # |angle| per body axis over the KF interval (rotation-dependent noise)
        rot[0] += abs(phi_m[0])
        rot[1] += abs(phi_m[1])
        rot[2] += abs(phi_m[2])
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

    # -- the INS and MAG histories -----------------------------------------------------------------------
    def has_history(self) -> bool:
        """Whether the INS history holds a state (a measurement can be referred to its time)."""
        return bool(self._hist)

    def add_mag(self, t_sample_s: float, fld: tuple[int, int, int]) -> None:
        """A MAG frame's field (words of 0.1 nT, body) sampled at ``t_sample_s`` (FPGA time), into the history."""
        self._mag_hist.append((t_sample_s, fld))

    # -- FilterHost --------------------------------------------------------------------------------------
    def now_s(self) -> float:
        """FPGA time of the latest IMU frame, s (:meth:`.timekeeping.Clock.now_s`)."""
        return self.clock.now_s()

    def utc_days(self, t_fpga_s: float) -> float | None:
        """Grena days (UT) at FPGA time ``t_fpga_s`` once GNSS gave date and time
        (:meth:`.timekeeping.Clock.utc_days`)."""
        return self.clock.utc_days(t_fpga_s)

    def ins_at(self, t_meas: float) -> tuple[F64Array, FloatArray, FloatArray]:
        """INS position (float64), velocity and attitude quaternion at ``t_meas`` (2 s history, nearest entry)."""
        best = None
        for e in reversed(self._hist):
            if best is None or abs(e[0] - t_meas) < abs(best[0] - t_meas):
                best = e
            if e[0] < t_meas:
                break
        assert best is not None
        x, nd = best[1], self.nav_dtype
        return np.array(x[POS]), np.array(x[V], dtype=nd), np.array(x[Q], dtype=nd)

    def mag_mean_nt(self, t_center_s: float, half_window_s: float = 0.025) -> tuple[FloatArray, int] | None:
        """Mean MAG field (nT, body axes) of the frames sampled within ``t_center_s +- half_window_s``
        (FPGA time; e.g. a camera exposure), corrected with the calibrated iron, and their number; None when there is
        none. The sensor reads ``m = W B + h`` (``W`` soft iron, ``h`` hard iron, body axes); the firmware returns
        ``B = W^-1 (m - h)`` (docs/calibration.md)."""
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
        m = np.array(acc, dtype=np.float64) * (0.1 / n)  # MAG words are 0.1 nT
        self.meter.charge("mag_calibration", c674x.flops(9, 9))  # 3 SUB, 3x3 matrix-vector product
        return self._mag_w_inv @ (m - self._mag_h), n
