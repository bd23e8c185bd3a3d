"""Per-member NEES of a certification campaign, grouped by the GNSS environment each seed drew (issue 36 item 3).

``python -m studies.scripts.cert_by_environment CAMPAIGN_DIR`` reads the members' records of a finished
``psns-hil campaign ... --consistency`` run (``campaign.mcap``, topic ``/campaign/members``: each member's mean NEES
per state group over the consistency window and its drawn envelope) and prints, per GNSS environment drawn
(``field`` when the campaign drew none), the number of runs, the mean of the members' NEES per group and the worst
member's velocity and position NEES. Used by studies/2026-12-07-certification-across-the-envelope.md.
"""

from __future__ import annotations

import argparse
import json
from collections import defaultdict
from pathlib import Path

import numpy as np
from mcap.reader import make_reader

GROUPS = ("attitude", "heading", "velocity", "position")


def members(campaign: Path) -> list[dict]:
    """The ``/campaign/members`` records of ``campaign/campaign.mcap`` in member order."""
    out = []
    with (campaign / "campaign.mcap").open("rb") as f:
        for _schema, channel, message in make_reader(f).iter_messages(topics=["/campaign/members"]):
            out.append(json.loads(message.data))
            del channel
    return sorted(out, key=lambda m: m["index"])


def by_environment(campaign: Path) -> dict[str, dict[str, float]]:
    """``{environment: {"runs": n, group: mean of the members' NEES, "worst_velocity", "worst_position"}}``."""
    acc: dict[str, dict[str, list[float]]] = defaultdict(lambda: defaultdict(list))
    for m in members(campaign):
        if not m.get("ok") or not m.get("nees_mean"):
            continue
        env = str((m.get("envelope") or {}).get("sensors.gnss.environment", "field"))
        for g in GROUPS:
            v = m["nees_mean"].get(g)
            if v is not None:
                acc[env][g].append(float(v))
        acc[env]["seeds"].append(float(m["seed"]))
    out: dict[str, dict[str, float]] = {}
    for env, d in sorted(acc.items()):
        out[env] = {"runs": float(len(d["seeds"])),
                    **{g: float(np.mean(d[g])) if d[g] else float("nan") for g in GROUPS},
                    "worst_velocity": float(np.max(d["velocity"])) if d["velocity"] else float("nan"),
                    "worst_position": float(np.max(d["position"])) if d["position"] else float("nan")}
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="per-environment NEES of a certification campaign")
    ap.add_argument("campaign", type=Path)
    a = ap.parse_args(argv)
    print("| GNSS environment | runs | attitude | heading | velocity | position | worst velocity | worst position |")
    print("|---|---|---|---|---|---|---|---|")
    for env, d in by_environment(a.campaign).items():
        print(f"| {env} | {int(d['runs'])} | {d['attitude']:.2f} | {d['heading']:.2f} | {d['velocity']:.2f} | "
              f"{d['position']:.2f} | {d['worst_velocity']:.2f} | {d['worst_position']:.2f} |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
