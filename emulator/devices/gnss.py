"""GNSS receiver: fixes as NMEA GGA + RMC on an RS422 link, the PPS line, outages and glitches.

Epochs come at ``rate_hz`` on a grid aligned to whole UTC seconds; PPS rises at every whole UTC second only
(a timepulse is 1 Hz at any navigation rate; latched by the FPGA; its edge carries a Gaussian jitter, the
paper's "second pulse accuracy 50 ns" read as 95 %); ``latency_s`` after each epoch the receiver writes the
sentences of that epoch. NAV-STATUS ``msss`` counts from power-on (scenario t = 0), ``ttff`` is the time of
the first epoch with a fix; without a fix the accuracies are reported unknown (:data:`NO_FIX_ACC_M`). At
9600 baud a GGA + RMC pair takes ~0.15 s on the wire.

Errors (:class:`GnssErrorModel`; base paper figures, docs/architecture.md, read as 95 % bounds,
docs/decisions/world-and-sensors.md D1): horizontal position < 10 m (95 % radial: 4.08 m per axis), vertical
< 15 m (95 %: 7.5 m), each axis the sum of a first-order Gauss-Markov process
(``pos_corr_time_s``) and a white part (``pos_white_fraction`` of the sigma), with the total
variance equal to the configured sigma squared; horizontal velocity 0.1 m/s (95 % radial:
0.041 m/s per axis), vertical 0.2 m/s (0.1 m/s), white.

Fix types: GGA quality (1 GPS, 2 DGPS, 4 RTK fixed, 5 RTK float) with the matching RMC mode
letter. Outages (``outages``: start and duration): no fix (GGA quality 0, RMC status V) and no
PPS; after the outage the receiver re-acquires in ``reacquisition_s`` (the paper's "loss of lock
recapture time < 1 s"), and the Gauss-Markov error restarts from a fresh draw. Glitches
(``glitches``): a position jump (ENU metres) added during a time window, as a multipath or
false-lock event would.

Multipath (``multipath_sigma_*``, ``multipath_corr_time_s``; the ``field`` preset): a second, faster
first-order Gauss-Markov process per axis added to the position; both correlated processes restart from a
fresh draw at re-acquisition, so the solution jumps when the fixes return. ``latency_s`` is the receiver's
output latency (epoch to first byte).

Height in GGA is above MSL: ``h_msl = h - N``, the receiver's geoid separation ``N`` EGM96 at the reported position
(:mod:`emulator.devices.geoid`, proj-data's 15' grid) unless the scenario fixes ``geoid_sep_m``;
``geoid_sep_field = "empty"`` leaves GGA's separation field empty (MSL height only), as several receiver families do.

Message sets: NMEA sentences, then UBX: NAV-PVT (u-blox 7 and later) or the set of the generations before it
(NAV-SOL, NAV-POSLLH, NAV-VELNED, NAV-TIMEUTC, NAV-TIMEGPS, NAV-STATUS: u-blox 5/6, or an M8/F9 configured so).
"""

from __future__ import annotations

import datetime as _dt
import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import pymap3d

from protocols import ubx_cfg as cfgmsg
from protocols.constants import A_WGS84, DEG, F_WGS84
from protocols.gnss import NMEA_SENTENCES, UBX_MESSAGES, GnssFix, GnssOutputSet, build_epoch
from protocols.nmea import NMEA_RX_MAX_LEN, NmeaFormat
from protocols.stream import StreamDecoder
from protocols.ubx import UbxFormat, UbxFrame

from ..links.base import Link
from ..world.trajectory import Trajectory
from .geoid import egm96_separation_m

__all__ = ["NO_FIX_ACC_M", "RADIAL_95", "GnssConfig", "GnssErrorModel", "GnssErrors", "GnssGlitch", "GnssOutage",
           "GnssReceiver", "constellation"]

