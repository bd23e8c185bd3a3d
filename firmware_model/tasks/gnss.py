"""GNSS staging (ISR side): NMEA GGA/GNS/RMC/GSA and UBX NAV-PVT into one measurement per receiver epoch.

Epochs. The sentences of one epoch carry the same UTC; they may arrive in one write or split over many (a
10 Hz receiver writing GGA and RMC separately). Everything with the same UTC time of day is one epoch and one
measurement; sentences without a time (GSA, VTG) belong to the open epoch. An epoch closes (becomes a
measurement for the loop's measurement task) when

* a message of a later epoch arrives (the stream moved on), or
* every message kind that made up the previous whole epoch has arrived (the stream's composition, learned
  like gpsd's cycle detection: GGA + RMC, RMC alone, NAV-PVT alone, ...), or
* ``cfg.gnss_epoch_hold_s`` has passed since its first byte (the first epoch, or a lost sentence).

Time of validity (FPGA time base, docs/icd.md "GNSS time tags"):

* with a PPS (latched by the FPGA within the last 2 s): the PPS edge marks the whole UTC second, so an epoch
  at UTC ``S + f`` is valid at ``t_pps + f + n``, the latest such time (``n`` whole seconds) at or before the
  arrival of its first message (PPS is 1 Hz at any navigation rate; the output latency is under a second);
* without PPS (an external receiver on a pty, no modem line): from the epoch's own UTC, ``t = UTC + c``,
  where the UTC-to-FPGA offset ``c`` is the smallest ``t_first_byte - latency - UTC`` over the last
  ``_OFFSET_WINDOW`` epochs (the first byte of an epoch is never early; the minimum removes the line and
  write jitter) and ``latency`` is ``cfg.gnss_latency_s``, the receiver's configured output latency (epoch
  to first byte). Never the parse tick.

Refused and ignored input is counted under the cause (``gnss_*`` counters, docs/icd.md): dead-reckoning
fixes (GGA quality 6, GNS mode E, RMC mode E, NAV-PVT fixType 1) are never fed back as measurements, epochs
without a fix are counted, NAV-PVT of an unknown payload length never reaches here (the framer refuses it).

The measurement update itself runs in the loop's measurement task (``Firmware._measurement_tasks``) with the
INS state at the fix's time of validity.
"""

from __future__ import annotations

import datetime as _dt
import math
from collections import deque
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from protocols.nmea import Gga, Gns, Gsa, Rmc
from protocols.ubx import NavPvt, UbxFrame

from .. import input_guard
from ..filters import GnssMeasurement
from ..units import DEG
from .timekeeping import TimeKeeping

__all__ = ["GNSS_COUNTERS", "GnssTask"]

#: epochs whose first-byte offset feeds the no-PPS UTC-to-FPGA offset (minimum over the window)
_OFFSET_WINDOW = 32
#: a first-byte offset this far (s) from the current minimum is a new time base (receiver restart, UTC step)
_OFFSET_JUMP_S = 1.0
#: message kinds that carry measurement content (the stream's composition is learned over these)
_CONTENT_KINDS = frozenset({"GGA", "GNS", "RMC", "GSA", "PVT"})
#: GNS mode characters with a GNSS fix (NMEA 4.10: A autonomous, D differential, P precise, R RTK fixed,
#: F RTK float); E is estimated (dead reckoning), N none, M manual, S simulator
_GNS_FIX = frozenset("ADPRF")
_GNS_QUALITY = {"A": 1, "D": 2, "P": 3, "R": 4, "F": 5}

#: counters of the GNSS path (all present in the summary from the start, docs/icd.md "GNSS input counters")
GNSS_COUNTERS = (
    "gnss_epochs",               # epochs closed (one measurement at most each)
    "gnss_epochs_split",         # epochs whose messages came in more than one chunk
    "gnss_epoch_timeouts",       # epochs closed by gnss_epoch_hold_s (no later epoch, composition not complete)
    "gnss_no_fix_epochs",        # epochs with no fix (GGA quality 0, RMC V, GNS N, NAV-PVT fixType 0/5)
    "gnss_dr_refused",           # dead-reckoning fixes not used as measurements (GGA 6, GNS/RMC E, PVT fixType 1)
    "gnss_2d_fixes",             # 2-D fixes (GSA/NAV-PVT fix type 2, RMC-only): horizontal position only
    "gnss_late_messages",        # content for an epoch that had already closed (dropped)
    "gnss_no_utc",               # fixes without a UTC time (tagged at arrival minus latency)
    "gnss_tag_pps",              # epochs tagged from the PPS edge
    "gnss_tag_utc",              # epochs tagged from their UTC and the configured latency (no PPS)
    "gnss_utc_offset_resets",    # UTC-to-FPGA offset restarted (a step of more than 1 s)
    "gnss_pvt_ignored_flags",    # NAV-PVT with gnssFixOK clear
    "gnss_ubx_other",            # checked UBX frames not used (other classes/ids)
    "gnss_nmea_other",           # checked NMEA sentences not used (GSV, VTG, ZDA, TXT, proprietary ...)
)


