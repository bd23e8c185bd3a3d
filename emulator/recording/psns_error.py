"""The firmware's solved solar vectors against truth: ``psns.csv`` and the summary's ``psns`` section.

Every solve the firmware reports (``TickResult.solar_solves``, :class:`firmware_model.registry.SolarSolve`) is
compared with the world's truth at its mid-exposure time ``t``: the body-frame sun vector

    ``S^b_true(t) = (C_b^n(t))^T S^n(t)``

with ``C_b^n`` the trajectory's attitude (:mod:`emulator.world.trajectory`) and ``S^n`` the SPA sun vector in
ENU at the trajectory's position (:class:`emulator.world.sun.SunModel`; the same sun the sky and the camera
model are drawn from). The solve is bi-directional (``+-S``, base paper Eqs. 9-14; the filter picks the sign
with the smaller residual, the remark after Eq. 38), so its error is the angle between the two lines:

    ``err = atan2(|s_b x S^b_true|, |s_b . S^b_true|)``  (deg, in [0, 90]; the acos of the normalised
    ``|s_b . S^b_true|`` without its loss of precision near 0).

The error is also split in the local level frame (ENU): the solve is turned to ENU with the *true* attitude,
``s^n = C_b^n(t) s_b`` (sign taken towards the truth), and compared in azimuth and elevation:

    ``err_az = az(s^n) - az(S^n)`` (wrapped to [-180, 180), ``az = atan2(E, N)``),
    ``err_el = el(s^n) - el(S^n)`` (``el = asin(U)``), both signed, deg.

The azimuth part is what a sun-referenced heading inherits one to one; the elevation part maps into tilt (and into
the position of a sun-elevation fix). The sky's neutral points lie on the solar meridian and bend the E-vectors
symmetrically about it, so they bias the elevation and leave the azimuth unbiased (docs/sensors.md, "Error
budget").

It does not depend on the navigation state: it measures the camera, the sky, the solve and the calibration
(mounting) alone. The comparison runs in batches (at every flush and when the summary is read), so the
recorder's per-tick cost does not change; solves arrive at the camera's frame rate (5 Hz).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from firmware_model.registry import SolarSolve

from ..world.sun import SunModel
from ..world.trajectory import Trajectory
from .formatting import csv_row_fast

__all__ = ["PSNS_COLUMNS", "SolarVsTruth", "azimuth_elevation_error", "line_angle_deg", "solar_error_stats"]

PSNS_COLUMNS = [
    "time_s", "s_b_x", "s_b_y", "s_b_z", "true_s_b_x", "true_s_b_y", "true_s_b_z", "err_deg",
    "err_az_deg", "err_el_deg", "n_used", "quality", "source", "use",
]


def solar_error_stats(err_deg: list[float] | np.ndarray) -> dict[str, float | None]:
    """Median, 95th percentile (linear interpolation, numpy's default) and maximum of the errors, deg."""
    e = np.asarray(err_deg, dtype=np.float64)
    if e.size == 0:
        return {"median": None, "p95": None, "max": None}
    return {"median": float(np.median(e)), "p95": float(np.percentile(e, 95.0)), "max": float(np.max(e))}


def line_angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    """Angle (deg, in [0, 90]) between the lines of the vectors ``a`` and ``b`` (any length, either sign):
    ``atan2(|a x b|, |a . b|)``, exact near 0 where the acos of the normalised dot product loses half the digits."""
    c = np.cross(a, b)
    return math.degrees(math.atan2(math.sqrt(float(c @ c)), abs(float(a @ b))))


def azimuth_elevation_error(s_n: np.ndarray, true_s_n: np.ndarray) -> tuple[float, float]:
    """Signed azimuth and elevation errors (deg) of the solved sun ``s_n`` (ENU, any length, either sign: turned
    towards ``true_s_n``) against the true unit sun ``true_s_n`` (ENU); azimuth ``atan2(E, N)``, wrapped to
    [-180, 180), elevation ``asin(U)`` (module docstring)."""
    v = s_n / math.sqrt(float(s_n @ s_n))
    if float(v @ true_s_n) < 0.0:
        v = -v
    d_az = math.degrees(math.atan2(v[0], v[1]) - math.atan2(true_s_n[0], true_s_n[1]))
    d_az = (d_az + 180.0) % 360.0 - 180.0
    d_el = math.degrees(math.asin(max(-1.0, min(1.0, float(v[2])))) - math.asin(max(-1.0, min(1.0,
                                                                                           float(true_s_n[2])))))
    return d_az, d_el


class SolarVsTruth:
    """Solves compared with the world's sun in the body frame (see module docstring).

    ``rows`` starts with the header line once the first solve arrived (a run without a polarization sensor
    writes no ``psns.csv``); the owner writes the rows out and clears them.
    """

    def __init__(self, trajectory: Trajectory, sun: SunModel) -> None:
        self.traj = trajectory
        self.sun = sun
        self.pending: list[SolarSolve] = []
        self.rows: list[str] = []
        self.started = False
        #: every error so far (deg), with the time and whether the filter accepted it
        self.t_s: list[float] = []
        self.err_deg: list[float] = []
        self.err_az_deg: list[float] = []
        self.err_el_deg: list[float] = []
        self.uses: dict[str, int] = {}

    def add(self, solves: list[SolarSolve]) -> None:
        """Queue ``solves`` (compared at the next :meth:`drain`)."""
        self.pending.extend(solves)

    def truth_s_b(self, t: float) -> np.ndarray:
        """``S^b_true(t)``: the unit sun vector in the body frame (x right, y forward, z up) at scenario time ``t``."""
        return self._truth(self.traj.state(t), t)[1]

    def _truth(self, st: Any, t: float) -> tuple[np.ndarray, np.ndarray]:
        """The true sun ``(S^n, S^b)`` (ENU, body) of the trajectory state ``st`` at scenario time ``t``."""
        lat, lon, h = (float(x) for x in st.pos)
        s_n = self.sun.sun_enu(t, lat, lon, h)
        s_b: np.ndarray = st.c_bn.T @ s_n
        return s_n, s_b

    def drain(self) -> None:
        """Compare the queued solves with truth (one vectorised trajectory evaluation)."""
        pend = self.pending
        if not pend:
            return
        self.pending = []
        if not self.started:
            self.rows.append(",".join(PSNS_COLUMNS) + "\r\n")
            self.started = True
        for s, st in zip(pend, self.traj.states([s.t_exposure_s for s in pend])):
            tn, tb = self._truth(st, s.t_exposure_s)
            sb = np.array(s.s_b, dtype=np.float64)
            if np.isfinite(sb).all() and float(sb @ sb) > 0.0:
                err = line_angle_deg(sb, tb)
                err_az, err_el = azimuth_elevation_error(st.c_bn @ sb, tn)
            else:  # a zero or non-finite vector
                err = err_az = err_el = math.nan
            self.t_s.append(s.t_exposure_s)
            self.err_deg.append(err)
            self.err_az_deg.append(err_az)
            self.err_el_deg.append(err_el)
            self.uses[s.use] = self.uses.get(s.use, 0) + 1
            self.rows.append(csv_row_fast((s.t_exposure_s, *s.s_b, float(tb[0]), float(tb[1]), float(tb[2]), err,
                                           err_az, err_el, s.n_used, s.quality, s.source, s.use)))

    def window(self, after_s: float, until_s: float | None) -> list[float]:
        """The errors (deg) of the solves exposed in [``after_s``, ``until_s``]."""
        self.drain()
        return [e for t, e in zip(self.t_s, self.err_deg) if t >= after_s and (until_s is None or t <= until_s)]

    def summary(self) -> dict[str, Any] | None:
        """The summary's ``psns`` section, None when nothing was solved."""
        self.drain()
        if not self.err_deg:
            return None
        return {"solves": len(self.err_deg), "uses": dict(sorted(self.uses.items())),
                "solar_vector_error_deg": solar_error_stats(self.err_deg),
                "azimuth_error_deg": solar_error_stats(np.abs(self.err_az_deg)),
                "elevation_error_deg": solar_error_stats(np.abs(self.err_el_deg))}
