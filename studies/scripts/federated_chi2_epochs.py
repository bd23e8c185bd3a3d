"""The federated filter's chi-square statistic at each GNSS epoch of ``federated_gnss_glitch`` (D-5.34).

``python -m studies.scripts.federated_chi2_epochs [--from 42] [--to 48] [--duration 75] [--seeds A-B]``:
runs the library
scenario as ``tests/firmware_model/variants/test_scenarios.py``'s glitch test does (static for ``--duration`` s, no
expectations, seed 11) and prints, for every GNSS epoch in the window, ``lambda = eps^T A^-1 eps`` with
``A = H P_1 H^T + R`` (what :meth:`FederatedFilter.update_gnss` tests against ``chi2_{0.999}(6)`` = 22.458), each
row's ``eps / sqrt(A_kk)`` (rows: the fix's position, then its velocity), ``sqrt(A_kk)`` and the
``gnss_isolated`` / ``gnss_readmitted`` events of the run. The statistic is read by wrapping the module's
``spd_solve`` (the same matrix and innovation the filter solves with); the firmware is not changed. With
``--seeds`` (e.g. ``1-20``) it runs each seed instead and prints, per seed and pooled, the mean ``lambda`` over the
window (``m`` = 6 rows: 6 for a consistent test) and how many epochs exceed the threshold (``alpha`` = 0.001 of
them expected).
"""

from __future__ import annotations

import argparse
import json
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from emulator.assembly.session import run_scenario
from emulator.testing import load_test_scenario
from firmware_model.variants import federated as fed

#: chi2_{0.999}(6): the mode manager's threshold for a UBX fix's six rows
THRESHOLD = 22.4577
SCENARIO = Path(__file__).resolve().parents[2] / "scenarios" / "federated_gnss_glitch.yaml"


def epochs(t0: float, t1: float, duration_s: float = 75.0, seed: int | None = None,
           run_dir: Path | None = None) -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """(per-epoch records in ``[t0, t1]``, the run's isolation / readmission events); ``seed`` None: the file's;
    ``run_dir``: where the run's recording (events.jsonl, nav.csv) is kept (None: a temporary directory)."""
    seen: dict[str, Any] = {}
    out: list[dict[str, Any]] = []
    orig_solve, orig_update = getattr(fed, "spd_solve"), fed.FederatedFilter.update_gnss  # noqa: B009

    def solve(a: Any, b: Any) -> Any:
        seen["A"], seen["eps"] = np.array(a, dtype=float), np.array(b, dtype=float)
        return orig_solve(a, b)

    def update(self: Any, nav: Any, meas: Any, p_ins: Any, v_ins: Any) -> Any:
        seen.clear()
        rep = orig_update(self, nav, meas, p_ins, v_ins)
        t = float(meas.t_fpga_s)
        if "A" in seen and t0 - 1e-6 <= t <= t1 + 1e-6:
            a, e = seen["A"], seen["eps"]
            out.append({"t_s": t, "lambda": float(e @ np.linalg.solve(a, e)), "accepted": rep.accepted,
                        "norm_eps": (e / np.sqrt(np.diag(a))).tolist(), "sqrt_a": np.sqrt(np.diag(a)).tolist()})
        return rep

    setattr(fed, "spd_solve", solve)  # noqa: B010
    setattr(fed.FederatedFilter, "update_gnss", update)  # noqa: B010
    try:
        over: dict[str, Any] = {"duration_s": duration_s, "expectations": [],
                                "motion": [{"static": {"duration_s": duration_s}}]}
        if seed is not None:
            over["seed"] = seed
        scn = load_test_scenario(SCENARIO, over)
        if run_dir is not None:
            run_scenario(scn, run_dir, mode="fast")
            lines = (run_dir / "events.jsonl").read_text().splitlines()
        else:
            with tempfile.TemporaryDirectory(prefix="chi2-") as tmp:
                run_scenario(scn, Path(tmp) / "run", mode="fast")
                lines = (Path(tmp) / "run" / "events.jsonl").read_text().splitlines()
    finally:
        setattr(fed, "spd_solve", orig_solve)  # noqa: B010
        setattr(fed.FederatedFilter, "update_gnss", orig_update)  # noqa: B010
    events = [e for e in (json.loads(s) for s in lines if s.strip())
              if e.get("event") in ("gnss_isolated", "gnss_readmitted")]
    return out, events


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--from", dest="t0", type=float, default=42.0, help="first epoch (s)")
    ap.add_argument("--to", dest="t1", type=float, default=48.0, help="last epoch (s)")
    ap.add_argument("--duration", type=float, default=75.0, help="run length (s), static")
    ap.add_argument("--seeds", default=None, help="A-B: per-seed mean lambda and exceedances over the window instead")
    a = ap.parse_args()
    if a.seeds:
        lo, hi = (int(v) for v in a.seeds.split("-"))
        total, n, over = 0.0, 0, 0
        for seed in range(lo, hi + 1):
            lam = [r["lambda"] for r in epochs(a.t0, a.t1, a.duration, seed)[0]]
            k = sum(1 for v in lam if v > THRESHOLD)
            total, n, over = total + sum(lam), n + len(lam), over + k
            print(f"seed {seed}: mean lambda {sum(lam) / len(lam):.2f}, max {max(lam):.2f}, above {k}", flush=True)
        print(f"pooled: mean lambda {total / n:.3f} over {n} epochs, {over} above {THRESHOLD}")
        return
    recs, events = epochs(a.t0, a.t1, a.duration)
    for e in events:
        print(f"{e['event']} at t_meas {e.get('t_meas_s')} s, lambda {e.get('nis'):.4f}")
    for r in recs:
        print(f"t = {r['t_s']:6.1f} s  lambda {r['lambda']:8.4f}  {'pass' if r['accepted'] else 'FAIL'}  "
              "eps/sqrt(A_kk) " + " ".join(f"{v:+.2f}" for v in r["norm_eps"])
              + "  sqrt(A_kk) " + " ".join(f"{v:.3f}" for v in r["sqrt_a"]))


if __name__ == "__main__":
    main()
