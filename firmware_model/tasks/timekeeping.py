"""Time keeping: the FPGA time base (32-bit microsecond counter, unwrapped), PPS edges and UTC from GNSS.

Every time in the loop is FPGA time in seconds; UTC (for the sun ephemeris) is tied to it at a PPS edge
by the GNSS date and time (:meth:`Clock.utc_days`). :class:`Clock` is one task object of the cyclic executive
(:class:`firmware_model.firmware.Firmware` owns it and hands it to the tasks that read the time): its state is its
own, the other tasks use its methods.
"""

from __future__ import annotations

import datetime as _dt

from .. import sun
from ..config import FirmwareConfig

__all__ = ["Clock"]

#: the GPS week count's day 0 (IS-GPS-200)
_GPS_EPOCH = _dt.date(1980, 1, 6)


class Clock:
    """FPGA time and UTC (the services :meth:`now_s` and :meth:`utc_days` of
    :class:`firmware_model.filters.interface.FilterHost`).

    Collaborators: ``cfg`` (GPS week era, date-jump tolerance) and ``counters`` (the loop's counter table, shared:
    ``gnss_date_refused``, ``utc_stale_pps``, ``utc_stale_tag``)."""

    def __init__(self, cfg: FirmwareConfig, counters: dict[str, int]) -> None:
        self._cfg = cfg
        self._counters = counters
        #: the latest IMU frame's 32-bit time stamp (us) and the epoch (us) its unwrapping added; None: no frame yet
        self._t_last_us: int | None = None
        self._t_epoch_us = 0
        #: FPGA time of the latest PPS edge (s) and the PPS count of the frame that reported it
        self._t_pps_s: float | None = None
        self._pps_count: int | None = None
        #: Grena days (UT) at FPGA time ``_utc_t_ref`` (s); None: no UTC yet
        self._utc_days_ref: float | None = None
        self._utc_t_ref = 0.0
        #: the receiver's date last taken (:meth:`take_date`)
        self._date: _dt.date | None = None

    # -- the FPGA time base -----------------------------------------------------------------------------
    def now_s(self) -> float:
        """FPGA time of the latest IMU frame, s (0 before the first)."""
        if self._t_last_us is None:
            return 0.0
        return (self._t_epoch_us + self._t_last_us) / 1e6

    def last_us(self) -> int | None:
        """Unwrapped FPGA time of the latest IMU frame, us; None before the first (or after :meth:`rebase`)."""
        if self._t_last_us is None:
            return None
        return self._t_epoch_us + self._t_last_us

    def unwrap_us(self, t_us: int) -> int:
        """The 32-bit time stamp ``t_us`` of a new IMU frame unwrapped (us); it becomes the latest time."""
        if self._t_last_us is not None and t_us < self._t_last_us and self._t_last_us - t_us > 2**31:
            self._t_epoch_us += 2**32
        self._t_last_us = t_us
        return self._t_epoch_us + t_us

    def unwrap_near(self, t_us: int) -> int:
        """A 32-bit FPGA time stamp near the latest IMU time, unwrapped like :meth:`unwrap_us` (us)."""
        base = self._t_epoch_us + (self._t_last_us or 0)
        full = (base & ~0xFFFFFFFF) | (t_us & 0xFFFFFFFF)
        if full - base > 2**31:
            full -= 2**32
        elif base - full > 2**31:
            full += 2**32
        return full

    def rebase(self, t_new_us: int, t_raw_us: int) -> int:
        """Take a new FPGA time base (the FPGA was reset): the raw stamp ``t_raw_us`` is unwrapped time ``t_new_us``
        (us); the next frame starts the base. Returns the epoch (us) added to raw stamps from now on."""
        self._t_epoch_us = t_new_us - t_raw_us
        self._t_last_us = None
        return self._t_epoch_us

    def epoch_us(self) -> int:
        """The epoch (us) the unwrapping adds to a raw 32-bit stamp."""
        return self._t_epoch_us

    def pps_edge(self, t_us: int, pps_count: int, t_pps_raw_us: int) -> None:
        """A frame flagged PPS-valid at unwrapped time ``t_us`` (us) reports PPS ``pps_count`` latched at raw stamp
        ``t_pps_raw_us``; a new count moves the PPS edge."""
        if pps_count != self._pps_count:
            self._pps_count = pps_count
            full = (t_us & ~0xFFFFFFFF) | t_pps_raw_us
            if full > t_us:
                full -= 2**32
            self._t_pps_s = full / 1e6

    @property
    def t_pps_s(self) -> float | None:
        """FPGA time of the latest PPS edge, s (None before the first)."""
        return self._t_pps_s

    # -- UTC --------------------------------------------------------------------------------------------
    @property
    def date(self) -> _dt.date | None:
        """The receiver's date last taken (None before the first)."""
        return self._date

    def utc_days(self, t_fpga_s: float) -> float | None:
        """Grena days (UT since 2060-01-01) at FPGA time ``t_fpga_s``, once GNSS gave date and time."""
        if self._utc_days_ref is None:
            return None
        return self._utc_days_ref + (t_fpga_s - self._utc_t_ref) / 86400.0

    def date_ok(self, date: _dt.date) -> bool:
        """Whether a receiver's date may be taken (counted ``gnss_date_refused`` when not): inside the firmware's
        GPS week era (``cfg.gnss_era_start`` + 1024 weeks: a date before it is a week-rollover or RTC date, as gpsd
        reads a week before its build week), and within ``cfg.gnss_date_jump_tol_s`` of the firmware's running
        clock once it has one (the date of a receiver that rolled over jumps by 1024 weeks)."""
        start = _GPS_EPOCH + _dt.timedelta(weeks=self._cfg.gnss_era_start_week)
        ok = start <= date < start + _dt.timedelta(weeks=1024)
        if ok and self._utc_days_ref is not None and self._date is not None:
            ok = abs((date - self._date).days) * 86400.0 <= self._cfg.gnss_date_jump_tol_s + 86400.0
        if not ok:
            self._counters["gnss_date_refused"] = self._counters.get("gnss_date_refused", 0) + 1
        return ok

    def take_date(self, date: _dt.date) -> None:
        """The receiver's date, taken when :meth:`date_ok`."""
        if self.date_ok(date):
            self._date = date

    def set_utc(self, t_meas: float, date: _dt.date, tm: _dt.time, pps: bool = False) -> None:
        """Tie UTC ``date`` ``tm`` to FPGA time ``t_meas`` (s; ``pps``: at a PPS edge), unless the epoch is stale or
        jumps against the running clock (counted)."""
        if self.now_s() - t_meas > 1.5:
            # an epoch this old (an outage: the receiver still sends its clock's time without a fix or a pulse):
            # tagging it to the last, stale PPS edge would make UTC gain a second per second
            key = "utc_stale_pps" if pps else "utc_stale_tag"
            self._counters[key] = self._counters.get(key, 0) + 1
            return
        hour = tm.hour + tm.minute / 60.0 + (tm.second + tm.microsecond * 1e-6) / 3600.0
        days = sun.grena_days(date.year, date.month, date.day, hour)
        run = self.utc_days(t_meas)
        if run is not None and abs(days - run) * 86400.0 > self._cfg.gnss_date_jump_tol_s:
            # the date and time jump against the running clock (a rollover, an RTC date): refused
            self._counters["gnss_date_refused"] = self._counters.get("gnss_date_refused", 0) + 1
            return
        self._utc_days_ref = days
        self._utc_t_ref = t_meas
