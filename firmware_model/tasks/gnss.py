"""GNSS staging (ISR side): NMEA GGA/RMC and UBX NAV-PVT into one pending measurement at its PPS time.

The measurement update itself runs in the loop's measurement task (``Firmware._measurement_tasks``) with the
INS state at the fix's time of validity.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from protocols.nmea import Gga, Rmc
from protocols.ubx import NavPvt

from .. import input_guard
from ..filters import GnssMeasurement
from ..units import DEG
from .timekeeping import TimeKeeping

__all__ = ["GnssTask"]


class GnssTask(TimeKeeping):
    """Parse and stage GNSS fixes; the date and time set UTC (:class:`~.timekeeping.TimeKeeping`)."""
    def _on_nmea(self, s: Any) -> None:
        """GGA gives a position fix, RMC a horizontal velocity and the date; both valid at the last PPS."""
        t_meas = self._t_pps_s if self._t_pps_s is not None else self._now_s()
        if isinstance(s, Gga):
            if s.quality == 0 or s.lat_deg is None or s.lon_deg is None or s.altitude_msl_m is None:
                return
            reason = input_guard.check_gga(s)
            if reason is not None:
                self._reject(reason)
                return
            pos = (s.lat_deg * DEG, s.lon_deg * DEG, s.altitude_msl_m + (s.geoid_sep_m or 0.0))
            self.counters["gnss_fixes"] += 1
            m = self._stage_gnss(t_meas)
            m.pos, m.quality = pos, s.quality
            self._last_fix = (pos[0], pos[1], pos[2], s.quality)
            if s.time_utc is not None and self._date is not None:
                self._set_utc(t_meas, self._date, s.time_utc)
        elif isinstance(s, Rmc):
            reason = input_guard.check_rmc(s)
            if reason is not None:
                self._reject(reason)
                return
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
            dt = input_guard.nav_pvt_datetime(p)  # a leap second (sec = 60) is legal; month 13 is not
            if dt is None:
                self._reject("date")
            else:
                self._date = dt[0]
                self._set_utc(t_pps, dt[0], dt[1])
        if not p.flags & 0x01 or p.fixType not in (3, 4):  # gnssFixOK and a 3-D (or GNSS + DR) fix
            return
        reason = input_guard.check_nav_pvt(p)
        if reason is not None:
            self._reject(reason)
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
