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

The time base follows the receiver (docs/icd.md 5.1.3, D-5.39): every epoch gives a sample of the
offset, whatever message opens it (ZDA, GST and the UBX time messages open an epoch like GGA; a sample is tight
when the opening message is the first of its chunk, else bounded by the chunk's arrival). A sample more than
``cfg.gnss_clock_step_tol_s`` from the current offset is a step of the receiver's clock: the epoch is refused
(``gnss_clock_step_refused``: neither its fix nor its time is used) until ``cfg.gnss_clock_rebase_epochs``
consecutive epochs agree on the new offset; the last of them re-bases the offset (``gnss_clock_steps``) and is
used. One epoch never moves UTC. UBX epochs are placed on GPS time (UTC + the receiver's leap seconds, NAV-TIMEGPS
``leapS`` or UTC against iTOW), so a leap second is no step; an NMEA-only stream sees it as a 1 s step. A tag later
than the arrival of its own bytes (``gnss_tag_future``) or older than ``cfg.gnss_max_age_s`` at the close
(``gnss_tag_stale``) is refused.

Fix quality as receivers mean it (docs/icd.md 5.1.3): GGA quality 6 / mode E
(dead reckoning), 7 / M (manual input) and 8 / S (simulator) are not fixes (``gnss_dr_refused``,
``gnss_manual_refused``, ``gnss_sim_refused``); fewer than 4 satellites is no 3-D fix (3: horizontal only,
fewer: none, ``gnss_few_sats``); GSA fix type 1 is no fix; UBX fix types above 5 are reserved, not fixes
(``gnss_fix_type_unknown``). An empty geoid-separation field is filled from the firmware's own EGM96 table
(:mod:`firmware_model.geoid`, ``gnss_geoid_filled``), never MSL taken as ellipsoidal height.

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
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from protocols.nmea import Gga, Gns, Gsa, Gst, NmeaSentence, Rmc, Zda
from protocols.stream import StreamDecoder
from protocols.ubx import NavPosllh, NavPvt, NavSol, NavStatus, NavTimeGps, NavTimeUtc, NavVelned, UbxFrame

from .. import input_guard
from ..config import FirmwareConfig
from ..earth import ecef_to_geodetic
from ..filters.gnss import GnssMeasurement
from ..geoid import geoid_separation_m
from ..units import DEG
from .state import count_rejection
from .timekeeping import Clock

__all__ = ["GNSS_COUNTERS", "GnssTask"]

#: epochs whose first-byte offset feeds the no-PPS UTC-to-FPGA offset (minimum over the window)
_OFFSET_WINDOW = 32
#: message kinds that carry measurement content or time (the stream's composition is learned over these)
_CONTENT_KINDS = frozenset({"GGA", "GNS", "RMC", "GSA", "PVT", "ZDA", "TIME", "POSLLH", "SOL", "VELNED", "TIMEUTC",
                            "TIMEGPS", "STATUS"})
#: NMEA sentences carrying only a UTC time of day (field index): they open an epoch like GGA (Ashtech, Septentrio
#: and SiRF bursts open with GST or ZDA)
_TIME_ONLY = {"GBS": 1, "GRS": 1, "GLL": 5}
#: GPS - UTC (s) assumed for UBX messages that carry only GPS time until the receiver reports its own (NAV-TIMEGPS
#: leapS, or NAV-PVT / NAV-TIMEUTC UTC against iTOW): IERS Bulletin C, since 2017-01-01
_LEAP_DEFAULT_S = 18
#: epoch kinds of the UBX messages before NAV-PVT, and of the messages that carry their own fix indication
_LEGACY_KINDS = frozenset({"POSLLH", "VELNED", "SOL", "STATUS"})
_FIX_KINDS = frozenset({"GGA", "GNS", "RMC", "PVT"})
#: refusals whose epoch's time and date are not the receiver's real clock either (simulator, manual input)
_NOT_REAL = frozenset({"gnss_sim_refused", "gnss_manual_refused"})
#: UBX fix types that are fixes (2 2-D, 3 3-D, 4 GNSS + DR); 0 none, 1 DR, 5 time only, 6+ reserved
_UBX_FIX = (2, 3, 4)
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
    "gnss_utc_offset_resets",    # UTC-to-FPGA offset re-based after a clock step (same as gnss_clock_steps)
    "gnss_clock_steps",          # receiver clock steps detected and re-based on (N consecutive agreeing epochs)
    "gnss_clock_step_refused",   # epochs refused while their clock disagreed with the time base
    "gnss_tag_future",           # epochs whose tag was later than the arrival of their bytes (refused)
    "gnss_tag_stale",            # epochs whose tag was older than gnss_max_age_s (refused)
    "gnss_date_refused",         # dates refused: outside the firmware's GPS week era, or a jump against its clock
    "gnss_manual_refused",       # manual-input fixes (GGA 7, GNS/RMC M) not used
    "gnss_sim_refused",          # simulator fixes (GGA 8, GNS/RMC S) not used
    "gnss_few_sats",             # fixes with fewer satellites than their dimension needs (3-D: 4, 2-D: 3)
    "gnss_fix_type_unknown",     # UBX fix types 6, 7 (reserved) and GGA qualities above 8
    "gnss_geoid_filled",         # empty geoid separations filled from the firmware's own table
    "gnss_legacy_ubx",           # NAV-POSLLH/SOL/VELNED/TIMEUTC/TIMEGPS/STATUS messages read (no NAV-PVT)
    "gnss_leap_changes",         # the receiver's GPS - UTC leap seconds changed
    "gnss_pvt_ignored_flags",    # NAV-PVT with gnssFixOK clear
    "gnss_ubx_other",            # checked UBX frames not used (other classes/ids)
    "gnss_nmea_other",           # checked NMEA sentences not used (GSV, VTG, TXT, proprietary ...)
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
    refused: str | None = None       # counter of a refusal (manual, simulator, few satellites, reserved fix type)
    date: Any = None
    tod: Any = None
    base_ok: bool = True             # the epoch's clock agrees with the time base
    tag_pps: bool = False            # tagged from a PPS edge
    pos_ecef: Any = None             # NAV-SOL position (m), used when no NAV-POSLLH came
    vel_ecef: Any = None             # NAV-SOL velocity (m/s), used when no NAV-VELNED came
    ubx_fix: int | None = None       # NAV-SOL / NAV-STATUS fix type (with gpsFixOK)
    gsa_best: int = 0                # best GSA fix type of the epoch (0: no GSA; 1 no fix, 2 2-D, 3 3-D)
    hdop: float | None = None        # GGA / GNS HDOP of the fix (scales its sigmas, D-5.42)
    gst_h: float | None = None       # GST: the receiver's horizontal error estimate per axis, m (D-5.51)
    num_sats: int | None = None      # satellites used (GGA / GNS / NAV-PVT)
    pdop: float | None = None        # NAV-PVT pDOP (the 4-satellite rule's geometry without an HDOP)


class GnssTask:
    """Parse GNSS messages into one measurement per epoch; the date and time set UTC
    (:class:`~.timekeeping.Clock`).

    A task object of the cyclic executive: its state is its own; collaborators ``cfg``, ``counters`` (the loop's
    table, shared), ``clock`` and ``fault`` (the loop's containment of an exception in one message). The loop
    owns the UART3 decoder and hands it to :meth:`on_bytes`."""

    def __init__(self, cfg: FirmwareConfig, counters: dict[str, int], clock: Clock,
                 fault: Callable[[str, BaseException], None]) -> None:
        self.cfg = cfg
        self.counters = counters
        self.clock = clock
        self._fault = fault
        #: the latest fix: (lat rad, lon rad, h m, GGA quality); None before the first
        self._last_fix: tuple[float, float, float, int] | None = None
        #: the measurement handed to the update (:meth:`pending`), until the loop takes it
        self._gnss_pending: GnssMeasurement | None = None
        self._gnss_init()

    def _reject(self, reason: str) -> None:
        count_rejection(self.counters, reason)

    def _gnss_init(self) -> None:
        """State of the GNSS path (called from ``__init__``)."""
        self._gnss_epoch: _Epoch | None = None
        self._gnss_ready: deque[tuple[GnssMeasurement, _Epoch]] = deque(maxlen=8)
        self._gnss_kinds_last: frozenset[str] = frozenset()
        self._gnss_kinds_cur: set[str] = set()
        self._gnss_closed_utc: float | None = None
        self._gnss_offsets: deque[float] = deque(maxlen=_OFFSET_WINDOW)
        self._gnss_step_cand: list[float] = []
        self._gnss_leap: int | None = None  # the receiver's GPS - UTC (s), once it reported it
        self._gnss_leap_ref: int | None = None  # the first it reported: the epochs' time scale is UTC + this
        self._gnss_day = 0
        self._gnss_last_tod: float | None = None
        self._gnss_chunk = 0
        self._gnss_chunk_start = 0.0
        self._gnss_chunk_t_rx = 0.0
        for k in GNSS_COUNTERS:
            self.counters.setdefault(k, 0)

    # -- bytes in -------------------------------------------------------------------------------------
    def _on_gnss_bytes(self, dec: StreamDecoder, data: bytes, t_rx_s: float | None) -> None:
        """One chunk from UART3 for the decoder ``dec``: ``t_rx_s`` is when its last byte arrived (the ISR's time
        stamp)."""
        t_rx = t_rx_s if t_rx_s is not None else self.clock.now_s()
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
                elif isinstance(s, NavPosllh | NavSol | NavVelned | NavTimeUtc | NavTimeGps | NavStatus):
                    self._on_ubx_legacy(s)
                else:
                    self._on_nmea(s)
            except Exception as e:
                self._fault("gnss message", e)  # the loop's containment
            self._gnss_after_message()
            # the next message of this chunk started after this one: only the first is dated by the chunk
            self._gnss_chunk_start = math.nan

    def _gnss_decoder_stats(self, dec: StreamDecoder) -> dict[str, Any]:
        """UART3 decoder counters plus ``lf_only`` (NMEA lines accepted with an LF-only end)."""
        return {**dec.stats.as_dict(), "lf_only": getattr(dec.formats[0], "lf_only", 0)}

    # -- messages --------------------------------------------------------------------------------------
    def _on_nmea(self, s: Any) -> None:
        """GGA / GNS: position fix; RMC: horizontal velocity, date (status A only; and the position of RMC-only
        streams); GSA: fix type; ZDA: date and time; GST/GBS/GRS/GLL: time (they open an epoch). Other sentences
        are counted and left alone."""
        if isinstance(s, Gga):
            reason = input_guard.check_gga(s) if s.quality != 0 else None
            if reason is not None:
                self._reject(reason)
                return
            e = self._gnss_epoch_for("GGA", *self._nmea_key(s.time_utc))
            if e is None:
                return
            if s.quality == 0 or s.lat_deg is None or s.lon_deg is None:
                e.no_fix = True
                return
            if s.quality == 6:
                e.dr = True
                return
            if s.quality in (7, 8) or s.quality > 8:
                e.refused = {7: "gnss_manual_refused", 8: "gnss_sim_refused"}.get(s.quality, "gnss_fix_type_unknown")
                return
            self._nmea_fix(e, s.lat_deg, s.lon_deg, s.altitude_msl_m, s.geoid_sep_m, s.num_sats, s.quality)
            e.hdop = s.hdop
        elif isinstance(s, Gns):
            reason = input_guard.check_gns(s) if s.lat_deg is not None else None
            if reason is not None:
                self._reject(reason)
                return
            e = self._gnss_epoch_for("GNS", *self._nmea_key(s.time_utc))
            if e is None:
                return
            modes = set(s.mode or "N")
            if not modes & _GNS_FIX or s.lat_deg is None or s.lon_deg is None:
                if "E" in modes:
                    e.dr = True
                elif "S" in modes:
                    e.refused = "gnss_sim_refused"
                elif "M" in modes:
                    e.refused = "gnss_manual_refused"
                else:
                    e.no_fix = True
                return
            best = max((_GNS_QUALITY[c] for c in modes & _GNS_FIX), key=lambda q: (q in (4, 5), q))
            self._nmea_fix(e, s.lat_deg, s.lon_deg, s.altitude_msl_m, s.geoid_sep_m, s.num_sats, best)
            e.hdop = s.hdop
        elif isinstance(s, Rmc):
            reason = input_guard.check_rmc(s)
            if reason is not None:
                self._reject(reason)
                return
            e = self._gnss_epoch_for("RMC", *self._nmea_key(s.time_utc))
            if e is None:
                return
            if s.date is not None and s.valid:  # a void RMC's date is the receiver's RTC (or nothing)
                e.date = s.date
            if s.mode == "E":
                e.dr = True
                return
            if s.mode in ("S", "M"):
                e.refused = "gnss_sim_refused" if s.mode == "S" else "gnss_manual_refused"
                return
            if not s.valid or s.mode == "N":
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
            if e is not None:
                e.gsa_best = max(e.gsa_best, s.fix_type)  # one GSA per system (NMEA 4.10): the best one counts
        elif isinstance(s, Zda):
            e = self._gnss_epoch_for("ZDA", *self._nmea_key(s.time_utc))
            if e is not None and s.date is not None and s.time_utc is not None:
                e.date = s.date
        elif isinstance(s, Gst):
            # time (it opens an epoch, 5.1.3) and the receiver's own error estimate (D-5.51)
            if s.time_utc is None:
                self.counters["gnss_nmea_other"] += 1
                return
            e = self._gnss_epoch_for("TIME", *self._nmea_key(s.time_utc))
            if e is None or s.lat_m is None or s.lon_m is None:
                return
            reason = input_guard.check_gst(s)
            if reason is not None:
                self._reject(reason)
                return
            if s.lat_m > 0.0 and s.lon_m > 0.0:  # zero: no estimate
                e.gst_h = math.sqrt(0.5 * (s.lat_m * s.lat_m + s.lon_m * s.lon_m))
        elif isinstance(s, NmeaSentence) and s.kind in _TIME_ONLY:
            tod = _field_tod(s.fields, _TIME_ONLY[s.kind] - 1)
            if tod is None:
                self.counters["gnss_nmea_other"] += 1
                return
            self._gnss_epoch_for("TIME", tod + self._leap_shift(), tod)
        else:
            self.counters["gnss_nmea_other"] += 1

    def _nmea_fix(self, e: _Epoch, lat_deg: float, lon_deg: float, alt_msl: float | None, sep: float | None,
                  num_sats: int | None, quality: int) -> None:
        """A GGA / GNS fix: 3-D with a height and 4+ satellites, 2-D with 3 (or no height), none with fewer; an
        empty separation is filled from the firmware's geoid table."""
        if num_sats is not None and num_sats < 3:
            e.refused = "gnss_few_sats"
            return
        lat, lon = lat_deg * DEG, lon_deg * DEG
        if alt_msl is None or (num_sats is not None and num_sats < 4):
            if alt_msl is not None:
                self.counters["gnss_few_sats"] += 1
            e.fix2d = True
            e.pos2 = (lat, lon)
        else:
            if sep is None:
                sep = geoid_separation_m(lat, lon)
                self.counters["gnss_geoid_filled"] += 1
            e.pos3 = (lat, lon, alt_msl + sep)
            self._last_fix = (*e.pos3, quality)
        e.quality = quality
        e.num_sats = num_sats

    def _on_nav_pvt(self, p: NavPvt) -> None:
        """UBX NAV-PVT (any protocol version: 84-byte protocol 14 and 92-byte 15+): position, 3-D velocity
        (velD) and UTC (hour:min:sec + nano). The epoch sits on GPS time (iTOW); the UTC and date are used when
        valid, fully resolved (the leap seconds known) and, where the receiver says so, confirmed."""
        self.counters["gnss_pvt"] += 1
        tod: float | None = None
        if p.valid & 0x02:  # validTime
            if not (0 <= p.hour <= 23 and 0 <= p.min <= 59 and 0 <= p.sec <= 60):
                self._reject("date")
                return
            tod = p.hour * 3600.0 + p.min * 60.0 + p.sec + (p.nano * 1e-9 if abs(p.nano) < 1_000_000_000 else 0.0)
        date = None
        if p.valid & 0x03 == 0x03:  # validDate | validTime
            dt = input_guard.nav_pvt_datetime(p)  # a leap second (sec = 60) is legal; month 13 is not
            if dt is None:
                self._reject("date")
                return
            confirmed = not p.flags2 & 0x20 or p.flags2 & 0xC0 == 0xC0  # confirmedAvai: date and time confirmed
            if p.valid & 0x04 and confirmed:  # fullyResolved
                date = dt[0]
        if tod is not None and p.valid & 0x04:
            self._learn_leap(p.iTOW, tod)
        e = self._ubx_epoch("PVT", p.iTOW, bool(p.valid & 0x02))
        if e is None:
            return
        if date is not None:
            e.date = date
            e.tod = tod
        if p.fixType == 1:
            e.dr = True
            return
        if p.fixType > 5:
            e.refused = "gnss_fix_type_unknown"
            return
        if p.fixType not in _UBX_FIX:
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
        # the 4-satellite rule (D-5.51) reads numSV and pDOP; hAcc is not taken as a sigma (D-5.52)
        e.num_sats, e.pdop = p.numSV, p.pDOP * 0.01

    def _on_ubx_legacy(self, m: Any) -> None:
        """The NAV messages of u-blox 5/6/7 (no NAV-PVT): NAV-POSLLH position, NAV-VELNED velocity, NAV-SOL fix
        type, satellites (and ECEF position / velocity when the others are absent), NAV-STATUS fix type,
        NAV-TIMEUTC UTC and date (validUTC), NAV-TIMEGPS the leap seconds (leapSValid). One epoch per iTOW."""
        self.counters["gnss_legacy_ubx"] += 1
        if isinstance(m, NavTimeGps):
            if m.valid & 0x04 and 0 <= m.leapS <= 60:
                self._set_leap(int(m.leapS))
            self._ubx_epoch("TIMEGPS", m.iTOW, bool(m.valid & 0x01))
            return
        if isinstance(m, NavTimeUtc):
            date = tod = None
            if m.valid & 0x04:  # validUTC
                dt = input_guard.nav_pvt_datetime(m)
                if dt is None:
                    self._reject("date")
                    return
                date = dt[0]
                tod = m.hour * 3600.0 + m.min * 60.0 + m.sec + (m.nano * 1e-9 if abs(m.nano) < 1_000_000_000 else 0.0)
                self._learn_leap(m.iTOW, tod)
            e = self._ubx_epoch("TIMEUTC", m.iTOW, bool(m.valid & 0x01))
            if e is not None and date is not None:
                e.date, e.tod = date, tod
            return
        if isinstance(m, NavStatus):
            e = self._ubx_epoch("STATUS", m.iTOW, bool(m.flags & 0x08))
            if e is not None:
                self._ubx_fix_type(e, m.gpsFix, m.flags)
            return
        if isinstance(m, NavSol):
            e = self._ubx_epoch("SOL", m.iTOW, bool(m.flags & 0x08))
            if e is None:
                return
            self._ubx_fix_type(e, m.gpsFix, m.flags)
            if m.flags & 0x02:
                e.quality = 2  # diffSoln
            if (m.gpsFix == 3 and m.numSV < 4) or (m.gpsFix == 2 and m.numSV < 3):
                e.refused = "gnss_few_sats"
            e.pos_ecef = np.array([m.ecefX, m.ecefY, m.ecefZ], dtype=float) * 0.01
            e.vel_ecef = np.array([m.ecefVX, m.ecefVY, m.ecefVZ], dtype=float) * 0.01
            return
        if isinstance(m, NavPosllh):
            e = self._ubx_epoch("POSLLH", m.iTOW)
            if e is None:
                return
            lat, lon, h = m.lat * 1e-7, m.lon * 1e-7, m.height * 1e-3
            if not (-90.0 <= lat <= 90.0 and -180.0 <= lon <= 180.0 and input_guard.ALT_MIN_M <= h
                    <= input_guard.ALT_MAX_M):
                self._reject("position")
                return
            e.pos3 = (lat * DEG, lon * DEG, h)
            return
        e = self._ubx_epoch("VELNED", m.iTOW)  # NavVelned
        if e is None:
            return
        vel = np.array([m.velE, m.velN, -m.velD], dtype=float) * 0.01
        if float(np.linalg.norm(vel)) > input_guard.SPEED_MAX_MPS:
            self._reject("speed")
            return
        e.vel = vel
        e.vel_up = True

    @staticmethod
    def _ubx_fix_type(e: _Epoch, fix: int, flags: int) -> None:
        """NAV-SOL / NAV-STATUS gpsFix with gpsFixOK (flags b0)."""
        if fix == 1:
            e.dr = True
        elif fix > 5:
            e.refused = "gnss_fix_type_unknown"
        elif fix not in _UBX_FIX or not flags & 0x01:
            e.no_fix = True
        else:
            e.ubx_fix = fix
            if fix == 2:
                e.fix2d = True

    def _set_leap(self, leap: int) -> None:
        """The receiver's GPS - UTC (s). The first report shifts the offset window from the assumed value; a later
        change is a leap second (GPS time, the epochs' scale, does not step)."""
        if self._gnss_leap is None:
            self._gnss_leap_ref = leap
            if leap and self._gnss_offsets:
                # the offsets so far are against UTC; from now on against GPS time (UTC + leap)
                shifted = [x - leap for x in self._gnss_offsets]
                self._gnss_offsets.clear()
                self._gnss_offsets.extend(shifted)
                self._gnss_step_cand = [x - leap for x in self._gnss_step_cand]
        elif leap != self._gnss_leap:
            self.counters["gnss_leap_changes"] += 1
        self._gnss_leap = leap

    def _learn_leap(self, itow_ms: int, utc_tod: float) -> None:
        """GPS - UTC from one message with both GPS time of week and a resolved UTC time of day."""
        d = (itow_ms * 1e-3 - utc_tod) % 86400.0
        leap = round(d)
        if abs(d - leap) < 0.01 and 0 <= leap <= 60:
            self._set_leap(leap)

    def _ubx_epoch(self, kind: str, itow_ms: int, tow_valid: bool = True) -> _Epoch | None:
        """The epoch of a UBX message at GPS time of week ``itow_ms``: placed on the UTC time of day with the
        receiver's leap seconds, on the GPS time scale (:meth:`_gnss_epoch_for`). ``tow_valid`` False (the
        message's own flag: NAV-PVT validTime, NAV-SOL / NAV-STATUS towSet, NAV-TIMEGPS towValid, NAV-TIMEUTC
        validTOW): the message belongs to the open epoch, or opens one without a time."""
        if not tow_valid:
            return self._gnss_epoch_for(kind, None)
        ref = self._gnss_leap_ref if self._gnss_leap_ref is not None else _LEAP_DEFAULT_S
        leap = self._gnss_leap if self._gnss_leap is not None else _LEAP_DEFAULT_S
        if not 0 <= itow_ms < 604_800_000:
            self._reject("date")
            return None
        return self._gnss_epoch_for(kind, (itow_ms * 1e-3 - ref) % 86400.0, (itow_ms * 1e-3 - leap) % 86400.0)

    def _leap_shift(self) -> int:
        """Seconds from the receiver's UTC to the epochs' scale (UTC at the first leap seconds it reported): 0 until a
        leap second changed them, then the change (a UTC that repeated a second is placed one second on)."""
        if self._gnss_leap is None or self._gnss_leap_ref is None:
            return 0
        return self._gnss_leap - self._gnss_leap_ref

    def _nmea_key(self, t: Any) -> tuple[float | None, float | None]:
        """(epoch key, UTC time of day) of an NMEA time field: the key on the epochs' scale (:meth:`_leap_shift`)."""
        tod = _tod(t)
        return (None, None) if tod is None else (tod + self._leap_shift(), tod)

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

    def _gnss_epoch_for(self, kind: str, tod: float | None, utc_tod: float | None = None) -> _Epoch | None:
        """The open epoch a message of ``kind`` with time of day ``tod`` (s, None: no time; on the epochs' scale,
        ``utc_tod`` the receiver's UTC time of day when it differs) belongs to; a message of a new time closes the
        open epoch first. None: the message belongs to an epoch already closed."""
        if utc_tod is None:
            utc_tod = tod
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
                # not the first message of its chunk: its first byte arrived no later than the chunk's end (a
                # bound from above, as every sample of the minimum must be)
                t_first = self._gnss_chunk_t_rx if self._gnss_chunk else self.clock.now_s()
            e = self._gnss_epoch = _Epoch(utc_s=utc, t_first=t_first, t_rx=self._gnss_chunk_t_rx)
            e.tod = utc_tod
            if utc is not None:
                e.base_ok = self._gnss_offset_sample(t_first - utc - self._gnss_scale_leap())
        elif e.utc_s is None and utc is not None:
            e.utc_s = utc
            e.tod = utc_tod
            e.base_ok = self._gnss_offset_sample(e.t_first - utc - self._gnss_scale_leap())
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

    def _gnss_scale_leap(self) -> int:
        """Seconds added to UTC for the offset's time scale: the receiver's GPS - UTC once it reported it (GPS
        time does not step at a leap second), else 0 (UTC)."""
        return self._gnss_leap_ref or 0

    def _gnss_offset_sample(self, x: float) -> bool:
        """One epoch's first-byte-minus-time sample ``x`` (s). True: the epoch's clock agrees with the time base
        (the sample joins the minimum); False: a step of the receiver's clock not yet confirmed (the epoch is
        refused). ``cfg.gnss_clock_rebase_epochs`` consecutive samples agreeing among themselves and away from
        the base re-base it (module docstring)."""
        offs = self._gnss_offsets
        tol = self.cfg.gnss_clock_step_tol_s
        if offs and abs(x - min(offs)) > tol:
            cand = self._gnss_step_cand
            if cand and abs(x - min(cand)) > tol:
                cand.clear()  # disagrees with the candidates too: a new candidate run
            cand.append(x)
            if len(cand) < self.cfg.gnss_clock_rebase_epochs:
                return False
            offs.clear()
            offs.extend(cand)
            cand.clear()
            self.counters["gnss_clock_steps"] += 1
            self.counters["gnss_utc_offset_resets"] += 1
            return True
        self._gnss_step_cand.clear()
        offs.append(x)
        return True

    def _gnss_time_of_validity(self, e: _Epoch) -> float:
        """FPGA time (s) at which the epoch's fix is valid (module docstring)."""
        t_ref = e.t_first
        t_pps = self.clock.t_pps_s
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
            e.tag_pps = True
            return t
        self.counters["gnss_tag_utc"] += 1
        lp = self._gnss_scale_leap()
        off = min(self._gnss_offsets) if self._gnss_offsets else t_ref - e.utc_s - lp
        return e.utc_s + lp + off - self.cfg.gnss_latency_s

    def _gnss_close(self, e: _Epoch) -> None:
        """The epoch is complete: one measurement (or a counted reason for none)."""
        self._gnss_epoch = None
        self._gnss_closed_utc = e.utc_s
        self.counters["gnss_epochs"] += 1
        if e.chunks > 1:
            self.counters["gnss_epochs_split"] += 1
        if not e.base_ok:
            self.counters["gnss_clock_step_refused"] += 1
            return
        t_meas = self._gnss_time_of_validity(e)
        if t_meas > max(e.t_rx, e.t_first) + 1e-3:
            # valid after its own bytes arrived: a tag in the future (a clock the time base does not follow)
            self.counters["gnss_tag_future"] += 1
            return
        if self.clock.now_s() - t_meas > self.cfg.gnss_max_age_s:
            self.counters["gnss_tag_stale"] += 1
            return
        simulated = e.refused in _NOT_REAL  # a simulator's or a manual fix: neither its place nor its time
        if e.date is not None and not simulated:
            self.clock.take_date(e.date)
        date = self.clock.date
        if date is not None and e.tod is not None and not simulated and (
                e.date is not None or e.pos3 is not None or e.pos2 is not None):
            h, rem = divmod(e.tod % 86400.0, 3600.0)
            mi, sec = divmod(rem, 60.0)
            whole = min(int(sec), 59)
            self.clock.set_utc(t_meas, date, _dt.time(int(h), int(mi), whole, min(999_999, round((sec - whole) * 1e6))),
                          pps=e.tag_pps)
        if e.dr:
            self.counters["gnss_dr_refused"] += 1
            return
        if e.refused is not None:
            self.counters[e.refused] += 1
            return
        if e.pos3 is None and e.pos_ecef is not None and e.ubx_fix is not None:
            # NAV-SOL without NAV-POSLLH: the ECEF solution
            e.pos3 = ecef_to_geodetic(*(float(v) for v in e.pos_ecef))
        if e.vel is None and e.vel_ecef is not None and e.ubx_fix is not None and e.pos3 is not None:
            e.vel = _ecef_to_enu(e.vel_ecef, e.pos3[0], e.pos3[1])
            e.vel_up = True
        if e.gsa_best == 1:
            e.no_fix = True
        elif e.gsa_best == 2:
            e.fix2d = True
        if e.ubx_fix is None and e.kinds & _LEGACY_KINDS and not e.kinds & _FIX_KINDS:
            # NAV-POSLLH / VELNED carry no fix type: without NAV-SOL or NAV-STATUS saying "fix" they are not used
            e.no_fix = True
        if e.no_fix:  # any message of the epoch saying "no fix" (GGA 0, RMC V/N, GSA 1, GNS N, UBX fix type 0/5)
            self.counters["gnss_no_fix_epochs"] += 1
            return
        if e.pos3 is not None and e.ubx_fix == 3:
            self._last_fix = (*e.pos3, e.quality)
        m = GnssMeasurement(t_fpga_s=t_meas)
        if e.pos3 is not None and not e.fix2d:
            m.pos = e.pos3
        elif e.pos3 is not None or e.pos2 is not None:
            lat, lon = e.pos3[:2] if e.pos3 is not None else e.pos2  # type: ignore[misc]
            m.pos = (lat, lon, 0.0)
            m.pos_up = False
            self.counters["gnss_2d_fixes"] += 1
        m.vel, m.vel_up, m.quality, m.hdop, m.reported_sigma_h_m = e.vel, e.vel_up, e.quality, e.hdop, e.gst_h
        m.num_sats, m.pdop = e.num_sats, e.pdop
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

    # -- the task's interface to the loop ---------------------------------------------------------------
    def on_bytes(self, dec: StreamDecoder, data: bytes, t_rx_s: float | None) -> None:
        """Bytes from UART3 (the loop's decoder ``dec``; ``t_rx_s``: the ISR's time of the last byte, s)."""
        self._on_gnss_bytes(dec, data, t_rx_s)

    def decoder_stats(self, dec: StreamDecoder) -> dict[str, Any]:
        """The UART3 decoder's counters plus ``lf_only``."""
        return self._gnss_decoder_stats(dec)

    def hold(self, t: float) -> None:
        """Every tick (also while aligning; ``t``: tick time, s): close an epoch held too long."""
        if self._gnss_epoch is not None:
            self._gnss_hold(t)

    def pending(self, t: float) -> GnssMeasurement | None:
        """The measurement due for the update at tick time ``t`` (s), kept until :meth:`take`."""
        self._gnss_poll(t)
        return self._gnss_pending

    def take(self) -> None:
        """The loop took (or dropped) the pending measurement."""
        self._gnss_pending = None

    @property
    def last_fix(self) -> tuple[float, float, float, int] | None:
        """The latest fix: (lat rad, lon rad, h m, GGA quality); None before the first."""
        return self._last_fix


def _ecef_to_enu(v: Any, lat: float, lon: float) -> Any:
    """An ECEF vector rotated into the local East, North, Up frame at (lat, lon) rad."""
    sl, cl, so, co = math.sin(lat), math.cos(lat), math.sin(lon), math.cos(lon)
    x, y, z = (float(c) for c in v)
    return np.array([-so * x + co * y, -sl * co * x - sl * so * y + cl * z, cl * co * x + cl * so * y + sl * z])


def _field_tod(fields: tuple[str, ...], i: int) -> float | None:
    """Seconds of the day of an ``hhmmss.ss`` field of an untyped sentence (None: empty or not a time)."""
    if i >= len(fields):
        return None
    f = fields[i]
    if len(f) < 6 or not f[:6].isdigit():
        return None
    try:
        sec = float(f[4:])
    except ValueError:
        return None
    h, m = int(f[0:2]), int(f[2:4])
    if h > 23 or m > 59 or not 0.0 <= sec < 61.0:
        return None
    return h * 3600.0 + m * 60.0 + sec


def _tod(t: Any) -> float | None:
    """Seconds of the day of a ``datetime.time`` (None: no time)."""
    if t is None:
        return None
    return float(t.hour * 3600.0 + t.minute * 60.0 + t.second + t.microsecond * 1e-6)
