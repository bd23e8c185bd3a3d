"""The federated master's fusion traced against truth (Ge et al. under the field presets; D-5.36).

``python -m studies.scripts.ge_fusion_trace SEED [--config fused] [--csv out.csv]`` runs
``benchmarks.paper_reproductions``'s ``ge`` member on the seed's stream with :meth:`FederatedFilter.feedback` wrapped
(the firmware is not changed). At every fusion (one record per ``--step`` s), before the feedback, it records each
sub-filter's common states ``x_i = [phi, eps]`` and their covariance block ``P_i``, the fused ``x_g``, ``P_g``, the
reference attitude, and the MIMU/polarization sub-filter's solar-bias states and solar-meridian axis. Each
sub-filter's attitude is the reference corrected by its own ``phi`` (what it would output alone), so its error
against truth is read without a sign convention; truth comes from the run's ``nav.csv`` (each output angle less its
error), which only this diagnostic reads. Per window (``ge_phases``'s), in deg:

* the heading error mean / RMS, heading sigma (``sqrt P_UU``; the sub-filters' as carried, with the ``1 / beta`` of the
  no-reset sharing) and heading NEES of the fused estimate (``g``), the SINS/GNSS sub-filter (``1``) and the
  MIMU/polarization sub-filter (``2``);
* their tilt errors about the sun's horizontal axes: ``u`` across the solar meridian (a tilt about it moves the sun in
  elevation) and ``a`` along the sun's azimuth (a tilt about it moves the sun across the meridian, as a heading error
  does), in the states' sign (estimate less truth);
* how the fused heading differs from sub-filter 2's: ``x_g - x_2 = W_1 (x_1 - x_2)`` with ``W_1 = P_g P_1^-1`` (the
  truth cancels in ``x_1 - x_2``), split by the component of ``x_1 - x_2`` it comes through;
* the solar-bias states along ``u`` and ``a``.

``--set KEY=JSON`` overrides a dotted scenario key (attribution runs, e.g. D-5.36's
``firmware.alignment.misalignment_deg=[-0.9,0.6,-0.7]``).
``python -m studies.scripts.ge_fusion_trace --seeds 1-10`` traces
the fused member of each seed and prints one line per seed and phase (rest 20-200 and 200-400 s, motion 400-705 s):
:func:`seed_table`. D-5.36 quotes both.
"""

from __future__ import annotations

import argparse
import bisect
import csv
import math
import statistics
import sys
from typing import Any

import numpy as np

from benchmarks.paper_reproductions import GE_CONFIGS, _f, ge_overrides, parse_overrides, parse_seeds, run_nav
from firmware_model.attitude import a2mat, q2att, q2mat, qmul, qnormalize, rv2q, yaw_from_heading
from firmware_model.kf import IDX_ATT, PHI_U
from firmware_model.variants import federated as fed
from studies.scripts.ge_phases import WINDOWS

RAD = 180.0 / math.pi
#: names of the common states ``[phi_E, phi_N, phi_U, eps_x, eps_y, eps_z]``
COMMON = ("lvlE", "lvlN", "hdg", "epsx", "epsy", "epsz")


def _heading_deg(q: Any) -> float:
    """Heading (deg, clockwise from North) of ``q_b^n``."""
    return (-q2att(np.asarray(q, dtype=np.float64))[2] * RAD) % 360.0


def _wrap(d: float) -> float:
    return (d + 180.0) % 360.0 - 180.0


