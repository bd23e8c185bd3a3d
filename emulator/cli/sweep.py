"""``psns-hil sweep``: where the firmware's sigma stops holding, one world dimension at a time (issue 36 item 4).

For each value of ``--param`` (any scenario key ``psns-hil run --set`` accepts: ``sky.neutral_point_sep_deg``,
``sensors.imu.accel.bias_repeatability_mg``, the envelope's diattenuation or GNSS environment keys when they exist)
the command runs a Monte-Carlo campaign of SCENARIO on the same seeds (``--seeds``, default 301-310: seeds the
library's own checks never use) with the filter-consistency check (:mod:`emulator.distributed.campaign.consistency`),
and collects per value: the navigation error statistics (rms over the run, mean over the members) and the average
NEES of every state group with its two-sided chi-square bounds for the number of runs. The *boundary* of a group is
the first value, in the order given, at which its average NEES rises above the upper bound: the filter is
overconfident there (its sigma no longer covers the error). The groups that decide are those a campaign asks for
(the scenario's ``consistency:`` expectation or ``--groups``; ``heading`` wherever the scenario has a heading source).

Writes into ``--out`` (default ``runs/sweep-<scenario>-<param>-<UTC time>``): ``sweep.csv`` (one row per value),
``sweep.json`` (the same with the bounds and the boundary per group) and ``sweep.png`` (error and NEES against the
parameter, bounds as dashed lines, the boundary marked), and one campaign directory per value. Exit code 0 when every
asked group holds at every value, 1 when a boundary was found (or a member failed), 2 for bad input.
"""

from __future__ import annotations

import argparse
import csv
import datetime as _dt
import json
import math
import re
from pathlib import Path
from typing import Any

__all__ = ["add_parser", "boundary", "parse_values", "run", "sweep_rows"]

#: the error statistics a sweep reports per value (a campaign's ``<metric>_rms``, mean over the members)
ERROR_METRICS = ("heading_deg_rms", "attitude_deg_rms", "velocity_mps_rms", "position_m_rms")


def add_parser(sub: Any) -> argparse.ArgumentParser:
    """Register ``psns-hil sweep`` on an argparse sub-parser collection."""
    s: argparse.ArgumentParser = sub.add_parser(
        "sweep", help="error and NEES against one world parameter; marks where the firmware's sigma stops holding",
        description="Run a consistency campaign of SCENARIO for each value of one scenario key and mark the first "
                    "value at which a state group's average NEES leaves the chi-square upper bound.")
    s.add_argument("scenario", help="scenario YAML file")
    s.add_argument("--param", required=True, metavar="KEY",
                   help="the scenario key to sweep (dotted, as psns-hil run --set), e.g. sky.neutral_point_sep_deg")
    s.add_argument("--values", required=True, metavar="V,V,...",
                   help="the values, in sweep order, e.g. 20,30,40,50,60; separated by ';' when a value is a list, "
                        "e.g. '[3.6,3.6,3.6];[7.2,7.2,7.2]'")
    s.add_argument("--seeds", default="301-310", metavar="A-B|A,B,...",
                   help="run seeds of every value's members (default 301-310, seeds the library never uses)")
    s.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="a further override applied at every value (as psns-hil run --set)")
    s.add_argument("--groups", default=None, metavar="G,G,...",
                   help="state groups that decide (default: as psns-hil campaign --consistency)")
    s.add_argument("--after-s", type=float, default=None, metavar="S",
                   help="consistency from this scenario time on (default: the scenario's consistency: expectation)")
    s.add_argument("--workers", type=int, default=2, help="LocalCluster worker processes (default 2)")
    s.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT", help="a running Dask scheduler")
    s.add_argument("--out", default=None, help="output directory (default runs/sweep-<scenario>-<param>-<time>)")
    s.add_argument("--no-plots", action="store_true", help="skip sweep.png")
    s.add_argument("--json", action="store_true", help="print sweep.json")
    s.add_argument("--quiet", action="store_true", help="no per-value progress line")
    return s


def parse_values(text: str) -> list[Any]:
    """``"20,30,40"`` -> ``[20, 30, 40]`` (each read as YAML, as ``--set`` does); with a ``;`` anywhere the values
    are split on ``;`` instead, so that a value may be a list (``"[3.6,3.6,3.6];[7.2,7.2,7.2]"``); CampaignError when
    empty."""
    import yaml

    from ..distributed.campaign import CampaignError

    sep = ";" if ";" in text else ","
    vals = [yaml.safe_load(v.strip()) for v in text.split(sep) if v.strip()]
    if not vals:
        raise CampaignError("--values: give at least one value")
    return vals