#: PRNs reported in GSA / numSV (a fixed, plausible constellation; the count follows ``num_sats``).
_SAT_IDS = (2, 5, 6, 12, 13, 15, 17, 19, 24, 25, 29, 30, 1, 3, 7, 9, 10, 14, 18, 20, 21, 22, 23, 26)
#: satellite numbers per system talker, in NMEA 4.10 numbering (protocols.nmea_build.SV_NUMBERS): GPS as above,
#: GLONASS 65-96, Galileo 1-36, BeiDou 1-63
_SYSTEM_SATS = {"GP": _SAT_IDS, "GL": (65, 66, 71, 72, 73, 79, 80, 81, 86, 87, 88, 70),
                "GA": (2, 3, 5, 7, 8, 11, 12, 19, 24, 25, 26, 30), "GB": (6, 9, 11, 12, 14, 16, 19, 20, 22, 23, 29, 32)}
_SYSTEM_SATS["BD"] = _SYSTEM_SATS["GB"]


def constellation(talker: str, n: int) -> tuple[tuple[str, int, int, int, int | None], ...]:
    """``n`` satellites in view for ``talker`` as (system talker, NMEA 4.10 number, elevation deg, azimuth deg,
    C/N0 dBHz): a fixed sky (not propagated from orbits), spread over elevation 15-85 deg and the whole azimuth;
    ``GN`` alternates GPS and GLONASS."""
    systems = ("GP", "GL") if talker == "GN" else (talker if talker in _SYSTEM_SATS else "GP",)
    out = []
    used = dict.fromkeys(systems, 0)
    for i in range(max(0, n)):
        sys_tk = systems[i % len(systems)]
        ids = _SYSTEM_SATS[sys_tk]
        k = used[sys_tk]
        if k >= len(ids):
            break
        used[sys_tk] += 1
        out.append((sys_tk, ids[k], 15 + (37 * i) % 71, (73 * i + 20) % 360, 32 + (11 * i) % 16))
    return tuple(out)
#: accuracies a receiver without a fix reports (UBX-NAV-PVT hAcc/vAcc, sAcc, tAcc): "unknown", the largest values
#: of their fields that the message's builders accept (hAcc/vAcc U4 mm: 4294967.295 m)
NO_FIX_ACC_M = 4294967.295
NO_FIX_SACC_MPS = 4294967.295
NO_FIX_TACC_NS = 4294967295
#: 95 % radius of a circular 2-D normal error, in per-axis sigmas: sqrt(-2 ln 0.05).
RADIAL_95 = math.sqrt(-2.0 * math.log(0.05))
#: WGS-84 from its defining constants (protocols.constants), for pymap3d's ENU -> geodetic conversion.
WGS84 = pymap3d.Ellipsoid(A_WGS84, A_WGS84 * (1.0 - F_WGS84), "WGS-84 (protocols.constants)")


#: (class, id) of every message the receiver can output (NMEA standard messages are UBX class 0xF0)
MESSAGE_IDS: dict[str, tuple[int, int]] = {
    "GGA": (0xF0, 0x00), "GSA": (0xF0, 0x02), "GSV": (0xF0, 0x03), "RMC": (0xF0, 0x04), "VTG": (0xF0, 0x05),
    "GST": (0xF0, 0x07),
    "ZDA": (0xF0, 0x08), "NAV-STATUS": (0x01, 0x03), "NAV-PVT": (0x01, 0x07), "NAV-POSLLH": (0x01, 0x02),
    "NAV-SOL": (0x01, 0x06), "NAV-VELNED": (0x01, 0x12), "NAV-TIMEGPS": (0x01, 0x20), "NAV-TIMEUTC": (0x01, 0x21)}
#: the receiver's port number (UBX-CFG-PRT portID): the link is its UART1
UART1 = 1
#: what MON-VER reports (a u-blox M8 with protocol 18, as a NEO-M8N of SPG 3.01 firmware reports itself)
MON_VER = cfgmsg.MonVer("ROM CORE 3.01 (107888)", "00080000",
                        ("FWVER=SPG 3.01", "PROTVER=18.00", "GPS;GLO;GAL;BDS", "SBAS;IMES;QZSS"))
#: CFG-PRT mode of an 8N1 UART: charLen 3 (8 bit) << 6 | parity 4 (none) << 9 | nStopBits 0
MODE_8N1 = (3 << 6) | (4 << 9)


