"""Filter consistency over a campaign: NEES per state group and NIS per measurement type, with chi-square bounds.

A filter is *consistent* when its errors are as large as its covariance says (Bar-Shalom, Li & Kirubarajan,
*Estimation with Applications to Tracking and Navigation*, 2001, section 5.4.2). Over ``N`` independent runs:

``NEES`` (normalised estimation error squared) of a state group with ``n`` components at time ``k``::

    eps_k = sum_i (e_i / sigma_i)^2          (error e against truth, sigma the filter's reported 1 sigma)

``N * mean_N(eps_k)`` is chi-square with ``N n`` degrees of freedom, so the average NEES lies inside the
two-sided ``1 - alpha`` interval ``[chi2.ppf(alpha/2, N n) / N, chi2.ppf(1 - alpha/2, N n) / N]`` for a consistent
filter (Bar-Shalom Eq. 5.4.2-8). The host receives only the sigmas of the navigation errors (NAV_SOLUTION, the
diagonal of P), so ``eps`` here is the diagonal form: it equals the full-covariance NEES when the group's errors
are uncorrelated and is a close proxy otherwise (its expectation is still ``n``).

``NIS`` (normalised innovation squared) of a measurement type: the firmware accumulates ``nu^2 / s`` of every
scalar row it processes (:attr:`firmware_model.filters.interface.NavFilter.innovation_stats`, in the run summary under
``firmware.innovation``); a row's NIS is chi-square with 1 dof, so the average over ``M`` rows of all runs lies
inside ``[chi2.ppf(alpha/2, M) / M, chi2.ppf(1 - alpha/2, M) / M]``. ``rows`` counts degrees of freedom: a solar
vector fix is three scalar rows carrying two (its residual has no first-order part along the sun), counted as 2 rows
with its NIS across the sun (:func:`firmware_model.filters.solar.solar_fix_nis`, D-5.32). Sequential rows of one fix
are not independent of the previous fixes when the GNSS error is correlated in time; the bound is then optimistic,
which is said in the table.

State groups (the names a ``consistency:`` expectation may use, :data:`STATE_GROUPS`): ``attitude`` (phi E, N, U,
from the computed against the true ``C_b^n``), ``heading`` (the heading error against the filter's heading sigma),
``velocity`` (E, N, U), ``position``
(E, N, U), ``horizontal_position`` (E, N). The biases have no truth in ``truth.csv``; they are not a group.

Per member (:func:`member_consistency`, on the worker that ran it, before ``nav.csv`` is deleted): the group NEES
sampled once per second of navigation after ``after_s``, and the share of those samples whose heading error lies
inside the reported 3 sigma. Over the campaign (:func:`campaign_consistency`): the average NEES per group and per
sample time, its time mean, the share of sample times inside the bounds, and pass/fail.
"""

from __future__ import annotations

import csv
import math
from pathlib import Path
from typing import Any

import numpy as np

from protocols.constants import DEG

from ...scenario.consistency_schema import DEFAULT_GROUPS, MEASUREMENT_TYPES, STATE_GROUPS, chi2_bounds, min_runs

__all__ = [
    "MEASUREMENT_TYPES",
    "STATE_GROUPS",
    "campaign_consistency",
    "chi2_bounds",
    "member_consistency",
    "min_runs",
]


def _rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


def _cbn(roll_deg: float, pitch_deg: float, heading_deg: float) -> np.ndarray:
    """``C_b^n`` (ENU) from roll, pitch and heading (deg, heading clockwise from North), firmware convention."""
    from firmware_model.attitude import a2mat, yaw_from_heading

    return np.asarray(a2mat(pitch_deg * DEG, roll_deg * DEG, yaw_from_heading(heading_deg * DEG)), dtype=np.float64)


