"""Navigation output: NAV_SOLUTION at ``output_rate_hz`` (protocols/host.py), the CPU load it reports, and the
NMEA 0183 sentences of the same solution (GGA, RMC, VTG, ZDA, HDT, THS, PASHR; docs/icd.md, "NMEA navigation
output"), as real INS firmware writes them next to its binary protocol."""

from __future__ import annotations

import datetime as _dt
import math
from collections.abc import Sequence

from protocols.host import HostFormat, NavMode, NavSolution, nav_solution_frame
from protocols.host_text import nav_text_sentences
from protocols.nmea_build import build_gga, build_rmc, build_vtg, build_zda
from protocols.nmea_nav import build_hdt, build_pashr, build_ths

from .. import c674x, earth
from ..attitude import heading_from_yaw
from ..config import UART_HOST, FirmwareConfig
from ..kf import D_H, D_LAT, D_LON, DV_E, DV_N, DV_U, N_NAV_ERRORS, PHI_E, PHI_N, PHI_U
from ..nav_state import POS, Q, V
from ..units import DEG
from .gnss import GnssTask
from .navigation import NavCore
from .state import CpuLoad, FirmwareState, LoopStatus, TickResult
from .timekeeping import Clock

__all__ = ["OutputTask", "utc_from_grena_days"]

#: Grena's day count starts at 2060-01-01 00:00 UT (firmware_model.sun.grena_days)
_GRENA_EPOCH = _dt.datetime(2060, 1, 1)
_POSITION_SENTENCES = ("GGA", "RMC", "VTG", "ZDA")
#: characters and DP-scaled values per sentence, for the cycle charge (c674x.nmea_sentence) [D]
_NMEA_SIZE = {"GGA": (72, 4), "RMC": (70, 4), "VTG": (40, 2), "ZDA": (36, 1), "HDT": (18, 1), "THS": (18, 1),
              "PASHR": (70, 7)}

#: characters and DP-scaled values of the four $PSNS text sentences (POS, VEL, ATT, STA), for the cycle charge [D]
_TEXT_SIZE = ((58, 3), (38, 3), (36, 3), (30, 1))
_HOST_FORMAT = HostFormat()

_GNSS_AIDED, _PSNS_AIDED, _DEGRADED = int(NavMode.GNSS_AIDED), int(NavMode.PSNS_AIDED), int(NavMode.DEGRADED)
_sqrt = math.sqrt


