"""Where the fused filter gains or loses against polarization/MIMU alone, per phase (Ge et al. under the field presets).

``python -m studies.scripts.ge_phases SEED [--set KEY=JSON ...]``: runs
``benchmarks.paper_reproductions``'s ``ge`` members
``fused`` and ``pol_mimu`` on the seed's stream and prints each member's heading RMS after 20 s (the benchmark's) and,
per window of the 705 s run (20-100, ..., 600-705 s; the motion starts at 400 s), each member's heading error RMS and
mean (deg) and the window's share of the difference of the mean squares after 20 s (deg^2; the shares add up to
``fused^2 - pol^2`` of the benchmark's RMS). ``--set`` overrides a dotted scenario key for both members (attribution
runs, e.g. D-5.36's ``firmware.alignment.misalignment_deg=[-0.9,0.6,-0.7]``). D-5.34 and D-5.36 quote it.
"""

from __future__ import annotations

import argparse
import math
from typing import Any

from benchmarks.paper_reproductions import GE_CONFIGS, _f, ge_overrides, parse_overrides, run_nav

WINDOWS = ((20.0, 100.0), (100.0, 200.0), (200.0, 300.0), (300.0, 400.0), (400.0, 500.0), (500.0, 600.0),
           (600.0, 705.1))


def heading_errors(seed: int, config: str, overrides: dict[str, Any] | None = None) -> list[tuple[float, float]]:
    """(time s, heading error deg) of one member's navigation output (``overrides``: dotted scenario keys)."""
    over = ge_overrides(GE_CONFIGS[config], overrides)
    _s, nav, _ev = run_nav("federated_paper_comparison", seed, over)
    return [(float(r["time_s"]), h) for r in nav if (h := _f(r, "err_heading_deg")) is not None]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("seed", type=int)
    ap.add_argument("--set", action="append", default=[], metavar="KEY=JSON",
                    help="a dotted scenario override for both members, value as JSON")
    a = ap.parse_args()
    over = parse_overrides(a.set)
    runs = {c: heading_errors(a.seed, c, over) for c in ("fused", "pol_mimu")}
    n_all = sum(1 for t, _h in runs["fused"] if t >= WINDOWS[0][0])
    for c in ("fused", "pol_mimu"):
        h = [x for t, x in runs[c] if t >= WINDOWS[0][0]]
        print(f"{c}: heading RMS after {WINDOWS[0][0]:.0f} s {math.sqrt(sum(x * x for x in h) / len(h)):.4f} deg")
    for lo, hi in WINDOWS:
        cells, sq = [], []
        for c in ("fused", "pol_mimu"):
            h = [x for t, x in runs[c] if lo <= t < hi]
            sq.append(sum(x * x for x in h))
            cells.append(f"{c} {math.sqrt(sq[-1] / len(h)):.3f} (mean {sum(h) / len(h):+.3f})")
        print(f"{lo:5.0f}-{hi:5.0f} s: " + ", ".join(cells) + f"; share {(sq[0] - sq[1]) / n_all:+.5f} deg^2")


if __name__ == "__main__":
    main()
