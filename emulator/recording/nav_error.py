"""The navigation output against truth: per frame, the error of attitude, heading, position and velocity.

:class:`NavVsTruth` takes navigation frames (with their arrival time) in batches, evaluates the trajectory at
their times of validity in one vectorised call (bit for bit the per-frame values), and keeps the rows of
``nav.csv`` (the frame, decoded, and its errors) and ``truth.csv``, the running RMS / max of each error metric
(:class:`ErrorStats`) and the error and mode series that expectations and reports read.

The rows are written by :meth:`NavVsTruth._write_rows_fast`, which keeps the sigma cells of the previous frame;
:meth:`NavVsTruth._write_rows` is its reference (``NavVsTruth(..., fast_paths=False)``), and
:func:`nav_vs_truth_rows` / :func:`nav_vs_truth_rows_fast` the pair that ``tests/emulator/fast_path_cases.py``
compares.
"""

from __future__ import annotations

import math
from array import array
from dataclasses import dataclass
from operator import mul as _mul
from typing import Any

from firmware_model import earth
from protocols.constants import DEG
from protocols.host import NavMode, NavSolution

from ..world.trajectory import Trajectory
from .formatting import csv_row, csv_row_fast, reprs_are_cells

__all__ = [
    "ERROR_METRICS", "NAV_COLUMNS", "TRUTH_COLUMNS", "ErrorStats", "NavVsTruth", "nav_vs_truth_rows",
    "nav_vs_truth_rows_fast",
]


NAV_COLUMNS = [
    "time_s", "lat_deg", "lon_deg", "height_m", "vel_e_mps", "vel_n_mps", "vel_u_mps",
    "roll_deg", "pitch_deg", "heading_deg",
    "sig_att_e_deg", "sig_att_n_deg", "sig_att_u_deg", "sig_vel_e_mps", "sig_vel_n_mps", "sig_vel_u_mps",
    "sig_pos_n_m", "sig_pos_e_m", "sig_pos_u_m",
    "mode", "gnss_status", "psns_status", "cpu_load_pct", "deadline_misses", "arrival_s",
    "err_att_deg", "err_roll_deg", "err_pitch_deg", "err_heading_deg",
    "err_pos_e_m", "err_pos_n_m", "err_pos_u_m", "err_pos_m",
    "err_vel_e_mps", "err_vel_n_mps", "err_vel_u_mps", "err_vel_mps",
]
TRUTH_COLUMNS = [
    "time_s", "lat_deg", "lon_deg", "height_m", "vel_e_mps", "vel_n_mps", "vel_u_mps",
    "roll_deg", "pitch_deg", "heading_deg",
]
#: the error metrics, in the order of the error series' columns after the time
ERROR_METRICS = ("attitude_deg", "heading_deg", "position_m", "velocity_mps")
#: the phases of a navigating frame, as the summary's ``nav_error_by_phase`` names them
NAV_PHASES = ("fine_alignment", "navigating")
_SERIES_COLUMN = {m: 1 + i for i, m in enumerate(ERROR_METRICS)}
#: the error cells of a frame that is not navigating (empty)
_NO_ERRORS = "," * 11 + "\r\n"
#: the mode bits tested per frame, as plain ints (``int & IntFlag`` builds an enum member, ~1 us)
_NAVIGATING = int(NavMode.NAVIGATING)
_ALIGNING = int(NavMode.ALIGNING)


@dataclass
class ErrorStats:
    """Running RMS / max of one error metric."""

    n: int = 0
    sum_sq: float = 0.0
    max: float = 0.0

    def add(self, v: float) -> None:
        self.n += 1
        self.sum_sq += v * v
        a = abs(v)
        if self.max == self.max and not a <= self.max:  # a NaN sample makes the max NaN (max() would drop it)
            self.max = a

    def merged(self, other: ErrorStats) -> ErrorStats:
        """The statistics of both sample sets together (a NaN max in either stays NaN)."""
        m = math.nan if math.isnan(self.max) or math.isnan(other.max) else max(self.max, other.max)
        return ErrorStats(self.n + other.n, self.sum_sq + other.sum_sq, m)

    def as_dict(self) -> dict[str, float | None]:
        if not self.n:
            return {"rms": None, "max": None}
        return {"rms": math.sqrt(self.sum_sq / self.n), "max": self.max}