class OutputTask:
    """NAV_SOLUTION frames (attitude from the quaternion, sigmas from the filter's P), their ``$PSNS`` text and the
    NMEA sentences, each at its rate.

    A task object of the cyclic executive: its state (the rates as IMU ticks, the frame sequence) is its own;
    collaborators ``cfg``, ``meter``, ``core`` (the navigation state and the filter), ``gnss`` (the last fix),
    ``clock`` (UTC), ``status`` (mode and aiding times) and ``load`` (the CPU load and deadline misses reported)."""

    def __init__(self, cfg: FirmwareConfig, meter: c674x.CycleMeter, core: NavCore, gnss: GnssTask, clock: Clock,
                 status: LoopStatus, load: CpuLoad, nav_output_cycles: int) -> None:
        self.cfg = cfg
        self.meter = meter
        self.core = core
        self.gnss = gnss
        self.clock = clock
        self.status = status
        self.load = load
        self._cyc_nav_output = nav_output_cycles
        self._T = 1.0 / cfg.imu_rate_hz
        self._out_every = round(cfg.imu_rate_hz / cfg.output_rate_hz)  # IMU ticks per NAV_SOLUTION (0: off)
        pos = any(n in _POSITION_SENTENCES for n in cfg.nmea_sentences)
        att = any(n in ("HDT", "THS", "PASHR") for n in cfg.nmea_sentences)
        #: IMU ticks per NMEA position/velocity/time group and per heading/attitude group (0: off)
        self._nmea_every = round(cfg.imu_rate_hz / cfg.nmea_rate_hz) if pos else 0
        self._nmea_att_every = round(cfg.imu_rate_hz / cfg.nmea_attitude_rate_hz) if att else 0
        self._text_every = round(cfg.imu_rate_hz / cfg.text_rate_hz) if cfg.text_rate_hz else 0
        self._out_seq = 0

    # -- the task's interface to the loop ---------------------------------------------------------------
    def run(self, t: float, tick: int, res: TickResult) -> None:
        """The outputs due at the ``tick``-th IMU tick (time ``t``, s), each metered as its task, into ``res``."""
        m = self.meter
        cfg = self.cfg
        if self._out_every and tick % self._out_every == 0:
            m.begin("output", self._out_every * self._T)
            frame = self.nav_solution(t)
            m.charge("nav_output", self._cyc_nav_output)
            m.end()
            res.outputs.append((UART_HOST, frame, m.elapsed))
            if self._text_every and tick % self._text_every == 0:  # $PSNS text of the same solution
                m.begin("text_output", self._text_every * self._T)
                text = self._text_output(frame)
                m.end()
                res.outputs.append((cfg.nmea_uart, text, m.elapsed))
        if self._nmea_every or self._nmea_att_every:
            nmea_pos = bool(self._nmea_every) and tick % self._nmea_every == 0
            nmea_att = bool(self._nmea_att_every) and tick % self._nmea_att_every == 0
            if nmea_pos or nmea_att:
                m.begin("nmea_output", min(e for e in (self._nmea_every, self._nmea_att_every) if e) * self._T)
                text = self._nmea_output(t, nmea_pos, nmea_att)
                m.end()
                if text:
                    res.outputs.append((cfg.nmea_uart, text, m.elapsed))

    def set_every(self, ticks: int) -> None:
        """NAV_SOLUTION every ``ticks`` IMU ticks (0: off; SET_OUTPUT_RATE)."""
        self._out_every = ticks

    def rate_hz(self) -> float:
        """The NAV_SOLUTION rate (Hz; 0: off)."""
        return self.cfg.imu_rate_hz / self._out_every if self._out_every else 0.0

    def gnss_status_byte(self) -> int:
        """``gnss_status`` of NAV_SOLUTION / STATUS (:meth:`.state.LoopStatus.gnss_status_byte`)."""
        return self.status.gnss_status_byte(self.gnss.last_fix)

    def _euler_deg(self, x: Sequence[float]) -> tuple[float, float, float]:
        """``(roll, pitch, heading)`` in degrees from the quaternion of the state floats ``x`` (PSINS m2att from
        C32, C31, C33, C12, C22 of C_b^n; heading clockwise from true north)."""
        q0, q1, q2, q3 = x[Q]
        c32 = 2.0 * (q2 * q3 + q0 * q1)
        pitch = math.asin(max(-1.0, min(1.0, c32))) / DEG
        roll = math.atan2(-2.0 * (q1 * q3 - q0 * q2), q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3) / DEG
        yaw = math.atan2(-2.0 * (q1 * q2 - q0 * q3), q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3)
        return roll, pitch, heading_from_yaw(yaw) / DEG

    def _nmea_output(self, t: float, position: bool, attitude: bool) -> bytes:
        """The NMEA sentences due at tick time ``t`` (s, FPGA time base): the heading/attitude group and/or the
        position/velocity/time group of ``cfg.nmea_sentences``, in that order (each group in the configured order),
        charged to ``nmea_output``.

        Nothing before GNSS gave UTC (every sentence carries the time, GGA and RMC only it); GGA quality 0 and RMC
        ``V`` while there is no solution. GGA quality 1 (GPS) while GNSS-aided, 6 (dead reckoning) otherwise, RMC/VTG
        mode ``A`` / ``E`` and THS ``A`` / ``E`` likewise. The firmware has no geoid model: GGA carries the ellipsoidal
        height as altitude with a geoid separation of 0, so a reader's MSL + separation is the WGS-84 height.
        """
        days = self.clock.utc_days(t)
        if days is None:
            return b""
        cfg = self.cfg
        # to the 10 ms the sentences carry (hhmmss.ss), so that no field rounds up to second 60
        utc = utc_from_grena_days(days)
        utc += _dt.timedelta(microseconds=round(utc.microsecond, -4) - utc.microsecond)
        tm, date = utc.time(), utc.date()
        talker = cfg.nmea_talker
        s = self.core.nav
        out: list[bytes] = []
        # heading and attitude first, the position group last: readers such as gpsd end their reporting cycle at
        # the last timed sentence of a burst, and a heading sentence after GGA/RMC split gpsd's cycle (no TPV)
        names = ([n for n in cfg.nmea_sentences if n not in _POSITION_SENTENCES] if attitude else []) + \
                ([n for n in cfg.nmea_sentences if n in _POSITION_SENTENCES] if position else [])
        if s is None:
            for n in names:
                if n == "GGA":
                    out.append(build_gga(tm, 0.0, 0.0, 0.0, 0.0, quality=0, talker=talker))
                elif n == "RMC":
                    out.append(build_rmc(tm, date, 0.0, 0.0, 0.0, 0.0, valid=False, talker=talker))
                elif n == "ZDA":
                    out.append(build_zda(tm, date, talker=talker))
                elif n == "THS":
                    out.append(build_ths(None, "V", talker=talker))
        else:
            x = s.as_floats()
            lat, lon, h = x[POS]
            ve, vn, _vu = x[V]
            aided = t - self.status.last_gnss_update_t < 2.0
            speed = math.hypot(ve, vn)
            course = math.atan2(ve, vn) / DEG % 360.0
            roll = pitch = heading = 0.0
            if attitude:
                roll, pitch, heading = self._euler_deg(x)
            for n in names:
                if n == "GGA":
                    fix = self.gnss.last_fix
                    out.append(build_gga(tm, lat / DEG, lon / DEG, h, 0.0, quality=1 if aided else 6,
                                         num_sats=12 if fix is not None else 0, hdop=1.0, talker=talker))
                elif n == "RMC":
                    out.append(build_rmc(tm, date, lat / DEG, lon / DEG, speed, course, mode="A" if aided else "E",
                                         talker=talker))
                elif n == "VTG":
                    out.append(build_vtg(course, speed, mode="A" if aided else "E", talker=talker))
                elif n == "ZDA":
                    out.append(build_zda(tm, date, talker=talker))
                elif n == "HDT":
                    out.append(build_hdt(heading, talker=talker))
                elif n == "THS":
                    out.append(build_ths(heading, "A" if aided else "E", talker=talker))
                elif n == "PASHR":
                    d = [_sqrt(0.0 if v < 0.0 else v) for v in self.core.filter.P.diagonal()[:3].tolist()]
                    # roll/pitch sigma: the level misalignments (about N and E), heading: about U
                    out.append(build_pashr(tm, heading, roll, pitch, 0.0, d[PHI_N] / DEG, d[PHI_E] / DEG,
                                           d[PHI_U] / DEG, aiding=1 if aided else 0))
            m = self.meter
            m.charge("nmea_att", (c674x.mathlib("asinsp") + 2 * c674x.mathlib("atan2sp")) if attitude else 0)
            m.charge("nmea_vel", c674x.mathlib("sqrtsp") + c674x.mathlib("atan2sp"))
        for n in names:
            self.meter.charge("nmea_format", c674x.nmea_sentence(*_NMEA_SIZE[n]))
        return b"".join(out)

    def _text_output(self, frame: bytes) -> bytes:
        """The ``$PSNS`` text sentences (docs/icd.md 7: POS, VEL, ATT, STA) of the NAV_SOLUTION ``frame`` this tick
        sent, charged to ``text_output`` as four formatted sentences."""
        nav = _HOST_FORMAT.parse(frame)
        if not isinstance(nav, NavSolution):
            return b""
        for n_chars, n_scaled in _TEXT_SIZE:
            self.meter.charge("text_format", c674x.nmea_sentence(n_chars, n_scaled))
        return nav_text_sentences(nav, self.core.filter.variant_id & 0xF)

    def nav_solution(self, t: float) -> bytes:
        """The NAV_SOLUTION frame at tick time ``t`` (s), the next sequence number."""
        s = self.core.nav
        mode = int(self.status.mode) | (self.core.filter.variant_id & 0xF) << 8
        if s is None:
            lat = lon = h = 0.0
            if self.gnss.last_fix is not None:
                lat, lon, h = self.gnss.last_fix[0], self.gnss.last_fix[1], self.gnss.last_fix[2]
            vel = (0.0, 0.0, 0.0)
            roll = pitch = heading = 0.0
            sigma = (0.0,) * 9
        else:
            st = self.status
            if t - st.last_gnss_update_t < 2.0:
                mode |= _GNSS_AIDED
            elif st.state != FirmwareState.COARSE_ALIGN and t - st.t_aligned > 3.0:
                mode |= _DEGRADED  # GNSS missing or stale
            if t - st.last_psns_t < 2.0:
                mode |= _PSNS_AIDED
            if t - st.last_psns_reject_t < 2.0:
                mode |= _DEGRADED
            x = s.as_floats()
            lat, lon, h = x[POS]
            ve, vn, vu = x[V]
            vel = (ve, vn, vu)
            roll, pitch, heading = self._euler_deg(x)
            # sqrt(max(v, 0)) of the navigation errors' variances (kf layout)
            d = [_sqrt(0.0 if v < 0.0 else v) for v in self.core.filter.P.diagonal()[:N_NAV_ERRORS].tolist()]
            rm, rn = earth.radii(lat)
            sigma = (
                d[PHI_E] / DEG, d[PHI_N] / DEG, d[PHI_U] / DEG, d[DV_E], d[DV_N], d[DV_U],
                d[D_LAT] * (rm + h), d[D_LON] * (rn + h) * math.cos(lat), d[D_H],
            )
        vs = self.core.filter.variant_status()
        if vs is not None:  # VARIANT block: pack 4 bytes + CRC over 6 more [E]
            self.meter.charge("nav_variant_block", 6 * 4 + 4 * 2)
        seq = self._out_seq
        self._out_seq = seq + 1
        # the NavSolution fields in order (protocols.host.nav_solution_frame), without building the object
        return nav_solution_frame(
            seq, t, lat / DEG, lon / DEG, h, vel, roll, pitch, heading, sigma, int(mode),
            self.gnss_status_byte(), self.status.psns_status(t), self.load.load_pct(), self.load.deadline_misses,
            *(vs if vs is not None else (None, 0, 0)))


def utc_from_grena_days(days: float) -> _dt.datetime:
    """UTC (naive datetime) from Grena's day count (days of UT since 2060-01-01 00:00; firmware_model.sun)."""
    return _GRENA_EPOCH + _dt.timedelta(days=days)