@dataclass
class _Epoch:
    """One receiver epoch being assembled."""

    utc_s: float | None            # UTC seconds (days since the first epoch * 86400 + time of day)
    t_first: float                  # FPGA time of its first byte (s)
    t_rx: float = 0.0               # FPGA time the chunk completing its first message arrived (s)
    kinds: set[str] = field(default_factory=set)
    chunks: int = 0
    last_chunk: int = -1
    pos3: tuple[float, float, float] | None = None      # GGA / GNS / NAV-PVT (lat rad, lon rad, h m)
    pos2: tuple[float, float] | None = None              # RMC horizontal position (lat rad, lon rad)
    vel: Any = None
    vel_up: bool = False
    quality: int = 1
    fix2d: bool = False
    dr: bool = False
    no_fix: bool = False
    date: Any = None
    tod: Any = None


class GnssTask(TimeKeeping):
    """Parse GNSS messages into one measurement per epoch; the date and time set UTC
    (:class:`~.timekeeping.TimeKeeping`)."""

    def _gnss_init(self) -> None:
        """State of the GNSS path (called from ``Firmware.__init__``)."""
        self._gnss_epoch: _Epoch | None = None
        self._gnss_ready: deque[tuple[GnssMeasurement, _Epoch]] = deque(maxlen=8)
        self._gnss_kinds_last: frozenset[str] = frozenset()
        self._gnss_kinds_cur: set[str] = set()
        self._gnss_closed_utc: float | None = None
        self._gnss_offsets: deque[float] = deque(maxlen=_OFFSET_WINDOW)
        self._gnss_day = 0
        self._gnss_last_tod: float | None = None
        self._gnss_chunk = 0
        self._gnss_chunk_start = 0.0
        self._gnss_chunk_t_rx = 0.0
        for k in GNSS_COUNTERS:
            self.counters.setdefault(k, 0)

    # -- bytes in -------------------------------------------------------------------------------------
    def _on_gnss_bytes(self, data: bytes, t_rx_s: float | None) -> None:
        """One chunk from UART3: ``t_rx_s`` is when its last byte arrived (the ISR's time stamp)."""
        dec = self._dec_gnss
        t_rx = t_rx_s if t_rx_s is not None else self._now_s()
        self._gnss_chunk += 1
        self._gnss_chunk_t_rx = t_rx
        if dec.pending() == 0:
            # line idle before this chunk: its first byte started (n bytes before its end) at
            byte_s = self.cfg.gnss_bits_per_byte / self.cfg.gnss_baud
            self._gnss_chunk_start = t_rx - len(data) * byte_s
        for s in dec.feed(data):
            try:
                if isinstance(s, NavPvt):
                    self._on_nav_pvt(s)
                elif isinstance(s, UbxFrame):
                    self.counters["gnss_ubx_other"] += 1
                else:
                    self._on_nmea(s)
            except Exception as e:
                self._fault("gnss message", e)  # type: ignore[attr-defined]  # Firmware's containment
            self._gnss_after_message()
            # the next message of this chunk started after this one: only the first is dated by the chunk
            self._gnss_chunk_start = math.nan

    def _gnss_decoder_stats(self) -> dict[str, Any]:
        """UART3 decoder counters plus ``lf_only`` (NMEA lines accepted with an LF-only end)."""
        dec = self._dec_gnss
        return {**dec.stats.as_dict(), "lf_only": getattr(dec.formats[0], "lf_only", 0)}

    # -- messages --------------------------------------------------------------------------------------
    def _on_nmea(self, s: Any) -> None:
        """GGA / GNS: position fix; RMC: horizontal velocity, date (and the position of RMC-only streams);
        GSA: 2-D / 3-D fix type. Other sentences are counted and left alone."""
        if isinstance(s, Gga):
            reason = input_guard.check_gga(s) if s.quality != 0 else None
            if reason is not None:
                self._reject(reason)
                return
            e = self._gnss_epoch_for("GGA", _tod(s.time_utc))
            if e is None:
                return
            if s.quality == 0 or s.lat_deg is None or s.lon_deg is None:
                e.no_fix = True
                return
            if s.quality == 6:
                e.dr = True
                return
            if s.altitude_msl_m is None:
                e.fix2d = True
                e.pos2 = (s.lat_deg * DEG, s.lon_deg * DEG)
            else:
                e.pos3 = (s.lat_deg * DEG, s.lon_deg * DEG, s.altitude_msl_m + (s.geoid_sep_m or 0.0))
                self._last_fix = (*e.pos3, s.quality)
            e.quality = s.quality
        elif isinstance(s, Gns):
            reason = input_guard.check_gns(s) if s.lat_deg is not None else None
            if reason is not None:
                self._reject(reason)
                return
            e = self._gnss_epoch_for("GNS", _tod(s.time_utc))
            if e is None:
                return
            modes = set(s.mode or "N")
            if not modes & _GNS_FIX or s.lat_deg is None or s.lon_deg is None:
                if "E" in modes:
                    e.dr = True
                else:
                    e.no_fix = True
                return
            best = max((_GNS_QUALITY[c] for c in modes & _GNS_FIX), key=lambda q: (q in (4, 5), q))
            if s.altitude_msl_m is None:
                e.fix2d = True
                e.pos2 = (s.lat_deg * DEG, s.lon_deg * DEG)
            else:
                e.pos3 = (s.lat_deg * DEG, s.lon_deg * DEG, s.altitude_msl_m + (s.geoid_sep_m or 0.0))
                self._last_fix = (*e.pos3, best)
            e.quality = best
        elif isinstance(s, Rmc):
            reason = input_guard.check_rmc(s)
            if reason is not None:
                self._reject(reason)
                return
            e = self._gnss_epoch_for("RMC", _tod(s.time_utc))
            if e is None:
                return
            if s.date is not None:
                self._date = s.date
                e.date = s.date
            if s.mode == "E":
                e.dr = True
                return
            if not s.valid:
                e.no_fix = True
                return
            if s.lat_deg is not None and s.lon_deg is not None:
                e.pos2 = (s.lat_deg * DEG, s.lon_deg * DEG)
            if s.speed_mps is not None:
                c = (s.course_deg or 0.0) * DEG
                e.vel = np.array([s.speed_mps * math.sin(c), s.speed_mps * math.cos(c), 0.0])
                e.vel_up = False
        elif isinstance(s, Gsa):
            e = self._gnss_epoch_for("GSA", None)
            if e is not None and s.fix_type == 2:
                e.fix2d = True
        else:
            self.counters["gnss_nmea_other"] += 1

    def _on_nav_pvt(self, p: NavPvt) -> None:
        """UBX NAV-PVT (any protocol version: 84-byte protocol 14 and 92-byte 15+): position, 3-D velocity
        (velD) and UTC (hour:min:sec + nano)."""
        self.counters["gnss_pvt"] += 1
        tod: float | None = None
        if p.valid & 0x02:  # validTime
            if not (0 <= p.hour <= 23 and 0 <= p.min <= 59 and 0 <= p.sec <= 60):
                self._reject("date")
                return
            tod = p.hour * 3600.0 + p.min * 60.0 + p.sec + (p.nano * 1e-9 if abs(p.nano) < 1_000_000_000 else 0.0)
        if p.valid & 0x03 == 0x03:  # validDate | validTime
            dt = input_guard.nav_pvt_datetime(p)  # a leap second (sec = 60) is legal; month 13 is not
            if dt is None:
                self._reject("date")
                return
            self._date = dt[0]
        e = self._gnss_epoch_for("PVT", tod)
        if e is None:
            return
        if p.valid & 0x03 == 0x03:
            e.date = self._date
        if p.fixType == 1:
            e.dr = True
            return
        if p.fixType in (0, 5):
            e.no_fix = True
            return
        if not p.flags & 0x01:  # gnssFixOK clear: outside the receiver's accuracy masks
            self.counters["gnss_pvt_ignored_flags"] += 1
            e.no_fix = True
            return
        reason = input_guard.check_nav_pvt(p)
        if reason is not None:
            self._reject(reason)
            return
        e.quality = {1: 5, 2: 4}.get((p.flags >> 6) & 0x03, 2 if p.flags & 0x02 else 1)  # RTK float/fixed, DGNSS
        if p.fixType == 2:
            e.fix2d = True
            e.pos2 = (p.lat * 1e-7 * DEG, p.lon * 1e-7 * DEG)
        else:  # 3 (3-D) or 4 (GNSS + DR)
            e.pos3 = (p.lat * 1e-7 * DEG, p.lon * 1e-7 * DEG, p.height * 1e-3)
            self._last_fix = (*e.pos3, e.quality)
        e.vel = np.array([p.velE * 1e-3, p.velN * 1e-3, -p.velD * 1e-3])
        e.vel_up = p.fixType != 2

    # -- epochs ----------------------------------------------------------------------------------------
    def _gnss_utc_s(self, tod: float) -> float:
        """Continuous UTC seconds from a time of day (a day is added when the time of day wraps)."""
        last = self._gnss_last_tod
        if last is not None and tod < last - 43200.0:
            self._gnss_day += 1
        elif last is not None and tod > last + 43200.0:
            self._gnss_day -= 1  # an old epoch after midnight (out of order): keep it on its own day
        self._gnss_last_tod = tod
        return self._gnss_day * 86400.0 + tod

    def _gnss_epoch_for(self, kind: str, tod: float | None) -> _Epoch | None:
        """The open epoch a message of ``kind`` with time of day ``tod`` (s, None: no time) belongs to; a message
        of a new time closes the open epoch first. None: the message belongs to an epoch already closed."""
        utc = self._gnss_utc_s(tod) if tod is not None else None
        e = self._gnss_epoch
        if utc is not None and e is not None and e.utc_s is not None and abs(utc - e.utc_s) > 1e-4:
            self._gnss_close(e)
            e = None
        if utc is not None and self._gnss_closed_utc is not None and abs(utc - self._gnss_closed_utc) < 1e-4:
            self._gnss_kinds_cur.add(kind)
            if e is None:
                self.counters["gnss_late_messages"] += 1
                return None
        if e is None:
            if utc is None and self._gnss_closed_utc is not None:
                self._gnss_kinds_cur.add(kind)  # e.g. GSA after its epoch closed: part of the composition
                return None
            if utc is not None and (self._gnss_closed_utc is None or abs(utc - self._gnss_closed_utc) > 1e-4):
                # a new UTC: the previous one's whole composition is known now
                if self._gnss_kinds_cur:
                    self._gnss_kinds_last = frozenset(self._gnss_kinds_cur & _CONTENT_KINDS)
                self._gnss_kinds_cur = set()
            t_first = self._gnss_chunk_start
            if math.isnan(t_first):
                t_first = self._now_s() if self._t_last_us is not None else 0.0
                first_ok = False
            else:
                first_ok = True
            e = self._gnss_epoch = _Epoch(utc_s=utc, t_first=t_first, t_rx=self._gnss_chunk_t_rx)
            e.tod = tod
            if utc is not None and first_ok:
                self._gnss_offset_sample(t_first - utc)
        elif e.utc_s is None and utc is not None:
            e.utc_s = utc
            e.tod = tod
        e.kinds.add(kind)
        self._gnss_kinds_cur.add(kind)
        if e.last_chunk != self._gnss_chunk:
            e.chunks += 1
            e.last_chunk = self._gnss_chunk
        return e

    def _gnss_after_message(self) -> None:
        """Close the open epoch when its composition is complete (called after each message)."""
        e = self._gnss_epoch
        want = self._gnss_kinds_last
        if e is not None and want and want <= e.kinds:
            self._gnss_close(e)

    def _gnss_offset_sample(self, x: float) -> None:
        offs = self._gnss_offsets
        if offs and abs(x - min(offs)) > _OFFSET_JUMP_S:
            offs.clear()
            self.counters["gnss_utc_offset_resets"] += 1
        offs.append(x)

    def _gnss_time_of_validity(self, e: _Epoch) -> float:
        """FPGA time (s) at which the epoch's fix is valid (module docstring)."""
        t_ref = e.t_first
        t_pps = self._t_pps_s
        if e.utc_s is None:
            self.counters["gnss_no_utc"] += 1
            return t_ref - self.cfg.gnss_latency_s
        t_rx = max(e.t_rx, t_ref)
        if t_pps is not None and t_rx - t_pps < 2.0:
            # the latest t_pps + f + n (n whole seconds) at or before the arrival: the epoch precedes its bytes by
            # less than a second; the PPS edge of its own second may not be latched yet (n = 1)
            frac = e.utc_s - math.floor(e.utc_s + 1e-9)
            frac = frac if frac > 1e-9 else 0.0
            t = t_pps + frac
            while t + 1.0 <= t_rx + 1e-6:
                t += 1.0
            while t > t_rx + 1e-6:
                t -= 1.0
            self.counters["gnss_tag_pps"] += 1
            return t
        self.counters["gnss_tag_utc"] += 1
        off = min(self._gnss_offsets) if self._gnss_offsets else t_ref - e.utc_s
        return e.utc_s + off - self.cfg.gnss_latency_s

    def _gnss_close(self, e: _Epoch) -> None:
        """The epoch is complete: one measurement (or a counted reason for none)."""
        self._gnss_epoch = None
        self._gnss_closed_utc = e.utc_s
        self.counters["gnss_epochs"] += 1
        if e.chunks > 1:
            self.counters["gnss_epochs_split"] += 1
        t_meas = self._gnss_time_of_validity(e)
        date = e.date if e.date is not None else self._date
        if date is not None and e.tod is not None and (e.date is not None or e.pos3 is not None or e.pos2 is not None):
            h, rem = divmod(e.tod % 86400.0, 3600.0)
            mi, sec = divmod(rem, 60.0)
            whole = min(int(sec), 59)
            self._set_utc(t_meas, date, _dt.time(int(h), int(mi), whole, min(999_999, round((sec - whole) * 1e6))))
        if e.dr:
            self.counters["gnss_dr_refused"] += 1
            return
        if e.no_fix and e.pos3 is None and e.pos2 is None:
            self.counters["gnss_no_fix_epochs"] += 1
            return
        m = GnssMeasurement(t_fpga_s=t_meas)
        if e.pos3 is not None and not e.fix2d:
            m.pos = e.pos3
        elif e.pos3 is not None or e.pos2 is not None:
            lat, lon = e.pos3[:2] if e.pos3 is not None else e.pos2  # type: ignore[misc]
            m.pos = (lat, lon, 0.0)
            m.pos_up = False
            self.counters["gnss_2d_fixes"] += 1
        m.vel, m.vel_up, m.quality = e.vel, e.vel_up, e.quality
        if m.pos is None and m.vel is None:
            self.counters["gnss_no_fix_epochs"] += 1
            return
        if m.pos is not None:
            self.counters["gnss_fixes"] += 1
            if not m.pos_up:
                # a 2-D fix: the receiver's held height (GGA) or the last 3-D one, else 0 m (alignment input only)
                h = e.pos3[2] if e.pos3 is not None else (self._last_fix[2] if self._last_fix is not None else 0.0)
                self._last_fix = (m.pos[0], m.pos[1], h, m.quality)
        self._gnss_ready.append((m, e))

    def _gnss_hold(self, t: float) -> None:
        """Every tick (also while aligning): close an epoch held longer than ``gnss_epoch_hold_s``."""
        e = self._gnss_epoch
        if e is not None and t - e.t_first > self.cfg.gnss_epoch_hold_s:
            self.counters["gnss_epoch_timeouts"] += 1
            self._gnss_close(e)

    def _gnss_poll(self, t: float) -> None:
        """Loop side, once per tick: close an epoch held too long; hand the oldest closed one to the update."""
        if self._gnss_epoch is not None:  # (the usual tick holds none: no call)
            self._gnss_hold(t)
        if self._gnss_pending is None and self._gnss_ready:
            self._gnss_pending = self._gnss_ready.popleft()[0]


def _tod(t: Any) -> float | None:
    """Seconds of the day of a ``datetime.time`` (None: no time)."""
    if t is None:
        return None
    return float(t.hour * 3600.0 + t.minute * 60.0 + t.second + t.microsecond * 1e-6)