class NavVsTruth:
    """Navigation frames compared with ``trajectory`` (see module docstring).

    ``nav_rows`` and ``truth_rows`` start with their header line; the owner writes them out and clears them.
    """

    def __init__(self, trajectory: Trajectory, fast_paths: bool = True) -> None:
        self.traj = trajectory
        self.nav_rows: list[str] = [",".join(NAV_COLUMNS) + "\r\n"]
        self.truth_rows: list[str] = [",".join(TRUTH_COLUMNS) + "\r\n"]
        #: the error statistics by phase: fine alignment (ALIGNING and NAVIGATING: the strapdown runs while the
        #: filter still calibrates its heading and biases) and navigating proper (NAVIGATING alone)
        self.errors_by_phase = {phase: {k: ErrorStats() for k in ERROR_METRICS} for phase in NAV_PHASES}
        #: flat rows of (t, attitude, heading, position, velocity) errors, 40 bytes per navigating frame
        self.error_series: array[float] = array("d")
        #: flat rows of (time of validity, mode bits) of every frame, 16 bytes per frame
        self.mode_series: array[float] = array("d")
        #: how the rows are written: :meth:`_write_rows_fast`, or the reference :meth:`_write_rows`
        #: (``fast_paths=False``; the same text, ``tests/emulator/fast_path_cases.py``)
        self._write = self._write_rows_fast if fast_paths else self._write_rows
        #: the last sigma cells written (:meth:`_write_rows_fast`): the floats and their text
        self._sigma: tuple[float, ...] | None = None
        self._sigma_types: tuple[type, ...] = ()
        self._sigma_text = ""
        #: frames with a non-finite value (time, position, velocity or attitude: an outside DSP may send +-inf or
        #: NaN) or a time the trajectory cannot be evaluated at: counted here, never raised, and left out of the
        #: error statistics; their rows are written (with empty cells for the non-finite values) when their time is
        #: finite and the truth there could be evaluated, otherwise not at all
        self.nonfinite_frames = 0

    def add(self, frames: list[tuple[float, NavSolution]]) -> None:
        """Compare ``frames`` ((arrival time, frame) pairs) with truth: one vectorised trajectory evaluation."""
        times = [n.time_s for _t, n in frames]
        if not all(map(math.isfinite, times)):
            kept = [(t, n) for t, n in frames if math.isfinite(n.time_s)]
            self.nonfinite_frames += len(frames) - len(kept)
            frames = kept
            times = [n.time_s for _t, n in frames]
        try:
            states = self.traj.states(times)
        except (ArithmeticError, ValueError):  # a finite time the trajectory cannot be evaluated at (1e300 s)
            for t_arrival, n in frames:
                try:
                    (st,) = self.traj.states([n.time_s])
                except (ArithmeticError, ValueError):
                    self.nonfinite_frames += 1
                    continue
                self._compare(t_arrival, n, st)
            return
        for (t_arrival, n), st in zip(frames, states):
            self._compare(t_arrival, n, st)

    def _compare(self, t_arrival: float, n: NavSolution, st: Any) -> None:
        """One frame against its truth ``st``: the error statistics and series, and its rows (:attr:`_write`).

        The rows' cells, in ``NAV_COLUMNS`` / ``TRUTH_COLUMNS`` order: the truth's; the frame's, as three runs
        (up to the heading, the sigmas, from the mode to the arrival time); the errors (None: not navigating).
        """
        lat, lon, h = st.pos.tolist()
        ve, vn, vu = st.v_enu.tolist()
        truth = (n.time_s, lat / DEG, lon / DEG, h, ve, vn, vu, st.roll / DEG, st.pitch / DEG, st.heading / DEG)
        self.mode_series.extend((n.time_s, n.mode))
        errs: tuple[float, ...] | None = None
        if n.mode & _NAVIGATING and not _frame_finite(n):
            self.nonfinite_frames += 1  # no error of a non-finite value: counted, the row shows the frame
        elif n.mode & _NAVIGATING:
            c_nav = _c_bn(n.pitch_deg * DEG, n.roll_deg * DEG, -n.heading_deg * DEG)
            # trace(C_nav C_true^T) = sum of the element-wise product
            tr = sum(map(_mul, c_nav, st.c_bn.ravel().tolist()))
            att = math.degrees(math.acos(max(-1.0, min(1.0, (tr - 1.0) / 2.0))))
            e_roll = _wrap180(n.roll_deg - st.roll / DEG)
            e_pitch = n.pitch_deg - st.pitch / DEG
            e_hdg = _wrap180(n.heading_deg - st.heading / DEG)
            rm, rn = earth.radii(lat)
            e_n = (n.lat_deg * DEG - lat) * (rm + h)
            e_e = (n.lon_deg * DEG - lon) * (rn + h) * math.cos(lat)
            e_u = n.height_m - h
            e_pos = math.sqrt(e_e * e_e + e_n * e_n + e_u * e_u)
            v = n.vel_enu_mps
            ev = (v[0] - ve, v[1] - vn, v[2] - vu)
            e_vel = math.sqrt(ev[0] * ev[0] + ev[1] * ev[1] + ev[2] * ev[2])
            err = self.errors_by_phase[NAV_PHASES[0 if n.mode & _ALIGNING else 1]]
            err["attitude_deg"].add(att)
            err["heading_deg"].add(e_hdg)
            err["position_m"].add(e_pos)
            err["velocity_mps"].add(e_vel)
            self.error_series.extend((n.time_s, att, e_hdg, e_pos, e_vel))
            errs = (att, e_roll, e_pitch, e_hdg, e_e, e_n, e_u, e_pos, *ev, e_vel)
        self._write(
            truth,
            (n.time_s, n.lat_deg, n.lon_deg, n.height_m, *n.vel_enu_mps, n.roll_deg, n.pitch_deg, n.heading_deg),
            n.sigma,
            (n.mode, n.gnss_status, n.psns_status, n.cpu_load_pct, n.deadline_misses, t_arrival),
            errs,
        )

    def _write_rows(self, truth: tuple[Any, ...], head: tuple[Any, ...], sigma: tuple[Any, ...],
                    tail: tuple[Any, ...], errs: tuple[Any, ...] | None) -> None:
        """The reference: each row by :func:`csv_row_fast`, the nav row's frame cells and error cells apart."""
        self.truth_rows.append(csv_row_fast(truth))
        self.nav_rows.append(_nav_row(head, sigma, tail, errs))

    def _write_rows_fast(self, truth: tuple[Any, ...], head: tuple[Any, ...], sigma: tuple[Any, ...],
                         tail: tuple[Any, ...], errs: tuple[Any, ...] | None) -> None:
        """:meth:`_write_rows`' text with fewer joins, and the sigma cells of the previous frame kept.

        The sigmas change at the filter's covariance steps, not every frame (about 4 frames in 5 at 100 Hz repeat
        them). Their text is reused when they equal the previous frame's (``==``) with the same types and no zero
        among them: equal values of one type have the same ``repr``, but for the sign of a float zero (NaN equals
        nothing). A line whose ``repr`` s are not its cells (NaN, infinities, types other than float, int and bool:
        :func:`reprs_are_cells`) is written by the reference.
        """
        line = ",".join(map(repr, truth))
        self.truth_rows.append(line + "\r\n" if reprs_are_cells(line) else csv_row(truth))
        types = tuple(map(type, sigma))
        if sigma == self._sigma and types == self._sigma_types:
            sigma_text = self._sigma_text
        else:
            sigma_text = ",".join(map(repr, sigma))
            if 0.0 not in sigma:
                self._sigma, self._sigma_types, self._sigma_text = sigma, types, sigma_text
        line = ",".join(map(repr, head)) + "," + sigma_text + "," + ",".join(map(repr, tail if errs is None
                                                                                 else (*tail, *errs)))
        if not reprs_are_cells(line):
            self.nav_rows.append(_nav_row(head, sigma, tail, errs))
        else:
            self.nav_rows.append(line + "," + _NO_ERRORS if errs is None else line + "\r\n")

    @property
    def errors(self) -> dict[str, ErrorStats]:
        """Error statistics over every navigating frame (both phases), per metric."""
        fine, nav = (self.errors_by_phase[ph] for ph in NAV_PHASES)
        return {k: fine[k].merged(nav[k]) for k in ERROR_METRICS}

    def error_window(self, metric: str, after_s: float, until_s: float | None) -> ErrorStats:
        """RMS / max of ``metric`` over the navigating frames valid in [``after_s``, ``until_s``]."""
        idx = _SERIES_COLUMN[metric]
        es = ErrorStats()
        ser = self.error_series
        for k in range(0, len(ser), 5):
            t = ser[k]
            if t >= after_s and (until_s is None or t <= until_s):
                es.add(ser[k + idx])
        return es


