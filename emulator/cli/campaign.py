"""``psns-hil campaign``: a Monte-Carlo campaign of a scenario on a Dask cluster (:mod:`emulator.distributed.campaign`).

Prints a progress bar, the error statistics over the completed members, the expectation pass rates and every
failed member; exit code 0 when every member completed and passed, 1 otherwise, 2 for bad input.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from ..distributed.campaign import CampaignConfig, CampaignError, parse_vary, run_campaign

__all__ = ["add_parser", "run"]


def add_parser(sub: Any) -> argparse.ArgumentParser:
    """Register ``psns-hil campaign`` on an argparse sub-parser collection."""
    c: argparse.ArgumentParser = sub.add_parser("campaign", help="Monte-Carlo campaign of a scenario on a Dask cluster",
                       description="Run N members of SCENARIO (fast mode) with seeds derived from the campaign "
                                   "seed and parameters drawn per --vary; write runs.csv, stats.csv, "
                                   "campaign.json and plots.")
    c.add_argument("scenario", help="scenario YAML file")
    c.add_argument("--runs", type=int, default=None, help="number of members (default: the number of --seeds)")
    c.add_argument("--seeds", default=None, metavar="A-B|A,B,...",
                   help="explicit run seeds of the members (e.g. 1-10), instead of seeds derived from --seed")
    c.add_argument("--vary", action="append", default=[], metavar="KEY=DISTRIBUTION",
                   help="e.g. sensors.imu.gyro.arw_deg_rt_h=normal(0.15,0.02); uniform(a,b); choice(a,b,c)")
    c.add_argument("--envelope", default=None, metavar="PRESET",
                   help="draw each member's world from this envelope with the member's seed (e.g. published; "
                        "docs/sensors.md \"The envelope\"); the draws are in runs.csv (envelope:KEY columns)")
    c.add_argument("--envelope-groups", default=None, metavar="G1,G2",
                   help="only these groups of the envelope (imu, gnss, sky, camera, mounting, calibration)")
    c.add_argument("--seed", type=int, default=None, help="campaign seed (default: the scenario's seed)")
    c.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                   help="a running Dask scheduler (default: a LocalCluster on 127.0.0.1)")
    c.add_argument("--workers", type=int, default=2, help="LocalCluster worker processes (default 2)")
    c.add_argument("--out", default=None, help="output directory (default runs/campaign-<scenario>-<UTC time>)")
    c.add_argument("--keep-all", action="store_true",
                   help="keep every member's captures, nav.csv and truth.csv, and write its run.mcap")
    c.add_argument("--no-plots", action="store_true", help="skip campaign.png / sensitivity.png")
    c.add_argument("--json", action="store_true", help="print campaign.json's statistics as JSON")
    c.add_argument("--quiet", action="store_true", help="no progress bar")
    c.add_argument("--dashboard", action="store_true",
                   help="serve the Dask dashboard of the local cluster on 127.0.0.1:8787 (off by default)")
    c.add_argument("--consistency", action="store_true",
                   help="filter consistency: average NEES per state group and NIS per measurement type against the "
                        "two-sided chi-square bounds for N runs; writes consistency.json (the scenario's consistency: "
                        "expectation chooses groups and confidence, default all at 95 %%)")
    c.add_argument("--after-s", type=float, default=None, metavar="S",
                   help="consistency from this scenario time on (default: the consistency: expectation's, else 0)")
    c.add_argument("--allow-hooks", action="store_true",
                   help="run the scenario's Python expectation hooks in the members (a trusted scenario only)")
    return c


def run(args: argparse.Namespace) -> int:
    """``psns-hil campaign``: 0 every member completed and passed, 1 some failed or missed an expectation."""
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
    from rich.table import Table

    if args.workers < 1:
        raise CampaignError("--workers must be >= 1")
    seeds = parse_seeds(args.seeds) if args.seeds else None
    runs = args.runs if args.runs is not None else (len(seeds) if seeds else None)
    if runs is None:
        raise CampaignError("give --runs N or --seeds A-B")
    cfg = CampaignConfig(scenario=Path(args.scenario), runs=runs, seeds=seeds,
                         variations=[parse_vary(v) for v in args.vary], seed=args.seed, scheduler=args.scheduler,
                         workers=args.workers, out_dir=Path(args.out) if args.out else None,
                         keep_all=args.keep_all, plots=not args.no_plots, dashboard=args.dashboard,
                         consistency=args.consistency, consistency_after_s=args.after_s, envelope=args.envelope,
                         envelope_groups=args.envelope_groups.split(",") if args.envelope_groups else None)
    if args.allow_hooks:  # before the cluster exists: its worker processes inherit the setting
        import os

        from ..scenario.paths import ALLOW_HOOKS_ENV

        os.environ[ALLOW_HOOKS_ENV] = "1"
    console = Console(highlight=False)
    if not console.is_terminal:  # a log or a pipe: wide enough for the statistics table
        console = Console(highlight=False, width=140)
    prog = Progress(TextColumn("members"), BarColumn(), MofNCompleteColumn(),
                    TextColumn("{task.fields[failed]} failed"), TimeElapsedColumn(), console=console, transient=True,
                    disable=args.quiet or args.json or not console.is_terminal)
    task = prog.add_task("runs", total=cfg.runs, failed=0)
    failed = [0]

    def on_row(row: dict[str, Any], done: int, total: int) -> None:
        failed[0] += 0 if row.get("ok") else 1
        prog.update(task, completed=done, failed=failed[0])

    with prog:
        res = run_campaign(cfg, progress=on_row)
    if args.json:
        print(json.dumps({"campaign": res.info, "statistics": res.stats}, indent=2, default=str))
    else:
        st = res.stats
        console.print(f"campaign {res.info['scenario']}: {st['runs']} runs on {res.info['workers']} workers "
                      f"({res.info['scheduler']}) in {res.wall_s:.1f} s = {res.runs_per_min:.1f} runs/min "
                      f"-> {res.out_dir}")
        t = Table(title="error statistics over completed runs", title_justify="left")
        for col in ("quantity", "n", "mean", "sigma", "p5", "p50", "p95", "max"):
            t.add_column(col, justify="left" if col == "quantity" else "right", no_wrap=True)
        for name, d in st["metrics"].items():
            if name.endswith(("_rms", "_max", "_median", "_p95")) or name.startswith("param:"):
                t.add_row(name, str(d["n"]), *("-" if d[k] is None else f"{d[k]:.4g}"
                                              for k in ("mean", "sigma", "p5", "p50", "p95", "max")))
        console.print(t)
        if st["expectations"]:
            e = Table(title="expectations", title_justify="left")
            for col in ("#", "check", "passed", "pass rate"):
                e.add_column(col)
            for d in st["expectations"]:
                e.add_row(str(d["index"]), d["description"], f"{d['passed']}/{d['runs']}",
                          f"{100 * d['pass_rate']:.1f} %" if d["pass_rate"] is not None else "-")
            console.print(e)
        console.print(f"completed {st['completed']}/{st['runs']}, passed {st['passed']}"
                      + (f" ({100 * st['pass_rate']:.1f} % of completed)" if st["pass_rate"] is not None else ""))
        for r in res.failed:
            console.print(f"[bold red]member {r['index']} (seed {r['seed']}) failed:[/] {r['error']}", soft_wrap=True)
        if res.consistency is not None:
            console.print(consistency_table(res.consistency))
    consistent = res.consistency is None or bool(res.consistency.get("passed"))
    return 0 if res.all_passed and consistent else 1


def parse_seeds(text: str) -> list[int]:
    """``"1-10"`` or ``"1,4,7"`` (or both, comma-separated) -> the list of seeds; CampaignError on anything else."""
    out: list[int] = []
    for part in text.split(","):
        part = part.strip()
        try:
            if "-" in part:
                a, b = (int(x) for x in part.split("-", 1))
                if b < a:
                    raise ValueError
                out += list(range(a, b + 1))
            else:
                out.append(int(part))
        except ValueError:
            raise CampaignError(f"--seeds: {part!r} is not a seed or a range A-B") from None
    if not out or any(s < 0 for s in out):
        raise CampaignError("--seeds: give non-negative seeds")
    return out


def consistency_table(c: dict[str, Any]) -> Any:
    """The consistency check as a rich table: NEES per state group, NIS per measurement type, bounds, pass/fail."""
    from rich.table import Table

    t = Table(title=f"consistency over {c['runs']} runs ({100 * c['confidence']:.0f} % two-sided chi-square bounds)",
              title_justify="left")
    for col in ("quantity", "dof / rows", "average", "lower", "upper", "inside (share of times)", "result"):
        t.add_column(col, justify="left" if col == "quantity" else "right", no_wrap=True)
    for g, d in c.get("groups", {}).items():
        share = "-" if d["share_inside"] is None else f"{100 * d['share_inside']:.0f} %"
        t.add_row(f"NEES {g}", str(d["dof"]), f"{d['mean_nees']:.3g}", f"{d['lower']:.3g}", f"{d['upper']:.3g}",
                  share, "pass" if d["passed"] else "FAIL")
    for m, d in c.get("measurements", {}).items():
        if d["passed"] is None:
            t.add_row(f"NIS {m}", "0", "-", "-", "-", "-", "no rows")
            continue
        t.add_row(f"NIS {m}", str(d["rows"]), f"{d['mean_nis']:.3g}", f"{d['lower']:.3g}", f"{d['upper']:.3g}", "-",
                  "pass" if d["passed"] else "FAIL")
    h = c.get("heading_in_3sigma") or {}
    if h.get("mean") is not None:
        t.caption = (f"heading error inside 3 sigma: {100 * h['mean']:.1f} % of navigating frames on average "
                     f"(worst run {100 * h['min']:.1f} %)")
    return t