def member_consistency(run_dir: Path, summary: dict[str, Any], after_s: float = 0.0, step_s: float = 1.0
                       ) -> dict[str, Any]:
    """One member's NEES samples and innovation statistics (see module docstring).

    Returns ``{"t": [...], "nees": {group: [...]}, "heading_in_3sigma": share or None, "samples": n,
    "zero_sigma": n, "heading_err_mean_deg": mean signed heading error (deg) or None, "heading_sigma_mean_deg": the
    filter's mean heading sigma (deg), "innovation": summary["firmware"]["innovation"]}``. The heading group's NEES is
    the wrapped heading error (estimate minus truth) over the filter's heading sigma, squared."""
    nav = _rows(run_dir / "nav.csv")
    truth = _rows(run_dir / "truth.csv")
    out_t: list[float] = []
    nees: dict[str, list[float]] = {g: [] for g in STATE_GROUPS}
    head_err: list[float] = []
    head_sig: list[float] = []
    inside = total = zero = 0
    next_t = -math.inf
    for n, tr in zip(nav, truth, strict=False):
        if not n.get("err_att_deg"):  # not navigating
            continue
        t = float(n["time_s"])
        if t < after_s:
            continue
        sig_att = np.array([float(n["sig_att_e_deg"]), float(n["sig_att_n_deg"]), float(n["sig_att_u_deg"])]) * DEG
        c_comp = _cbn(float(n["roll_deg"]), float(n["pitch_deg"]), float(n["heading_deg"]))
        c_true = _cbn(float(tr["roll_deg"]), float(tr["pitch_deg"]), float(tr["heading_deg"]))
        a = c_comp @ c_true.T  # = I - [phi x]
        phi = np.array([a[1, 2] - a[2, 1], a[2, 0] - a[0, 2], a[0, 1] - a[1, 0]]) * 0.5
        # the heading error itself (estimate minus truth, wrapped), against the filter's heading sigma (its phi U
        # variance: the heading variance of a level box, the NAV frame's sigma of heading)
        dh = ((float(n["heading_deg"]) - float(tr["heading_deg"]) + 180.0) % 360.0 - 180.0) * DEG
        if sig_att[2] > 0.0:
            total += 1
            inside += abs(dh) <= 3.0 * sig_att[2]
        if t < next_t:
            continue
        sig_vel = np.array([float(n["sig_vel_e_mps"]), float(n["sig_vel_n_mps"]), float(n["sig_vel_u_mps"])])
        sig_pos = np.array([float(n["sig_pos_e_m"]), float(n["sig_pos_n_m"]), float(n["sig_pos_u_m"])])
        err_vel = np.array([float(n["err_vel_e_mps"]), float(n["err_vel_n_mps"]), float(n["err_vel_u_mps"])])
        err_pos = np.array([float(n["err_pos_e_m"]), float(n["err_pos_n_m"]), float(n["err_pos_u_m"])])
        if not (np.all(sig_att > 0) and np.all(sig_vel > 0) and np.all(sig_pos > 0)):
            zero += 1  # a sigma below the frame's resolution: no NEES sample
            continue
        next_t = t + step_s - 1e-6  # (float times of a 1 s grid)
        out_t.append(t)
        za, zv, zp = phi / sig_att, err_vel / sig_vel, err_pos / sig_pos
        nees["attitude"].append(float(za @ za))
        nees["heading"].append(float((dh / sig_att[2]) ** 2))
        head_err.append(dh / DEG)
        head_sig.append(float(sig_att[2]) / DEG)
        nees["velocity"].append(float(zv @ zv))
        nees["position"].append(float(zp @ zp))
        nees["horizontal_position"].append(float(zp[:2] @ zp[:2]))
    return {"t": out_t, "nees": nees, "heading_in_3sigma": inside / total if total else None, "samples": len(out_t),
            "zero_sigma": zero, "heading_err_mean_deg": float(np.mean(head_err)) if head_err else None,
            "heading_sigma_mean_deg": float(np.mean(head_sig)) if head_sig else None,
            "innovation": summary.get("firmware", {}).get("innovation", {})}


def _status(passed: bool | None) -> str:
    return "not applied" if passed is None else "pass" if passed else "FAIL"


