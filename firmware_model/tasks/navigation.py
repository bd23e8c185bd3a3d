"""The navigation task: bias compensation, coning/sculling and the strapdown per IMU sample, the INS history.

Also the services a filter variant asks of the loop (:class:`firmware_model.filters.FilterHost`): the INS state
at a measurement's time (2 s history) and the mean of the MAG frames around a given time.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .. import c674x
from ..arrays import F64Array, FloatArray
from ..config import FILTER_VARIANTS
from ..filters import NavFilter
from ..nav_state import FE, FN, FU, POS, Q, V
from ..strapdown import coning_sculling, coning_sculling_fast
from .state import LoopState

__all__ = ["Navigation"]


class Navigation(LoopState):
    """Mechanization per IMU sample; the filter and the services it uses (a ``FilterHost``)."""

    def _new_filter(self, name: str) -> NavFilter:
        """A fresh filter of the build's variant ``name``, attached to this loop."""
        cls: type[NavFilter] = FILTER_VARIANTS[name]
        flt = cls(self.cfg, self.meter, self.dtype)
        flt.attach(self)
        return flt

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
            m.charge("coning_sculling", self._cyc["coning2"])
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

    def now_s(self) -> float:
        """FPGA time of the latest IMU frame, s (:meth:`.timekeeping.Clock.now_s`)."""
        return self.clock.now_s()

    def utc_days(self, t_fpga_s: float) -> float | None:
        """Grena days (UT) at FPGA time ``t_fpga_s`` once GNSS gave date and time
        (:meth:`.timekeeping.Clock.utc_days`)."""
        return self.clock.utc_days(t_fpga_s)

    def ins_at(self, t_meas: float) -> tuple[F64Array, FloatArray, FloatArray]:
        """INS position, velocity and attitude quaternion at ``t_meas`` (2 s history, nearest entry)."""
        return self._ins_at(t_meas)

    def _ins_at(self, t_meas: float) -> tuple[F64Array, FloatArray, FloatArray]:
        """INS position (float64), velocity and attitude quaternion at ``t_meas`` (nearest history entry)."""
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
