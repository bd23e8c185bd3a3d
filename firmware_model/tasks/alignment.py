"""Coarse alignment glue: levelling from the mean specific force, heading from the solar vector (TRIAD) or the
configuration, then the filter's start (mode manager COARSE_ALIGN -> FINE_ALIGN); restart on RESET_FILTER.

The kernels are in :mod:`firmware_model.alignment`.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from protocols.host import NavMode

from .. import c674x, sun
from ..alignment import level_from_specific_force, solar_heading_alignment
from ..arrays import FloatArray, FloatDtype
from ..attitude import a2mat, heading_from_yaw, m2att, mat2q, q2mat_fast, rv2q, yaw_from_heading
from ..config import FirmwareConfig
from ..filters.solar import SolarObservation
from ..nav_state import NavState
from ..units import DEG
from .gnss import GnssTask
from .navigation import NavCore
from .psns import PsnsTask
from .state import FirmwareState, LoopStatus, TickResult
from .timekeeping import Clock

__all__ = ["AlignmentTask"]


class AlignmentTask:
    """Coarse alignment (levelling window, heading source, misalignment of a paper's initial condition).

    A task object of the cyclic executive: its state (the levelling window's sum, the solar vectors kept for the
    TRIAD heading) is its own; collaborators ``cfg``, ``meter`` and ``cyc`` (per-tick kernel cycles), ``core``
    (started at the end, reset by :meth:`restart`), ``gnss`` (the position fix), ``clock`` (UTC), ``psns`` (the
    solve of a frame), ``status`` (the mode manager's state it moves and the heading's standing it sets);
    ``dtype`` / ``nav_dtype``: the working precision and that of the strapdown state."""

    def __init__(self, cfg: FirmwareConfig, meter: c674x.CycleMeter, cyc: dict[str, int], core: NavCore,
                 gnss: GnssTask, clock: Clock, psns: PsnsTask, status: LoopStatus, dtype: FloatDtype,
                 nav_dtype: FloatDtype) -> None:
        self.cfg = cfg
        self.meter = meter
        self._cyc_level, self._cyc_triad = cyc["level"], cyc["triad"]
        self.core = core
        self.gnss = gnss
        self.clock = clock
        self.psns = psns
        self.status = status
        self.dtype = dtype
        self.nav_dtype = nav_dtype
        self._align_sum = np.zeros(3)
        self._align_n = 0
        self._align_t0: float | None = None
        self._align_sun: list[SolarObservation] = []

    def accumulate(self, t: float, f_b: FloatArray, res: TickResult) -> None:
        """One IMU tick of the coarse alignment at ``t`` (s; ``f_b``: specific force, body): into the levelling
        window; at its end (with a GNSS fix and the heading source ready) the navigation state and the filter
        start (``alignment_done`` into ``res``)."""
        cfg = self.cfg
        if self._align_t0 is None:
            self._align_t0 = t
        self._align_sum += f_b
        self._align_n += 1
        self.meter.charge("align_accumulate", c674x.flops(0, 3))
        if t - self._align_t0 < cfg.align_time_s or self.gnss.last_fix is None:
            return
        fm = self._align_sum / self._align_n
        lat, lon, h, _ = self.gnss.last_fix
        source = "config"
        heading_sigma = cfg.initial_heading_sigma_deg * DEG
        cbn = None
        want_psns = cfg.psns_enabled and cfg.alignment_heading in ("auto", "psns")
        if want_psns and self._align_sun and self.clock.utc_days(t) is not None:
            cbn, _sun_el = self._solar_alignment(fm, lat, lon)
            if cbn is not None:
                source = "psns"
                heading_sigma = cfg.psns_heading_sigma_deg * DEG
        if cbn is None and cfg.psns_enabled and cfg.alignment_heading == "psns" \
                and t - self._align_t0 < cfg.align_time_s + cfg.psns_align_timeout_s:
            return  # wait for a solar vector
        pitch, roll = level_from_specific_force(fm)
        self.meter.charge("coarse_level", self._cyc_level)
        if cbn is None:
            cbn = a2mat(pitch, roll, yaw_from_heading(cfg.initial_heading_deg * DEG))
            if cfg.alignment_heading == "psns":  # timed out: the heading is a placeholder, uniform on the circle
                heading_sigma = math.pi / math.sqrt(3.0)  # (D-5.50)
        if any(cfg.initial_misalignment_deg):  # C_b^{n'} = rv2m(-phi) C_b^n: the computed frame is off by phi
            cbn = q2mat_fast(rv2q(-np.asarray(cfg.initial_misalignment_deg, dtype=np.float64) * DEG)) @ cbn
        nd = self.nav_dtype
        self.core.start(NavState(q=mat2q(cbn).astype(nd), v=np.zeros(3, dtype=nd), pos=np.array([lat, lon, h]), t=t,
                                 a_prev=np.zeros(3, dtype=nd)), heading_sigma, t)
        self.status.heading_sigma0 = heading_sigma
        self.status.heading_placeholder = source == "config" and cfg.alignment_heading == "psns"  # timed out: D-5.50
        self.status.state = FirmwareState.FINE_ALIGN
        self.status.mode = NavMode.NAVIGATING | NavMode.ALIGNING
        self.status.t_aligned = t
        self.gnss.take()
        p, r, y = m2att(cbn)
        res.events.append({"event": "alignment_done", "t_fpga_s": t, "pitch_deg": p / DEG, "roll_deg": r / DEG,
                           "heading_deg": heading_from_yaw(y) / DEG, "heading_source": source,
                           "samples": self._align_n, "solar_vectors": len(self._align_sun)})

    def psns_frame(self, t_rx: float, f: Any) -> None:
        """A PSNS frame (received at ``t_rx``, s) during the coarse alignment: solved and kept for the TRIAD
        heading."""
        self.meter.begin("psns_update", 0.0)
        obs = self.psns.alignment_observation(t_rx, f)
        self.meter.end()
        if obs is not None and self._align_t0 is not None and obs.t_exposure_s >= self._align_t0 - 1.0:
            self._align_sun.append(obs)
            del self._align_sun[:-32]

    def _solar_alignment(self, f_b: FloatArray, lat: float, lon: float) -> tuple[FloatArray | None, float]:
        """TRIAD from gravity and the mean solar vector of the levelling window."""
        up = f_b / np.linalg.norm(f_b)
        acc = np.zeros(3)
        t_mean = 0.0
        for o in self._align_sun:
            s = o.s_b.astype(np.float64)
            acc += s if float(s @ up) >= 0 else -s
            t_mean += o.t_exposure_s
        t_mean /= len(self._align_sun)
        days = self.clock.utc_days(t_mean)
        assert days is not None
        s_n = sun.sun_vector_enu(days, lat, lon, dtype=self.dtype).astype(np.float64)
        self.meter.charge("sun_ephemeris", sun.ephemeris_cycles())
        el = math.asin(max(-1.0, min(1.0, float(s_n[2]))))
        if el < self.cfg.psns_min_sun_elevation_deg * DEG or el > 80.0 * DEG:
            return None, el
        try:
            cbn, _ = solar_heading_alignment(f_b, acc / np.linalg.norm(acc), s_n)
        except ValueError:
            return None, el
        self.meter.charge("triad", self._cyc_triad)
        return cbn, el

    def restart(self) -> None:
        """RESET_FILTER scope 0: back to coarse alignment with a fresh filter (biases included)."""
        self.status.state = FirmwareState.COARSE_ALIGN
        self.status.mode = NavMode.ALIGNING
        self.core.reset()
        self._align_sum[:] = 0.0
        self._align_n = 0
        self._align_t0 = None
        self._align_sun.clear()
        self.gnss.take()