def campaign_consistency(members: list[dict[str, Any]], confidence: float = 0.95,
                         groups: list[str] | None = None, measurements: list[str] | None = None,
                         upper_only: list[str] | None = None) -> dict[str, Any]:
    """Average NEES per group and NIS per measurement type over the members (``member_consistency`` results).

    Every state group and measurement type is evaluated and shown; only the *asked* ones (``groups``, default
    :data:`~emulator.scenario.consistency_schema.DEFAULT_GROUPS`; ``measurements``, default none) decide
    ``passed``: the others carry ``"asked": False`` and are informative (issue 38). Each entry's ``status`` is
    ``pass``, ``FAIL`` or ``not applied`` (no samples / no rows: never counted as a pass; an asked check that was
    not applied fails the campaign, ``not_applied`` lists it). A group in ``upper_only`` passes whenever its average
    NEES is under the upper bound (not overconfident); below the lower bound it is marked ``conservative``.

    Sample times are aligned by their index (members of one scenario navigate on the same schedule); a group passes
    when its time-averaged NEES lies inside the two-sided bounds for the number of runs. Also reported: the share of
    sample times whose N-run average lies inside the bounds (about ``confidence`` for a consistent filter)."""
    asked_g = list(groups) if groups else list(DEFAULT_GROUPS)
    asked_m = list(measurements or [])
    members = [m for m in members if m and m.get("samples")]
    runs = len(members)
    out: dict[str, Any] = {"runs": runs, "confidence": confidence, "groups": {}, "measurements": {},
                           "asked": {"groups": asked_g, "measurements": asked_m}}
    k = min((m["samples"] for m in members), default=0)
    out["t"] = members[0]["t"][:k] if runs else []
    for g in list(STATE_GROUPS):
        dof = STATE_GROUPS[g]
        arr = np.array([m["nees"].get(g, [])[:k] for m in members], dtype=np.float64)
        if not runs or not k or arr.shape[1] != k:
            out["groups"][g] = {"dof": dof, "mean_nees": None, "lower": None, "upper": None, "share_inside": None,
                                "passed": None, "status": "not applied", "asked": g in asked_g, "series": []}
            continue
        avg_t = arr.mean(axis=0)
        lo, hi = chi2_bounds(runs, dof, confidence)
        mean = float(avg_t.mean())
        one_sided = g in (upper_only or [])
        ok = bool(mean <= hi) if one_sided else bool(lo <= mean <= hi)
        out["groups"][g] = {
            "dof": dof, "mean_nees": mean, "lower": lo, "upper": hi,
            "share_inside": float(np.mean((avg_t >= lo) & (avg_t <= hi))),
            "passed": ok, "status": _status(ok), "asked": g in asked_g, "upper_only": one_sided,
            "conservative": bool(mean < lo),
            "series": [round(float(v), 4) for v in avg_t],
        }
    shares = [m["heading_in_3sigma"] for m in members if m.get("heading_in_3sigma") is not None]
    out["heading_in_3sigma"] = {"mean": float(np.mean(shares)) if shares else None,
                                "min": float(np.min(shares)) if shares else None}
    herr = [m["heading_err_mean_deg"] for m in members if m.get("heading_err_mean_deg") is not None]
    hsig = [m["heading_sigma_mean_deg"] for m in members if m.get("heading_sigma_mean_deg") is not None]
    out["heading_error"] = {"mean_deg": float(np.mean(herr)) if herr else None,
                            "positive_runs": sum(1 for v in herr if v > 0), "runs": len(herr),
                            "sigma_mean_deg": float(np.mean(hsig)) if hsig else None}
    for name in MEASUREMENT_TYPES:
        s = sum(float(m["innovation"].get(name, {}).get("nis_sum", 0.0)) for m in members)
        n = sum(int(m["innovation"].get(name, {}).get("rows", 0)) for m in members)
        if not n:
            out["measurements"][name] = {"rows": 0, "mean_nis": None, "lower": None, "upper": None, "passed": None,
                                         "status": "not applied", "asked": name in asked_m}
            continue
        lo, hi = chi2_bounds(n, 1, confidence)
        mean = s / n
        ok = bool(lo <= mean <= hi)
        out["measurements"][name] = {"rows": n, "mean_nis": mean, "lower": lo, "upper": hi, "passed": ok,
                                     "status": _status(ok), "asked": name in asked_m}
    decisive = [d for d in (*out["groups"].values(), *out["measurements"].values()) if d["asked"]]
    out["not_applied"] = [n for kind in ("groups", "measurements") for n, d in out[kind].items()
                          if d["asked"] and d["passed"] is None]
    out["passed"] = bool(decisive) and all(d["passed"] is True for d in decisive)
    return out
