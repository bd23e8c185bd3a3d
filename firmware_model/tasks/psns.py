"""PSNS staging and update: exposure time of a frame, solve (POLARIZATION_OBS), body frame, solar-vector update.

A frame's mid-exposure time comes from the reception time of its last byte, its length on the wire and the
sensor's declared latency (docs/architecture.md, section "Conventions"; docs/decisions/firmware.md D-5.8).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from protocols.psns import CompassFrame, PolarizationObs, PolarizationObsPacked, PsnsStatus, SolarVectorFrame

from .. import c674x, psns, sun
from ..arrays import FloatDtype
from ..attitude import mat2q, q2mat_fast
from ..config import FirmwareConfig
from ..filters.interface import UpdateReport
from ..filters.solar import SolarObservation
from ..units import DEG
from .navigation import NavCore
from .state import LoopStatus, SolarSolve
from .timekeeping import Clock

__all__ = ["PsnsTask", "psns_frame_len"]


#: the decoded POLARIZATION_OBS frames: points as objects, or as their wire bytes (the loop's own decoder,
#: ``PsnsFormat(packed_points=True)``: no point objects per frame)
_OBS_FRAMES = (PolarizationObs, PolarizationObsPacked)


def psns_frame_len(f: Any) -> int:
    """Wire length of a decoded PSNS frame (sync, id, length, header, body, CRC)."""
    if isinstance(f, _OBS_FRAMES):
        return 7 + 13 + 10 * f.n_points
    if isinstance(f, CompassFrame):
        return 7 + 13 + 5 * len(f.units)
    return 7 + 13 + 16


class PsnsTask:
    """Decode-side work and measurement update of the PSNS frames (UART2).

    A task object of the cyclic executive: its state (the solves of the current tick) is its own; collaborators
    ``cfg``, ``meter``, ``cost`` (kernel prices) and ``cyc`` (per-tick kernel cycles), ``counters`` (the loop's
    table, shared), ``core`` (navigation state, filter, INS history), ``clock`` (UTC), ``status`` (the heading's
    standing after the alignment) and ``events`` (the loop's list of events for the next result). The loop owns
    the UART2 decoder and the queue of frames; it hands each frame to :meth:`observation` (coarse alignment) or
    :meth:`update`."""

    def __init__(self, cfg: FirmwareConfig, meter: c674x.CycleMeter, cost: c674x.KernelCosts, cyc: dict[str, int],
                 counters: dict[str, int], core: NavCore, clock: Clock, status: LoopStatus,
                 events: list[dict[str, Any]], dtype: FloatDtype) -> None:
        self.cfg = cfg
        self.meter = meter
        self.cost = cost
        self._cyc_normalise, self._cyc_mounting = cyc["normalise"], cyc["mounting"]
        self.counters = counters
        self.core = core
        self.clock = clock
        self.status = status
        self.events = events
        self.dtype = dtype
        self._solar_solves: list[SolarSolve] = []  # solved in the current tick (TickResult.solar_solves)

    def take_solves(self) -> list[SolarSolve]:
        """The solar vectors solved since the last call (this tick's, for ``TickResult.solar_solves``)."""
        solves = self._solar_solves
        self._solar_solves = []
        return solves

    def has_solves(self) -> bool:
        """Whether a solar vector was solved since :meth:`take_solves`."""
        return bool(self._solar_solves)

    def alignment_observation(self, t_rx: float, f: Any) -> SolarObservation | None:
        """One frame during the coarse alignment: the solar vector solved and marked for the alignment."""
        obs = self.observation(t_rx, f)
        if obs is not None:
            self._solar_solves[-1].use = "alignment"
        return obs

    def _psns_frame_in(self, t_rx: float, f: Any) -> float:
        """Count and charge a decoded PSNS frame; return its mid-exposure time (docs/architecture.md "Conventions",
        docs/decisions/firmware.md D-5.8)."""
        cfg = self.cfg
        self.counters["psns_frames"] += 1
        if isinstance(f, CompassFrame):
            self.counters["compass_frames"] += 1
        n_bytes = psns_frame_len(f)
        self.meter.charge("psns_decode", n_bytes * 4 + c674x.CALL_OVERHEAD)  # CRC-16 by table + copy [E]
        return psns.exposure_time_s(t_rx, n_bytes, cfg.psns_baud, f.header.latency_us, cfg.psns_bits_per_byte)

    def observation(self, t_rx: float, f: Any) -> SolarObservation | None:
        """Decode-side work for one PSNS frame: exposure time, solve (POLARIZATION_OBS), body frame."""
        cfg = self.cfg
        m = self.meter
        dt = self.dtype
        t_exp = self._psns_frame_in(t_rx, f)
        if isinstance(f, CompassFrame):
            return None
        h = f.header
        if not h.status & PsnsStatus.VALID:
            self.counters["psns_invalid"] += 1
            return None
        cam = cfg.camera
        if isinstance(f, _OBS_FRAMES):
            n = f.n_points
            if n < 3:
                self.counters["psns_invalid"] += 1
                return None
            pts = psns.obs_points_array(f.point_bytes)
            aop = (pts[:, 2] * (0.01 * DEG)).astype(dt)
            dop = (pts[:, 3] * (1.0 / 65535.0)).astype(dt)
            aop, dop = psns.correct_polarizer(aop, dop, cam, dtype=dt)
            m.charge("psns_polarizer", psns.polarizer_cycles(n, cam, self.cost))
            e = psns.evectors_camera(pts[:, 0], pts[:, 1], aop, cam, dtype=dt)
            sol = psns.solve_solar_vector(e, dop, cfg.psns_dop_min, max_quality=cfg.psns_quality_max)
            m.charge("psns_evectors", psns.evector_cycles(n, self.cost))
            m.charge("psns_solve", psns.solve_cycles(n, self.cost))
            if not sol.valid:
                self.counters["psns_invalid"] += 1
                return None
            s_c, quality, n_used, source = sol.s, sol.quality, sol.n_used, "camera"
        elif isinstance(f, SolarVectorFrame):
            s_c = np.array(f.s, dtype=dt)
            nrm = float(np.sqrt(s_c @ s_c))
            if not (0.5 < nrm < 1.5) or f.quality > cfg.psns_quality_max:
                self.counters["psns_invalid"] += 1
                return None
            s_c = s_c / dt(nrm)
            quality, n_used, source = float(f.quality), h.count, "sensor"
            m.charge("psns_normalise", self._cyc_normalise)
        else:
            return None
        self.counters["psns_solutions"] += 1
        s_b = (cam.c_c_b.astype(dt) @ s_c).astype(dt)
        m.charge("psns_mounting", self._cyc_mounting)
        self._solar_solves.append(SolarSolve(t_exp, (float(s_b[0]), float(s_b[1]), float(s_b[2])), int(n_used),
                                             float(quality), source))
        return SolarObservation(t_exp, s_b, quality, n_used, source)

    def update(self, t: float, t_rx: float, f: Any) -> UpdateReport | None:
        """One pending PSNS frame after the coarse alignment (the navigation state exists)."""
        cfg = self.cfg
        nav = self.core.nav
        assert nav is not None
        if isinstance(f, CompassFrame):
            t_exp = self._psns_frame_in(t_rx, f)
            return self.core.filter.update_compass(nav, f, t_exp) if cfg.psns_enabled else None
        if self.core.filter.raw_polarization_obs and isinstance(f, _OBS_FRAMES):
            t_exp = self._psns_frame_in(t_rx, f)
            if not cfg.psns_enabled:
                return None
            if t - t_exp > cfg.psns_max_age_s:
                self.counters["psns_stale"] += 1  # older than psns_max_age_s when its turn came: dropped, counted
                return None
            return self.core.filter.update_polarization_obs(nav, f, t_exp)
        obs = self.observation(t_rx, f)
        if obs is None:
            return None
        solve = self._solar_solves[-1]  # the record of this solve (TickResult.solar_solves)
        if not cfg.psns_enabled:
            solve.use = "disabled"
            return None
        if t - obs.t_exposure_s > cfg.psns_max_age_s:
            solve.use = "stale"
            self.counters["psns_stale"] += 1
            return None
        days = self.clock.utc_days(obs.t_exposure_s)
        if days is None:
            solve.use = "no_utc"
            return None
        p_ins, _, q_exp = self.core.ins_at(obs.t_exposure_s)
        s_n = sun.sun_vector_enu(days, float(p_ins[0]), float(p_ins[1]), dtype=self.dtype)
        self.meter.charge("sun_ephemeris", sun.ephemeris_cycles())
        if float(s_n[2]) < math.sin(cfg.psns_min_sun_elevation_deg * DEG):
            self.counters["psns_sun_low"] += 1  # night or twilight: not an error, no update
            solve.use = "sun_low"
            return None
        if self.status.heading_placeholder and self._late_solar_heading(obs, s_n, q_exp):
            solve.use = "alignment"
            return None
        rep = self.core.filter.update_solar(nav, obs, s_n, q2mat_fast(q_exp))
        solve.use = "accepted" if rep.accepted else "refused"
        return rep

    def _late_solar_heading(self, obs: SolarObservation, s_n: Any, q_exp: Any) -> bool:
        """The heading from the first solar vector after a PSNS alignment that timed out (D-5.50).

        The alignment asked for the sun (``alignment_heading: psns``) and, without a valid solve within
        ``psns_align_timeout_s``, started from the configured heading, a placeholder the filter must not trust at
        ``initial_heading_sigma_deg``. The first solar vector turns the attitude about the vertical so that the
        solved sun has the ephemeris' azimuth (levels kept) and restarts the filter at ``psns_heading_sigma_deg``.
        False (nothing done) when the sun is within 10 deg of the zenith (its azimuth undefined)."""
        if float(s_n[2]) > math.sin(80.0 * DEG):
            return False
        nav = self.core.nav
        assert nav is not None
        c_exp = q2mat_fast(np.asarray(q_exp, dtype=np.float64))
        s_b = obs.s_b.astype(np.float64)
        if float(s_b @ c_exp[2, :]) < 0.0:  # the solve's sign: the sun above the horizon
            s_b = -s_b
        s_m = c_exp @ s_b
        d = math.atan2(float(s_n[1]), float(s_n[0])) - math.atan2(float(s_m[1]), float(s_m[0]))
        cd, sd = math.cos(d), math.sin(d)
        rz = np.array([[cd, -sd, 0.0], [sd, cd, 0.0], [0.0, 0.0, 1.0]])  # about Up (ENU), counter-clockwise
        nav.q = mat2q(rz @ q2mat_fast(np.asarray(nav.q, dtype=np.float64))).astype(nav.q.dtype)
        sigma = self.cfg.psns_heading_sigma_deg * DEG
        self.core.filter.initialise(nav, sigma)
        self.status.heading_sigma0 = sigma
        self.status.heading_placeholder = False
        self.events.append({"event": "late_solar_heading", "t_fpga_s": obs.t_exposure_s,
                                   "heading_change_deg": -math.degrees(math.atan2(sd, cd))})
        return True