@dataclass
class GnssErrors:
    """GNSS error figures (1 sigma, units in the names)."""

    pos_sigma_h_m: float = 10.0 / RADIAL_95
    pos_sigma_v_m: float = 15.0 / 2.0
    pos_white_fraction: float = 0.2
    pos_corr_time_s: float = 300.0
    #: multipath: a second, faster Gauss-Markov process per axis (0 = none)
    multipath_sigma_h_m: float = 0.0
    multipath_sigma_v_m: float = 0.0
    multipath_corr_time_s: float = 15.0
    vel_sigma_h_mps: float = 0.1 / RADIAL_95
    vel_sigma_v_mps: float = 0.2 / 2.0
    pps_jitter_ns: float = 50.0 / 2.0


@dataclass
class GnssOutage:
    start_s: float
    duration_s: float

    def covers(self, t: float) -> bool:
        return self.start_s <= t < self.start_s + self.duration_s


@dataclass
class GnssGlitch:
    start_s: float
    duration_s: float
    offset_enu_m: tuple[float, float, float]

    def covers(self, t: float) -> bool:
        return self.start_s <= t < self.start_s + self.duration_s


@dataclass
class GnssConfig:
    rate_hz: float = 1.0
    latency_s: float = 0.05
    sentences: tuple[str, ...] = ("GGA", "RMC")
    ubx: tuple[str, ...] = ()
    talker: str = "GP"
    #: NMEA layout: "2.3" or "4.10" (RMC navStatus, GSA systemId, GSV signalId)
    nmea_version: str = "2.3"
    num_sats: int = 12
    hdop: float = 0.8
    #: geoid separation reported (m); None: EGM96 at the reported position
    #: (:func:`emulator.devices.geoid.egm96_separation_m`)
    geoid_sep_m: float | None = None
    #: "reported" (GGA carries the separation) or "empty" (MSL height only, the separation field left empty)
    geoid_sep_field: str = "reported"
    fix_quality: int = 1
    reacquisition_s: float = 0.8
    outages: tuple[GnssOutage, ...] = ()
    glitches: tuple[GnssGlitch, ...] = ()
    errors: GnssErrors = field(default_factory=GnssErrors)
    #: the antenna's surroundings (a :class:`.gnss_environment.GnssEnvironmentProcess`; None: none modelled)
    environment: Any = None


class GnssErrorModel:
    """Position (GM + white) and velocity (white) errors in ENU metres; vectorised over a batch of receivers.

    Parameters
    ----------
    e : figures.
    rng : generator.
    batch : number of independent receivers (1 for a device; many for statistics).
    """

    def __init__(self, e: GnssErrors, rng: np.random.Generator, batch: int = 1) -> None:
        self.e = e
        self.rng = rng
        sig = np.array([e.pos_sigma_h_m, e.pos_sigma_h_m, e.pos_sigma_v_m])
        wf = e.pos_white_fraction
        self.sig_gm = sig * math.sqrt(max(0.0, 1.0 - wf * wf))
        self.sig_w = sig * wf
        self.sig_v = np.array([e.vel_sigma_h_mps, e.vel_sigma_h_mps, e.vel_sigma_v_mps])
        self.batch = batch
        self.gm = self.rng.standard_normal((batch, 3)) * self.sig_gm
        self.sig_mp = np.array([e.multipath_sigma_h_m, e.multipath_sigma_h_m, e.multipath_sigma_v_m])
        self.mp = np.zeros((batch, 3))
        if self.sig_mp.any():
            self.mp = self.rng.standard_normal((batch, 3)) * self.sig_mp

    def restart(self) -> None:
        """Fresh Gauss-Markov draws (after re-acquisition: the solution jumps)."""
        self.gm = self.rng.standard_normal((self.batch, 3)) * self.sig_gm
        if self.sig_mp.any():
            self.mp = self.rng.standard_normal((self.batch, 3)) * self.sig_mp

    def step(self, dt: float) -> tuple[np.ndarray, np.ndarray]:
        """Advance by ``dt`` s; returns (batch, 3) position and velocity errors (E, N, U)."""
        a = math.exp(-dt / self.e.pos_corr_time_s)
        w = self.rng.standard_normal((3, self.batch, 3))
        self.gm = a * self.gm + math.sqrt(1.0 - a * a) * self.sig_gm * w[0]
        pos = self.gm + self.sig_w * w[1]
        if self.sig_mp.any():
            b = math.exp(-dt / self.e.multipath_corr_time_s)
            self.mp = b * self.mp + math.sqrt(1.0 - b * b) * self.sig_mp * self.rng.standard_normal((self.batch, 3))
            pos = pos + self.mp
        return pos, self.sig_v * w[2]