def trace(seed: int, config: str = "fused", step_s: float = 1.0,
          overrides: dict[str, Any] | None = None) -> list[dict[str, Any]]:
    """One record per ``step_s`` of fusion: the sub-filters, the fused states and the truth (module docstring)."""
    recs: list[dict[str, Any]] = []
    orig = fed.FederatedFilter.feedback
    last = [-1e9]

    def feedback(self: Any, nav: Any) -> None:
        t = float(nav.t)
        if t - last[0] >= step_s - 1e-6:
            last[0] = t
            act = self._active()
            parts = []
            if fed.SUB_SINS_GNSS in act:
                parts.append((self.x1[fed.C1].astype(float), self.P1[np.ix_(fed.C1, fed.C1)].astype(float)))
            if fed.SUB_POL_MIMU in act:
                parts.append((self.x2[fed.C2].astype(float), self.P2[np.ix_(fed.C2, fed.C2)].astype(float)))
            q = np.asarray(nav.q, dtype=np.float64)
            r: dict[str, Any] = {"t": t, "active": tuple(act), "q_ref": q.copy(),
                                 "x1": self.x1[fed.C1].astype(float).copy(),
                                 "P1": self.P1[np.ix_(fed.C1, fed.C1)].astype(float).copy(),
                                 "x2": self.x2[fed.C2].astype(float).copy(),
                                 "P2": self.P2[np.ix_(fed.C2, fed.C2)].astype(float).copy()}
            if parts:
                r["xg"], r["Pg"] = (np.asarray(v, dtype=float) for v in fed.fuse_common_states(parts))
            sn = self.sun_states
            if sn is not None and sn.axis_n is not None:
                r["u"] = np.asarray(sn.axis_n, dtype=float).copy()
            if sn is not None:
                r["mu"] = self.x2[sn.i:sn.i + 3].astype(float).copy()
                r["Pmu"] = self.P2[sn.i:sn.i + 3, sn.i:sn.i + 3].astype(float).copy()
            recs.append(r)
        orig(self, nav)

    fed.FederatedFilter.feedback = feedback  # type: ignore[method-assign]
    try:
        over = ge_overrides(GE_CONFIGS[config], overrides)
        _s, nav_rows, _ev = run_nav("federated_paper_comparison", seed, over)
    finally:
        fed.FederatedFilter.feedback = orig  # type: ignore[method-assign]
    # the truth's attitude from the output (each angle less its error), interpolated to the fusion times
    tt: list[float] = []
    tr: list[tuple[float, float, float]] = []
    for row in nav_rows:
        e = _f(row, "err_heading_deg")
        if e is not None:
            tt.append(float(row["time_s"]))
            tr.append((float(row["heading_deg"]) - e, float(row["pitch_deg"]) - float(row["err_pitch_deg"]),
                       float(row["roll_deg"]) - float(row["err_roll_deg"])))
    out = []
    for r in recs:
        i = bisect.bisect_left(tt, r["t"])
        if not tt or i >= len(tt) or i == 0:
            continue
        a, b = tt[i - 1], tt[i]
        w = (r["t"] - a) / (b - a) if b > a else 0.0
        hdg, pitch, roll = (x0 + w * _wrap(x1 - x0) for x0, x1 in zip(tr[i - 1], tr[i]))
        c_true = a2mat(pitch * math.pi / 180.0, roll * math.pi / 180.0, yaw_from_heading(hdg * math.pi / 180.0))
        q = r["q_ref"]
        r["truth_hdg"] = hdg
        for k in ("x1", "x2", "xg"):
            if k in r:
                qk = qnormalize(qmul(rv2q(r[k][IDX_ATT]), q))
                r["e" + k[1:]] = _wrap(_heading_deg(qk) - hdg)
                # the estimate's attitude error in the states' convention (estimate = R(x) C_ref, so the error is
                # the rotation vector of C_est C_true^T, i.e. x - x_true), rad
                m = q2mat(qk) @ c_true.T
                r["a" + k[1:]] = 0.5 * np.array([m[2, 1] - m[1, 2], m[0, 2] - m[2, 0], m[1, 0] - m[0, 1]])
        out.append(r)
    return out


def _mean(xs: list[float]) -> float:
    return statistics.fmean(xs) if xs else math.nan


def _rms(xs: list[float]) -> float:
    return math.sqrt(_mean([x * x for x in xs])) if xs else math.nan


def _frame(r: dict[str, Any]) -> tuple[Any, Any]:
    """The horizontal axes of the sun: ``u`` across the solar meridian (a tilt about it moves the sun in elevation)
    and ``a = z x u`` along the sun's azimuth (a tilt about it moves the sun across the meridian, as a heading
    error does: the sun's across row sees ``cos(el) psi - sin(el) tilt_a``)."""
    u = r.get("u", np.array([1.0, 0.0, 0.0]))
    return u, np.cross([0.0, 0.0, 1.0], u)