def nav_vs_truth_rows(trajectory: Trajectory, frames: list[tuple[float, NavSolution]]) -> tuple[list[str], list[str]]:
    """The ``nav.csv`` and ``truth.csv`` rows (headers first) of ``frames`` ((arrival time, frame) pairs) against
    ``trajectory``, by the reference writer (``NavVsTruth(fast_paths=False)``)."""
    cmp = NavVsTruth(trajectory, fast_paths=False)
    cmp.add(frames)
    return cmp.nav_rows, cmp.truth_rows


def nav_vs_truth_rows_fast(trajectory: Trajectory,
                           frames: list[tuple[float, NavSolution]]) -> tuple[list[str], list[str]]:
    """:func:`nav_vs_truth_rows` by the recorder's writer (:meth:`NavVsTruth._write_rows_fast`)."""
    cmp = NavVsTruth(trajectory)
    cmp.add(frames)
    return cmp.nav_rows, cmp.truth_rows


def _nav_row(head: tuple[Any, ...], sigma: tuple[Any, ...], tail: tuple[Any, ...],
             errs: tuple[Any, ...] | None) -> str:
    """The reference nav row: the frame's cells and the error cells (empty when ``errs`` is None) by
    :func:`csv_row_fast` apart."""
    return csv_row_fast((*head, *sigma, *tail))[:-2] + "," + (_NO_ERRORS if errs is None else csv_row_fast(errs))


def _frame_finite(n: NavSolution) -> bool:
    """True when every compared value of ``n`` (position, velocity, attitude) is finite."""
    v = n.vel_enu_mps
    return math.isfinite(n.lat_deg + n.lon_deg + n.height_m + v[0] + v[1] + v[2] + n.roll_deg + n.pitch_deg
                         + n.heading_deg)


def _wrap180(x: float) -> float:
    return (x + 180.0) % 360.0 - 180.0


def _c_bn(pitch: float, roll: float, yaw: float) -> list[float]:
    """``C_b^n`` from Euler angles (rad; yaw counter-clockwise from North), row-major 9 floats.

    The same matrix as :func:`firmware_model.attitude.a2mat` (``docs/reference/algorithms.md`` section 0), in
    plain floats for the per-frame error evaluation.
    """
    sp, cp = math.sin(pitch), math.cos(pitch)
    sr, cr = math.sin(roll), math.cos(roll)
    sy, cy = math.sin(yaw), math.cos(yaw)
    return [cr * cy - sp * sr * sy, -cp * sy, sr * cy + sp * cr * sy,
            cr * sy + sp * sr * cy, cp * cy, sr * sy - sp * cr * cy,
            -cp * sr, sp, cp * cr]
