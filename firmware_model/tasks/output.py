"""Navigation output: NAV_SOLUTION at ``output_rate_hz`` (protocols/host.py) and the CPU load it reports."""

from __future__ import annotations

import math

from protocols.host import NavMode, nav_solution_frame

from .. import earth
from ..attitude import heading_from_yaw
from ..kf import D_H, D_LAT, D_LON, DV_E, DV_N, DV_U, N_NAV_ERRORS, PHI_E, PHI_N, PHI_U
from ..nav_state import POS, Q, V
from ..units import DEG
from .state import FirmwareState, LoopState

__all__ = ["NavOutput"]

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

    def _nav_output(self, t: float) -> bytes:
        s = self.nav
        mode = int(self.mode) | (self.filter.variant_id & 0xF) << 8
        if s is None:
            lat = lon = h = 0.0
            if self._last_fix is not None:
                lat, lon, h = self._last_fix[0], self._last_fix[1], self._last_fix[2]
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
            # PSINS m2att from the quaternion directly: C32, C31, C33, C12, C22 of C_b^n
            q0, q1, q2, q3 = x[Q]
            c32 = 2.0 * (q2 * q3 + q0 * q1)
            pitch = math.asin(max(-1.0, min(1.0, c32))) / DEG
            roll = math.atan2(-2.0 * (q1 * q3 - q0 * q2), q0 * q0 - q1 * q1 - q2 * q2 + q3 * q3) / DEG
            yaw = math.atan2(-2.0 * (q1 * q2 - q0 * q3), q0 * q0 - q1 * q1 + q2 * q2 - q3 * q3)
            heading = heading_from_yaw(yaw) / DEG
            # sqrt(max(v, 0)) of the navigation errors' variances (kf layout)
            d = [_sqrt(0.0 if v < 0.0 else v) for v in self.filter.P.diagonal()[:N_NAV_ERRORS].tolist()]
            rm, rn = earth.radii(lat)
            sigma = (
                d[PHI_E] / DEG, d[PHI_N] / DEG, d[PHI_U] / DEG, d[DV_E], d[DV_N], d[DV_U],
                d[D_LAT] * (rm + h), d[D_LON] * (rn + h) * math.cos(lat), d[D_H],
            )
        fix = self._last_fix
        vs = self.filter.variant_status()
        if vs is not None:  # VARIANT block: pack 4 bytes + CRC over 6 more [E]
            self.meter.charge("nav_variant_block", 6 * 4 + 4 * 2)
        seq = self._out_seq
        self._out_seq = seq + 1
        # the NavSolution fields in order (protocols.host.nav_solution_frame), without building the object
        return nav_solution_frame(
            seq, t, lat / DEG, lon / DEG, h, vel, roll, pitch, heading, sigma, int(mode),
            fix[3] if fix is not None else 0, self._psns_status_now(t), self.cpu_load_pct(), self.deadline_misses,
            *(vs if vs is not None else (None, 0, 0)))