def heading_split(r: dict[str, Any]) -> Any:
    """The fused heading less sub-filter 2's (deg, the heading's sign: heading = -yaw, so ``-(x_g - x_2)_U``) as six
    parts that add up to it: ``x_g - x_2 = W_1 (x_1 - x_2)``, ``W_1 = P_g P_1^-1`` (the truth cancels in
    ``x_1 - x_2``), with ``x_1 - x_2`` expressed in (tilt about ``u``, tilt about ``a``, heading, gyro bias x, y, z)."""
    u, a = _frame(r)
    T = np.eye(6)
    T[0, :3], T[1, :3] = u, a
    M = r["Pg"] @ np.linalg.inv(r["P1"]) @ np.linalg.inv(T)
    return -M[PHI_U, :] * (T @ (r["x1"] - r["x2"])) * RAD


def summarise(recs: list[dict[str, Any]]) -> list[str]:
    """The per-window table of the module docstring."""
    lines = []
    for lo, hi in WINDOWS:
        w = [r for r in recs if lo <= r["t"] < hi and "xg" in r]
        if not w:
            continue
        cells = []
        for k, P in (("g", "Pg"), ("1", "P1"), ("2", "P2")):
            e = [r["e" + k] for r in w]
            s = [math.sqrt(r[P][PHI_U, PHI_U]) * RAD for r in w]
            nees = _mean([r["e" + k] ** 2 / (r[P][PHI_U, PHI_U] * RAD * RAD) for r in w])
            cells.append(f"{k}: {_mean(e):+.3f}/{_rms(e):.3f} s {_mean(s):.3f} nees {nees:.2f}")
        lines.append(f"{lo:5.0f}-{hi:5.0f} s  heading mean/rms, sigma, NEES  " + "  ".join(cells))
        cells = []
        for k, P in (("g", "Pg"), ("1", "P1"), ("2", "P2")):
            fu, fa, su, sa = [], [], [], []
            for r in w:
                u, a = _frame(r)
                e, p3 = r["a" + k], r[P][:3, :3]
                fu.append(float(e @ u) * RAD)
                fa.append(float(e @ a) * RAD)
                su.append(math.sqrt(float(u @ p3 @ u)) * RAD)
                sa.append(math.sqrt(float(a @ p3 @ a)) * RAD)
            cells.append(f"{k}: u {_mean(fu):+.3f} s {_mean(su):.3f}, a {_mean(fa):+.3f} s {_mean(sa):.3f}")
        lines.append("              tilt error (states' sign) and sigma  " + "  ".join(cells))
        both = [r for r in w if len(r["active"]) == 2]
        if both:
            parts = np.mean([heading_split(r) for r in both], axis=0)
            lines.append("              fused - sub-filter 2 heading through x1 - x2 in  "
                         + " ".join(f"{n} {v:+.4f}" for n, v in zip(("tilt-u", "tilt-a", "hdg", "epsx", "epsy",
                                                                     "epsz"), parts))
                         + f"  sum {parts.sum():+.4f}")
        if "mu" in w[0]:
            mu = [(float(r["mu"] @ _frame(r)[0]) * RAD, float(r["mu"] @ _frame(r)[1]) * RAD) for r in w]
            lines.append(f"              solar bias along u (elevation) {_mean([m[0] for m in mu]):+.3f}, "
                         f"along a {_mean([m[1] for m in mu]):+.3f} deg")
    return lines


#: the phases of the per-seed table: at rest (20-200, 200-400 s) and the motion (400-705 s)
PHASES = ((20.0, 200.0), (200.0, 400.0), (400.0, 705.1))


