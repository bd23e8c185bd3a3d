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
from ..kf import D_H, D_LAT, D_LON, DV_E, DV_N, DV_U, N_NAV_ERRORS, PHI_E, PHI_N, PHI_U
from ..nav_state import POS, Q, V
from ..units import DEG
from .state import FirmwareState, LoopState

__all__ = ["NavOutput", "utc_from_grena_days"]

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


class NavOutput(LoopState):
    """NAV_SOLUTION frames (attitude from the quaternion, sigmas from the filter's P)."""
    def cpu_load_pct(self) -> float:
        """Worst tick of the last second, % of the tick budget (NAV_SOLUTION / STATUS ``cpu_load``)."""
        worst = self._load_window[0][1] if self._load_window else 0
        return 100.0 * worst / self.meter.tick_budget

    def _psns_status_now(self, t: float) -> int:
        return 1 if t - self._last_psns_t < 2.0 else 2 if t - self._last_psns_reject_t < 2.0 else 0

    def _gnss_status_byte(self) -> int:
        """``gnss_status``: the last fix's GGA quality (bits 0-6), bit 7 when the innovation gate refused rows of
        the last GNSS fix (docs/hostile-input.md)."""
        quality = self.gnss.last_fix[3] & 0x7F if self.gnss.last_fix is not None else 0
        return quality | (0x80 if self._gnss_gated else 0)

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
        s = self.nav
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
            aided = t - self._last_gnss_update_t < 2.0
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
                    d = [_sqrt(0.0 if v < 0.0 else v) for v in self.filter.P.diagonal()[:3].tolist()]
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
        return nav_text_sentences(nav, self.filter.variant_id & 0xF)

    def _nav_output(self, t: float) -> bytes:
        s = self.nav
        mode = int(self.mode) | (self.filter.variant_id & 0xF) << 8
        if s is None:
            lat = lon = h = 0.0
            if self.gnss.last_fix is not None:
                lat, lon, h = self.gnss.last_fix[0], self.gnss.last_fix[1], self.gnss.last_fix[2]
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
            lat, lon, h = x[POS]
            ve, vn, vu = x[V]
            vel = (ve, vn, vu)
            roll, pitch, heading = self._euler_deg(x)
            # sqrt(max(v, 0)) of the navigation errors' variances (kf layout)
            d = [_sqrt(0.0 if v < 0.0 else v) for v in self.filter.P.diagonal()[:N_NAV_ERRORS].tolist()]
            rm, rn = earth.radii(lat)
            sigma = (
                d[PHI_E] / DEG, d[PHI_N] / DEG, d[PHI_U] / DEG, d[DV_E], d[DV_N], d[DV_U],
                d[D_LAT] * (rm + h), d[D_LON] * (rn + h) * math.cos(lat), d[D_H],
            )
        vs = self.filter.variant_status()
        if vs is not None:  # VARIANT block: pack 4 bytes + CRC over 6 more [E]
            self.meter.charge("nav_variant_block", 6 * 4 + 4 * 2)
        seq = self._out_seq
        self._out_seq = seq + 1
        # the NavSolution fields in order (protocols.host.nav_solution_frame), without building the object
        return nav_solution_frame(
            seq, t, lat / DEG, lon / DEG, h, vel, roll, pitch, heading, sigma, int(mode),
            self._gnss_status_byte(), self._psns_status_now(t), self.cpu_load_pct(), self.deadline_misses,
            *(vs if vs is not None else (None, 0, 0)))


def utc_from_grena_days(days: float) -> _dt.datetime:
    """UTC (naive datetime) from Grena's day count (days of UT since 2060-01-01 00:00; firmware_model.sun)."""
    return _GRENA_EPOCH + _dt.timedelta(days=days)