def sweep_rows(param: str, results: list[tuple[Any, Any]]) -> list[dict[str, Any]]:
    """One row per value from ``(value, CampaignResult)`` pairs: the error means, and per state group the average
    NEES, its bounds, whether it was asked for and whether it holds (``lower <= NEES <= upper``; ``over``: above the
    upper bound, the overconfident side)."""
    rows = []
    for value, res in results:
        row: dict[str, Any] = {"param": param, "value": value, "runs": res.stats["completed"],
                               "failed": res.stats["failed"]}
        for m in ERROR_METRICS:
            d = res.stats["metrics"].get(m) or {}
            row[m] = d.get("mean")
        c = res.consistency or {}
        for g, d in (c.get("groups") or {}).items():
            row[f"nees_{g}"] = d.get("mean_nees")
            row[f"upper_{g}"] = d.get("upper")
            row[f"lower_{g}"] = d.get("lower")
            row[f"asked_{g}"] = bool(d.get("asked"))
            row[f"over_{g}"] = None if d.get("mean_nees") is None else bool(d["mean_nees"] > d["upper"])
        he = c.get("heading_error") or {}
        row["heading_err_mean_deg"] = he.get("mean_deg")
        row["heading_sigma_mean_deg"] = he.get("sigma_mean_deg")
        rows.append(row)
    return rows


