"""GNSS receiver: 1 Hz fixes as NMEA GGA + RMC on an RS422 link, and the PPS line.

At every whole UTC second the receiver raises PPS (latched by the FPGA) and, ``latency_s``
later, writes the sentences of that epoch; at 9600 baud a GGA + RMC pair takes ~0.15 s on the
wire. Errors (base paper figures, DESIGN.md section 2, read as 95 % bounds, docs/decisions.md):
horizontal position < 10 m (95 % radial: 4.08 m per axis), vertical < 15 m (95 %: 7.5 m), as a
first-order Gauss-Markov process (``pos_corr_time_s``) plus a white part; horizontal velocity
0.1 m/s (95 % radial: 0.041 m/s per axis) and vertical 0.2 m/s (0.1 m/s), white.
Height in GGA is above MSL: ``h_msl = h - geoid_sep_m``.
"""

from __future__ import annotations

import datetime as _dt
import math
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from firmware_model import earth
from protocols.nmea import build_gga, build_rmc

from ..links.base import Link
from ..world.trajectory import Trajectory

__all__ = ["GnssErrors", "GnssReceiver"]

DEG = math.pi / 180.0
#: 95 % radius of a circular 2-D normal error, in per-axis sigmas: sqrt(-2 ln 0.05).
RADIAL_95 = math.sqrt(-2.0 * math.log(0.05))


@dataclass
class GnssErrors:
    """GNSS error figures (1 sigma, units in the names)."""

    pos_sigma_h_m: float = 10.0 / RADIAL_95
    pos_sigma_v_m: float = 15.0 / 2.0
    pos_white_fraction: float = 0.2
    pos_corr_time_s: float = 300.0
    vel_sigma_h_mps: float = 0.1 / RADIAL_95
    vel_sigma_v_mps: float = 0.2 / 2.0


@dataclass
class GnssConfig:
    rate_hz: float = 1.0
    latency_s: float = 0.05
    sentences: tuple[str, ...] = ("GGA", "RMC")
    talker: str = "GP"
    num_sats: int = 12
    hdop: float = 0.8
    geoid_sep_m: float = 0.0
    errors: GnssErrors = field(default_factory=GnssErrors)


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
        e = self.cfg.errors
        self._sig_gm = np.array([e.pos_sigma_h_m, e.pos_sigma_h_m, e.pos_sigma_v_m]) * math.sqrt(1 - e.pos_white_fraction**2)
        self._sig_w = np.array([e.pos_sigma_h_m, e.pos_sigma_h_m, e.pos_sigma_v_m]) * e.pos_white_fraction
        self.gm = rng.standard_normal(3) * self._sig_gm
        self.epochs_sent = 0
        self.last_error_enu = np.zeros(3)
        self.last_vel_error_enu = np.zeros(3)

    def start(self) -> None:
        """Schedule the first epoch at the first whole UTC second at or after t = 0."""
        frac = self.epoch.microsecond / 1e6
        t0 = 0.0 if frac == 0 else 1.0 - frac
        self._schedule(t0)

    def _schedule(self, t: float) -> None:
        self.link.loop.call_at(t, self._epoch, t)

    def _epoch(self, t: float) -> None:
        if self.pps is not None:
            self.pps(t)
        self.link.loop.call_at(t + self.cfg.latency_s, self._emit, t)
        self._schedule(t + 1.0 / self.cfg.rate_hz)

    def _emit(self, t: float) -> None:
        cfg = self.cfg
        e = cfg.errors
        st = self.traj.state(t)
        dt = 1.0 / cfg.rate_hz
        a = math.exp(-dt / e.pos_corr_time_s)
        self.gm = a * self.gm + math.sqrt(1 - a * a) * self._sig_gm * self.rng.standard_normal(3)
        err = self.gm + self._sig_w * self.rng.standard_normal(3)  # E, N, U metres
        self.last_error_enu = err
        lat, lon, h = st.pos
        rm, rn = earth.radii(lat)
        lat_m = lat + err[1] / (rm + h)
        lon_m = lon + err[0] / ((rn + h) * math.cos(lat))
        h_m = h + err[2]
        verr = self.rng.standard_normal(3) * np.array([e.vel_sigma_h_mps, e.vel_sigma_h_mps, e.vel_sigma_v_mps])
        self.last_vel_error_enu = verr
        v = st.v_enu + verr
        utc = self.epoch + _dt.timedelta(seconds=t)
        tm = utc.time()
        out = bytearray()
        for kind in cfg.sentences:
            if kind == "GGA":
                out += build_gga(tm, lat_m / DEG, lon_m / DEG, h_m - cfg.geoid_sep_m, cfg.geoid_sep_m,
                                 quality=1, num_sats=cfg.num_sats, hdop=cfg.hdop, talker=cfg.talker)
            elif kind == "RMC":
                speed = math.hypot(v[0], v[1])
                course = math.degrees(math.atan2(v[0], v[1])) % 360.0
                out += build_rmc(tm, utc.date(), lat_m / DEG, lon_m / DEG, speed, course, talker=cfg.talker)
        if out:
            self.link.send(bytes(out))
        self.epochs_sent += 1
