"""Time keeping: the FPGA time base (32-bit microsecond counter, unwrapped), PPS edges and UTC from GNSS.

Every time in the loop is FPGA time in seconds; UTC (for the sun ephemeris) is tied to it at a PPS edge
by the GNSS date and time (:meth:`TimeKeeping.utc_days`).
"""

from __future__ import annotations

import datetime as _dt

from .. import sun
from .state import LoopState

__all__ = ["TimeKeeping"]

#: the GPS week count's day 0 (IS-GPS-200)
_GPS_EPOCH = _dt.date(1980, 1, 6)


class TimeKeeping(LoopState):
    """FPGA time and UTC (services of :class:`firmware_model.filters.FilterHost`: :meth:`now_s`, :meth:`utc_days`)."""
    def now_s(self) -> float:
        """FPGA time of the latest IMU frame, s."""
        return self._now_s()

    def _now_s(self) -> float:
        if self._t_last_us is None:
            return 0.0
        return (self._t_epoch_us + self._t_last_us) / 1e6

    def _unwrap_us(self, t_us: int) -> int:
        if self._t_last_us is not None and t_us < self._t_last_us and self._t_last_us - t_us > 2**31:
            self._t_epoch_us += 2**32
        self._t_last_us = t_us
        return self._t_epoch_us + t_us

    def _unwrap_near(self, t_us: int) -> int:
        """A 32-bit FPGA time stamp near the latest IMU time, unwrapped like :meth:`_unwrap_us`."""
        base = self._t_epoch_us + (self._t_last_us or 0)
        full = (base & ~0xFFFFFFFF) | (t_us & 0xFFFFFFFF)
        if full - base > 2**31:
            full -= 2**32
        elif base - full > 2**31:
            full += 2**32
        return full

    def utc_days(self, t_fpga_s: float) -> float | None:
        """Grena days (UT since 2060-01-01) at FPGA time ``t_fpga_s``, once GNSS gave date and time."""
        if self._utc_days_ref is None:
            return None
        return self._utc_days_ref + (t_fpga_s - self._utc_t_ref) / 86400.0

    def _gnss_date_ok(self, date: _dt.date) -> bool:
        """Whether a receiver's date may be taken (counted ``gnss_date_refused`` when not): inside the firmware's
        GPS week era (``cfg.gnss_era_start`` + 1024 weeks: a date before it is a week-rollover or RTC date, as gpsd
        reads a week before its build week), and within ``cfg.gnss_date_jump_tol_s`` of the firmware's running
        clock once it has one (the date of a receiver that rolled over jumps by 1024 weeks)."""
        start = _GPS_EPOCH + _dt.timedelta(weeks=self.cfg.gnss_era_start_week)
        ok = start <= date < start + _dt.timedelta(weeks=1024)
        if ok and self._utc_days_ref is not None and self._date is not None:
            ok = abs((date - self._date).days) * 86400.0 <= self.cfg.gnss_date_jump_tol_s + 86400.0
        if not ok:
            self.counters["gnss_date_refused"] = self.counters.get("gnss_date_refused", 0) + 1
        return ok

    def _set_utc(self, t_meas: float, date: _dt.date, tm: _dt.time, pps: bool = False) -> None:
        if self._now_s() - t_meas > 1.5:
            # an epoch this old (an outage: the receiver still sends its clock's time without a fix or a pulse):
            # tagging it to the last, stale PPS edge would make UTC gain a second per second
            key = "utc_stale_pps" if pps else "utc_stale_tag"
            self.counters[key] = self.counters.get(key, 0) + 1
            return
        hour = tm.hour + tm.minute / 60.0 + (tm.second + tm.microsecond * 1e-6) / 3600.0
        days = sun.grena_days(date.year, date.month, date.day, hour)
        run = self.utc_days(t_meas)
        if run is not None and abs(days - run) * 86400.0 > self.cfg.gnss_date_jump_tol_s:
            # the date and time jump against the running clock (a rollover, an RTC date): refused
            self.counters["gnss_date_refused"] = self.counters.get("gnss_date_refused", 0) + 1
            return
        self._utc_days_ref = days
        self._utc_t_ref = t_meas