def boundary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Per state group, the first value (sweep order) whose average NEES lies above the upper bound, or None;
    ``"asked"``: the first such value over the groups that decide (None: the sigma holds over the whole sweep)."""
    groups = sorted({k[len("nees_"):] for r in rows for k in r if k.startswith("nees_")})
    out: dict[str, Any] = {"groups": {}, "asked": None}
    for g in groups:
        first = next((r["value"] for r in rows if r.get(f"over_{g}")), None)
        out["groups"][g] = first
    for r in rows:
        if any(r.get(f"over_{g}") and r.get(f"asked_{g}") for g in groups):
            out["asked"] = r["value"]
            break
    return out


def _plot(rows: list[dict[str, Any]], bnd: dict[str, Any], path: Path, title: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    xs = list(range(len(rows)))

    def scalar(v: Any) -> float | None:
        if isinstance(v, list) and v and all(isinstance(e, (int, float)) for e in v) and len(set(v)) == 1:
            v = v[0]  # a vector of equal components (a per-axis figure): plot its value
        return float(v) if isinstance(v, (int, float)) and not isinstance(v, bool) else None

    sx = [scalar(r["value"]) for r in rows]
    numeric = all(v is not None for v in sx)
    x = [float(v) for v in sx if v is not None] if numeric else [float(i) for i in xs]
    fig, (ax1, ax2) = plt.subplots(2, 1, figsize=(8, 7), sharex=True)
    for m in ERROR_METRICS:
        ys = [r.get(m) for r in rows]
        if any(y is not None for y in ys) and m.startswith("heading"):
            ax1.plot(x, [math.nan if y is None else y for y in ys], "o-", label=f"{m} (mean over members)")
    sig = [r.get("heading_sigma_mean_deg") for r in rows]
    if any(s is not None for s in sig):
        ax1.plot(x, [math.nan if s is None else s for s in sig], "s--", label="filter's heading sigma (mean)")
    ax1.set_ylabel("deg")
    ax1.grid(True, alpha=0.3)
    ax1.legend(fontsize=8)
    groups = [g for g in bnd["groups"] if any(r.get(f"asked_{g}") for r in rows)]
    for g in groups:
        line, = ax2.plot(x, [math.nan if r.get(f"nees_{g}") is None else r[f"nees_{g}"] / max(1, _dof(g))
                             for r in rows], "o-", label=f"NEES {g} / dof")
        ax2.plot(x, [math.nan if r.get(f"upper_{g}") is None else r[f"upper_{g}"] / max(1, _dof(g)) for r in rows],
                 "--", color=line.get_color(), alpha=0.6, lw=1)
    if bnd["asked"] is not None:
        i = next(i for i, r in enumerate(rows) if r["value"] == bnd["asked"])
        for ax in (ax1, ax2):
            ax.axvline(x[i], color="r", lw=1.5, alpha=0.7)
        ax2.annotate(f"sigma stops holding at {bnd['asked']}", (x[i], ax2.get_ylim()[1]), color="r",
                     fontsize=9, ha="right", va="top")
    ax2.set_yscale("log")
    ax2.set_ylabel("average NEES per dof (dashed: upper bound)")
    ax2.grid(True, alpha=0.3, which="both")
    ax2.legend(fontsize=8)
    ax2.set_xlabel(rows[0]["param"])
    if not numeric:
        ax2.set_xticks(xs, [str(r["value"]) for r in rows])
    fig.suptitle(title, fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _dir_name(v: Any) -> str:
    return re.sub(r"[^A-Za-z0-9._-]+", "_", str(v)).strip("_") or "value"


def _num(v: Any) -> str:
    return "-" if v is None else f"{v:.3g}"


def _dof(group: str) -> int:
    from ..scenario.consistency_schema import STATE_GROUPS

    return STATE_GROUPS.get(group, 1)


def run(args: argparse.Namespace) -> int:
    """``psns-hil sweep``: 0 the asked groups hold at every value, 1 a boundary was found or a member failed."""
    from ..distributed.campaign import CampaignConfig, CampaignError, run_campaign
    from ..distributed.campaign.execute import local_cluster
    from ..scenario.consistency_schema import STATE_GROUPS
    from .campaign import parse_names, parse_seeds

    values = parse_values(args.values)
    seeds = parse_seeds(args.seeds)
    if "=" in args.param or not args.param.strip():
        raise CampaignError("--param: a dotted scenario key, e.g. sky.neutral_point_sep_deg")
    if args.workers < 1:
        raise CampaignError("--workers must be >= 1")
    groups = parse_names(args.groups, "--groups", STATE_GROUPS) if args.groups else None
    stamp = _dt.datetime.now(_dt.UTC).strftime("%Y%m%dT%H%M%SZ")
    scn_name = Path(args.scenario).stem
    out = Path(args.out) if args.out else Path("runs") / f"sweep-{scn_name}-{args.param}-{stamp}"
    out.mkdir(parents=True, exist_ok=True)
    client = cluster = None
    if args.scheduler is None:
        client, cluster = local_cluster(args.workers)
    results: list[tuple[Any, Any]] = []
    try:
        for i, v in enumerate(values):
            cfg = CampaignConfig(scenario=Path(args.scenario), runs=len(seeds), seeds=seeds, scheduler=args.scheduler,
                                 workers=args.workers, out_dir=out / f"{i:02d}-{_dir_name(v)}", plots=False,
                                 consistency=True,
                                 consistency_after_s=args.after_s, consistency_groups=groups,
                                 overrides=[*args.set, f"{args.param}={v}"])
            res = run_campaign(cfg, client=client)
            results.append((v, res))
            if not args.quiet and not args.json:
                c = res.consistency or {}
                asked = {g: d for g, d in (c.get("groups") or {}).items() if d.get("asked")}
                print(f"{args.param}={v}: {res.stats['completed']}/{len(seeds)} runs; "
                      + ", ".join(f"NEES {g} {_num(d['mean_nees'])} (upper {_num(d['upper'])})"
                                  for g, d in asked.items()), flush=True)
    finally:
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()
    rows = sweep_rows(args.param, results)
    bnd = boundary(rows)
    doc = {"scenario": str(args.scenario), "param": args.param, "values": values, "seeds": seeds,
           "overrides": list(args.set), "rows": rows, "boundary": bnd}
    (out / "sweep.json").write_text(json.dumps(doc, indent=1, default=str) + "\n", encoding="utf-8")
    cols = list(dict.fromkeys(k for r in rows for k in r))
    with open(out / "sweep.csv", "w", newline="", encoding="utf-8") as f:
        w = csv.DictWriter(f, fieldnames=cols)
        w.writeheader()
        for r in rows:
            w.writerow({k: ("" if r.get(k) is None else r[k]) for k in cols})
    if not args.no_plots:
        _plot(rows, bnd, out / "sweep.png", f"{scn_name}: {args.param}, seeds {args.seeds}")
    if args.json:
        print(json.dumps(doc, indent=1, default=str))
    else:
        where = ("the asked groups hold at every value" if bnd["asked"] is None
                 else f"the firmware's sigma stops holding at {args.param}={bnd['asked']}")
        per = ", ".join(f"{g}: {'holds' if b is None else b}" for g, b in bnd["groups"].items())
        print(f"sweep {scn_name} over {args.param}: {where} (per group: {per}) -> {out}")
    failed = any(r["failed"] for r in rows)
    return 0 if bnd["asked"] is None and not failed else 1