class GnssReceiver:
    """See module docstring.

    Parameters
    ----------
    link : serial link to the FPGA GNSS port.
    trajectory : truth.
    epoch : UTC time of scenario t = 0.
    pps : called with the scenario time of every PPS rising edge (the FPGA's latch input).
    """

    def __init__(self, link: Link, trajectory: Trajectory, epoch: _dt.datetime, rng: np.random.Generator,
                 cfg: GnssConfig | None = None, pps: Callable[[float], None] | None = None) -> None:
        self.link = link
        self.traj = trajectory
        self.epoch = epoch
        self.rng = rng
        self.cfg = cfg or GnssConfig()
        self.pps = pps
        self.errors = GnssErrorModel(self.cfg.errors, rng)
        self.epochs_sent = 0
        self.fixes_sent = 0
        self.last_error_enu = np.zeros(3)
        self.last_vel_error_enu = np.zeros(3)
        self._lost_until: float | None = None
        self._last_t: float | None = None
        # injected faults (emulator.faults): extra outages and glitches, a degraded solution
        self._fault_outages: list[GnssOutage] = []
        self._fault_glitches: list[GnssGlitch] = []
        self._degraded: dict[str, float | int | None] | None = None
        #: evidence counters: epochs sent without a fix, fixes carrying a glitch, fixes sent while degraded
        self.no_fix_epochs = 0
        self.glitched_fixes = 0
        self.degraded_fixes = 0
        #: PPS pulses raised (1 Hz at any rate_hz, none without a fix)
        self.pps_pulses = 0
        self._t0 = 0.0
        self._k = 0
        #: scenario time of the first epoch with a fix (ttff), None before it
        self._first_fix_t: float | None = None
        # what a host configures over the same link (UBX CFG-PRT / CFG-MSG / CFG-RATE), answered as a u-blox does
        self._rates: dict[str, int] = {m: 1 for m in (*self.cfg.sentences, *self.cfg.ubx)}
        self._order: list[str] = [*self.cfg.sentences, *self.cfg.ubx]
        self._out_proto = 0x03  # b0 UBX, b1 NMEA
        self._in_proto = 0x03
        self._prt_baud = link.line.baud if link is not None else 9600  # CFG-PRT reports the line's baud
        self._pending_rate: tuple[float, int, int] | None = None
        self._meas_nav = (round(1000.0 / self.cfg.rate_hz), 1)
        self._host_dec = StreamDecoder([UbxFormat(), NmeaFormat(NMEA_RX_MAX_LEN)])
        #: host messages: polls answered, sets applied (ACK-ACK), refused (ACK-NAK), ignored (not UBX CFG/MON)
        self.host_polls = 0
        self.host_acks = 0
        self.host_naks = 0
        self.host_ignored = 0

    # -- injected faults (emulator.faults) ----------------------------------------------------------
    def add_outage(self, start_s: float, duration_s: float) -> None:
        """Lose lock over ``[start_s, start_s + duration_s)`` (then re-acquire as after any outage)."""
        self._fault_outages.append(GnssOutage(start_s, duration_s))

    def add_glitch(self, start_s: float, duration_s: float, offset_enu_m: tuple[float, float, float]) -> None:
        """Add ``offset_enu_m`` to the reported position over ``[start_s, start_s + duration_s)``."""
        self._fault_glitches.append(GnssGlitch(start_s, duration_s, offset_enu_m))

    def set_degraded(self, noise_scale: float = 1.0, num_sats: int | None = None, hdop: float | None = None,
                     fix_quality: int | None = None) -> None:
        """A poorer solution: noise times ``noise_scale``, fewer satellites (< 4: no fix), hdop, fix quality."""
        self._degraded = {"noise_scale": noise_scale, "num_sats": num_sats, "hdop": hdop, "fix_quality": fix_quality}

    def clear_degraded(self) -> None:
        self._degraded = None

    def _deg(self, key: str) -> float | int | None:
        return self._degraded.get(key) if self._degraded is not None else None

    def start(self) -> None:
        """Schedule the first epoch at the first whole UTC second at or after t = 0 (the receiver's power-on is
        t = 0: ``msss`` counts from there), and listen to the host on the same link."""
        frac = self.epoch.microsecond / 1e6
        self._t0 = 0.0 if frac == 0 else 1.0 - frac
        self._k = 0
        if self.link.on_receive is None:
            self.link.on_receive = self._on_host_bytes
        self._schedule(self._t0)

    # -- the host side: UBX polls and sets (u-blox M8 receiver description, UBX-CFG / UBX-MON) ------------------
    def _on_host_bytes(self, data: bytes) -> None:
        for m in self._host_dec.feed(data):
            if isinstance(m, UbxFrame):
                self._on_host_ubx(m.cls, m.id, m.payload)
            else:
                self.host_ignored += 1  # NMEA from the host (e.g. $PUBX config) and typed UBX: not handled here

    def _reply(self, data: bytes) -> None:
        self.link.send(data)

    def _ack(self, cls: int, mid: int, ok: bool) -> None:
        if ok:
            self.host_acks += 1
        else:
            self.host_naks += 1
        self._reply(cfgmsg.encode_ack(cls, mid, ok))

    def _on_host_ubx(self, cls: int, mid: int, p: bytes) -> None:
        if (cls, mid) == (cfgmsg.CLS_MON, cfgmsg.ID_MON_VER):
            if p:
                self.host_ignored += 1
                return
            self.host_polls += 1
            self._reply(cfgmsg.encode_mon_ver(MON_VER))
            return
        if cls != cfgmsg.CLS_CFG:
            self.host_ignored += 1
            return
        try:
            ok = self._on_cfg(mid, p)
        except ValueError:
            ok = False
        self._ack(cls, mid, ok)

    def _on_cfg(self, mid: int, p: bytes) -> bool:
        """Apply or answer one CFG message; True: ACK-ACK, False: ACK-NAK."""
        if mid == cfgmsg.ID_CFG_PRT:
            if len(p) <= 1:  # poll (of the current port, or of portID)
                port = p[0] if p else UART1
                if port != UART1:
                    return False
                self.host_polls += 1
                self._reply(cfgmsg.encode_cfg_prt(cfgmsg.CfgPrt(UART1, 0, 0, MODE_8N1, self._prt_baud,
                                                                self._in_proto, self._out_proto, 0, 0)))
                return True
            prt = cfgmsg.decode_cfg_prt(p)
            if prt.portID != UART1 or prt.baudRate <= 0:
                return False
            # the line rate itself is the scenario's (links.gnss.baud); the receiver reports what it was told
            self._prt_baud, self._in_proto, self._out_proto = prt.baudRate, prt.inProtoMask, prt.outProtoMask
            return True
        if mid == cfgmsg.ID_CFG_MSG:
            if len(p) == 2:  # poll
                name = self._message_name(p[0], p[1])
                if name is None:
                    return False
                self.host_polls += 1
                rates = [0] * 6
                rates[UART1] = self._rates.get(name, 0)
                self._reply(cfgmsg.encode_cfg_msg(cfgmsg.CfgMsg(p[0], p[1], *rates)))
                return True
            m = cfgmsg.decode_cfg_msg(p, UART1)
            name = self._message_name(m.msgClass, m.msgID)
            if name is None:
                return False
            self._rates[name] = m.rateUART1
            if name not in self._order:
                self._order.append(name)
            return True
        if mid == cfgmsg.ID_CFG_RATE:
            if not p:
                self.host_polls += 1
                self._reply(cfgmsg.encode_cfg_rate(cfgmsg.CfgRate(self._meas_nav[0], self._meas_nav[1], 1)))
                return True
            r = cfgmsg.decode_cfg_rate(p)
            if r.navRate < 1 or r.measRate < 50 or r.timeRef > 4:  # u-blox M8: at most 18-20 Hz, navRate >= 1
                return False
            hz = 1000.0 / (r.measRate * r.navRate)
            if not 0 < hz <= 20.0:
                return False
            # takes effect at the next whole UTC second (the epoch grid stays aligned to the PPS)
            self._pending_rate = (hz, r.measRate, r.navRate)
            return True
        return False  # other CFG messages: not supported by this model

    @staticmethod
    def _message_name(cls: int, mid: int) -> str | None:
        for name, ids in MESSAGE_IDS.items():
            if ids == (cls, mid):
                return name
        return None

    def output_set(self) -> GnssOutputSet:
        """The messages of the current epoch: CFG-MSG rates (every N epochs) and CFG-PRT's output protocols."""
        k = self._k
        on = [m for m in self._order if self._rates.get(m, 0) and k % self._rates[m] == 0]
        nmea = tuple(m for m in on if m in NMEA_SENTENCES) if self._out_proto & 0x02 else ()
        ubx = tuple(m for m in on if m in UBX_MESSAGES) if self._out_proto & 0x01 else ()
        cfg = self.cfg
        return GnssOutputSet(nmea=nmea, ubx=ubx, talker=cfg.talker, rate_hz=cfg.rate_hz, version=cfg.nmea_version)

    def _schedule(self, t: float) -> None:
        self.link.loop.call_at(t, self._epoch, t)

    def _is_whole_second(self, t: float) -> bool:
        """Whether the epoch at scenario time ``t`` is a whole UTC second (PPS is 1 Hz at any navigation rate)."""
        u = t + self.epoch.microsecond / 1e6
        return abs(u - round(u)) < 1e-6

    def has_fix(self, t: float) -> bool:
        """No fix inside an outage and for ``reacquisition_s`` after it."""
        cfg = self.cfg
        for o in (*cfg.outages, *self._fault_outages) if self._fault_outages else cfg.outages:
            if o.covers(t) or (o.start_s + o.duration_s <= t < o.start_s + o.duration_s + cfg.reacquisition_s):
                return False
        sats = self._deg("num_sats")
        return sats is None or sats >= 4  # no 3-D solution from fewer than four satellites

    def _epoch(self, t: float) -> None:
        if self._pending_rate is not None and self._is_whole_second(t):
            hz, meas, nav = self._pending_rate
            self._pending_rate = None
            self.cfg = replace(self.cfg, rate_hz=hz)
            self._meas_nav = (meas, nav)
            self._t0, self._k = t, 0
        fix = self.has_fix(t)
        if fix and self.pps is not None and self._is_whole_second(t):
            jitter = self.rng.standard_normal() * self.cfg.errors.pps_jitter_ns * 1e-9
            self.pps(t + jitter)
            self.pps_pulses += 1
        if fix and self._first_fix_t is None:
            self._first_fix_t = t
        self.link.loop.call_at(t + self.cfg.latency_s, self._emit, t, fix, self.output_set())
        self._k += 1
        self._schedule(self._t0 + self._k / self.cfg.rate_hz)  # no accumulated rounding: PPS stays on the second

    def _emit(self, t: float, fix: bool, output: GnssOutputSet | None = None) -> None:
        if not fix:
            self.no_fix_epochs += 1
        out = self.sentences(t, fix, output)
        if out:
            self.link.send(out)
        self.epochs_sent += 1

    @property
    def _output(self) -> GnssOutputSet:
        cfg = self.cfg
        return GnssOutputSet(nmea=tuple(cfg.sentences), ubx=tuple(cfg.ubx), talker=cfg.talker, rate_hz=cfg.rate_hz,
                             version=cfg.nmea_version)

    def _fix(self, utc: _dt.datetime, lat_deg: float, lon_deg: float, h_m: float,
             vel_enu: tuple[float, float, float], fix_type: int = 3, quality: int | None = None) -> GnssFix:
        """What the receiver reports for one epoch (accuracy fields from its configured error figures)."""
        cfg = self.cfg
        e = cfg.errors
        num_sats, hdop, fq = cfg.num_sats, cfg.hdop, cfg.fix_quality
        if self._degraded is not None:
            num_sats = int(self._deg("num_sats") if self._deg("num_sats") is not None else num_sats)  # type: ignore[arg-type]
            hdop = float(self._deg("hdop") if self._deg("hdop") is not None else hdop)  # type: ignore[arg-type]
            fq = int(self._deg("fix_quality") if self._deg("fix_quality") is not None else fq)  # type: ignore[arg-type]
        t = (utc - self.epoch).total_seconds()
        msss = max(0, round(t * 1000.0))  # ms since start-up (power-on at t = 0)
        ttff = 0 if self._first_fix_t is None else round(self._first_fix_t * 1000.0)
        sep = cfg.geoid_sep_m if cfg.geoid_sep_m is not None else egm96_separation_m(lat_deg, lon_deg)
        in_gga = cfg.geoid_sep_field != "empty"
        if not fix_type:
            # no fix: the receiver reports its accuracies as unknown (U4 / U2 at their largest valid values; the
            # DOPs at 99.99 as NMEA receivers print them in GGA/GSA without a fix)
            return GnssFix(
                utc=utc, lat_deg=lat_deg, lon_deg=lon_deg, height_m=h_m, geoid_sep_m=sep, geoid_sep_in_gga=in_gga,
                vel_enu_mps=vel_enu, fix_type=0, quality=0, sat_ids=(), hdop=99.99, vdop=99.99, pdop=99.99,
                sky=tuple((e[0], e[1], e[2], e[3], None) for e in constellation(cfg.talker, cfg.num_sats)),
                h_acc_m=NO_FIX_ACC_M, v_acc_m=NO_FIX_ACC_M, s_acc_mps=NO_FIX_SACC_MPS, head_acc_deg=180.0,
                t_acc_ns=NO_FIX_TACC_NS, ttff_ms=ttff, msss_ms=msss,
            )
        sky = constellation(cfg.talker, num_sats)
        return GnssFix(
            utc=utc, lat_deg=lat_deg, lon_deg=lon_deg, height_m=h_m, geoid_sep_m=sep, geoid_sep_in_gga=in_gga,
            vel_enu_mps=vel_enu,
            fix_type=fix_type, quality=fq if quality is None else quality,
            sat_ids=tuple(e[1] for e in sky), sky=sky, hdop=hdop,
            h_acc_m=e.pos_sigma_h_m * math.sqrt(2.0), v_acc_m=e.pos_sigma_v_m,
            s_acc_mps=e.vel_sigma_h_mps * math.sqrt(2.0), ttff_ms=ttff, msss_ms=msss,
            # GST: in an environment the receiver's residuals show (part of) its multipath (D-4.14)
            gst_std_m=cfg.environment.reported_std_m(e, num_sats) if cfg.environment is not None else None,
        )

    def sentences(self, t: float, fix: bool = True, output: GnssOutputSet | None = None) -> bytes:
        """The bytes of the epoch at ``t`` (its NMEA sentences, then its UBX messages; advances the error model).
        ``output``: the message set (default: the configured one)."""
        cfg = self.cfg
        out_set = output if output is not None else self._output
        dt = 1.0 / cfg.rate_hz if self._last_t is None else t - self._last_t
        self._last_t = t
        utc = self.epoch + _dt.timedelta(seconds=t)
        if not fix:
            self._lost_until = t
            return build_epoch(self._fix(utc, 0.0, 0.0, 0.0, (0.0, 0.0, 0.0), fix_type=0, quality=0), out_set)
        if self._lost_until is not None:
            self.errors.restart()
            self._lost_until = None
        perr, verr = self.errors.step(max(dt, 1e-3))
        err = perr[0].copy()
        vel_err = verr[0]
        if self._degraded is not None:
            scale = float(self._deg("noise_scale") or 1.0)
            err = err * scale
            vel_err = vel_err * scale
            self.degraded_fixes += 1
        for g in cfg.glitches:
            if g.covers(t):
                err += np.asarray(g.offset_enu_m)
        for g in self._fault_glitches:
            if g.covers(t):
                err += np.asarray(g.offset_enu_m)
                self.glitched_fixes += 1
        if cfg.environment is not None:  # NLOS bias and outliers (emulator/devices/gnss_environment.py)
            err = err + cfg.environment.position_offset(t, dt)
        self.last_error_enu = err
        self.last_vel_error_enu = vel_err
        st = self.traj.state(t)
        lat, lon, h = (float(x) for x in st.pos)
        # the error is a displacement in the local ENU frame of the true position (pymap3d, WGS-84 ellipsoid)
        lat_m, lon_m, h_m = (float(x) for x in pymap3d.enu2geodetic(
            float(err[0]), float(err[1]), float(err[2]), lat, lon, h, ell=WGS84, deg=False))
        v = st.v_enu + vel_err
        out = build_epoch(self._fix(utc, lat_m / DEG, lon_m / DEG, h_m, (float(v[0]), float(v[1]), float(v[2]))),
                          out_set)
        self.fixes_sent += 1
        return bytes(out)