def seed_table(runs: dict[int, list[dict[str, Any]]]) -> list[str]:
    """Per seed and phase (deg): the heading error mean of the fused estimate (g) and of the sub-filters (2, 1), the
    tilt error about ``a`` (g, 2), ``heading - tilt_a`` (g, 2: what the sun's across row fixes, ``tan(el)`` ~ 1
    here), the fused heading NEES, the pull of sub-filter 1's heading on the fused one
    (``W_1[U, U] (x_1 - x_2)_U``) and ``e_g^2 - e_2^2`` (deg^2, the phase's mean)."""
    lines = ["seed phase     | heading err g / 2 / 1 | tilt-a err g / 2 | hdg - tilt-a g / 2 | NEES hdg g | "
             "pull of 1's hdg | e_g^2 - e_2^2"]
    for seed, recs in sorted(runs.items()):
        for lo, hi in PHASES:
            w = [r for r in recs if lo <= r["t"] < hi and len(r["active"]) == 2 and "u" in r]
            if not w:
                continue
            hg, h2, h1 = (_mean([-r[k][PHI_U] * RAD for r in w]) for k in ("ag", "a2", "a1"))
            tg, t2 = (_mean([float(r[k] @ _frame(r)[1]) * RAD for r in w]) for k in ("ag", "a2"))
            nees = _mean([r["ag"][PHI_U] ** 2 / r["Pg"][PHI_U, PHI_U] for r in w])
            pull = _mean([-(r["Pg"] @ np.linalg.inv(r["P1"]))[PHI_U, PHI_U] * (r["x1"][PHI_U] - r["x2"][PHI_U]) * RAD
                          for r in w])
            d2 = _mean([(r["ag"][PHI_U] ** 2 - r["a2"][PHI_U] ** 2) * RAD * RAD for r in w])
            lines.append(f"{seed:4d} {lo:3.0f}-{hi:3.0f} | {hg:+.3f} {h2:+.3f} {h1:+.3f} | {tg:+.3f} {t2:+.3f} | "
                         f"{hg - tg:+.3f} {h2 - t2:+.3f} | {nees:.2f} | {pull:+.4f} | {d2:+.4f}")
    return lines


def write_csv(recs: list[dict[str, Any]], path: str) -> None:
    """Every record as a row (deg): errors, sigmas, the common states of both sub-filters and the fused ones."""
    with open(path, "w", newline="") as f:
        wr = csv.writer(f)
        head = ["t", "active", "truth_hdg", "eg", "e1", "e2"]
        for k in ("x1", "x2", "xg"):
            head += [f"{k}_{n}" for n in COMMON]
        for k in ("P1", "P2", "Pg"):
            head += [f"sig{k[1]}_{n}" for n in COMMON]
        head += ["mu_e", "mu_n", "mu_u"]
        wr.writerow(head)
        for r in recs:
            row = [r["t"], "+".join(r["active"]), r["truth_hdg"], r.get("eg"), r.get("e1"), r.get("e2")]
            for k in ("x1", "x2", "xg"):
                row += list(r[k] * RAD) if k in r else [None] * 6
            for k in ("P1", "P2", "Pg"):
                row += list(np.sqrt(np.diag(r[k])) * RAD) if k in r else [None] * 6
            row += list(r["mu"] * RAD) if "mu" in r else [None] * 3
            wr.writerow(row)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("seed", nargs="?", type=int, default=None, help="one seed: the per-window detail")
    ap.add_argument("--seeds", default=None, help="A-B or A,B,...: the per-seed table of the fused member instead")
    ap.add_argument("--config", default="fused", choices=sorted(GE_CONFIGS))
    ap.add_argument("--step", type=float, default=1.0, help="seconds between records (default 1)")
    ap.add_argument("--csv", default=None, help="one seed: also write every record to this file")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=JSON",
                    help="a dotted scenario override (attribution runs), value as JSON")
    a = ap.parse_args()
    over = parse_overrides(a.set)
    if a.seeds:
        runs = {}
        for seed in parse_seeds(a.seeds):
            runs[seed] = trace(seed, "fused", a.step, over)
            print(f"seed {seed} traced", file=sys.stderr, flush=True)
        print("\n".join(seed_table(runs)))
        return
    if a.seed is None:
        ap.error("a seed or --seeds")
    recs = trace(a.seed, a.config, a.step, over)
    print("\n".join(summarise(recs)))
    if a.csv:
        write_csv(recs, a.csv)


if __name__ == "__main__":
    main()
