"""``psns-hil campaign``: a Monte-Carlo campaign of a scenario on a Dask cluster (:mod:`emulator.distributed.campaign`).

Prints a progress bar, the error statistics over the completed members, the expectation pass rates and every
failed member; exit code 0 when every member completed and passed (and, with ``--consistency``, every state group and
measurement type *asked for* lies inside its chi-square bounds), 1 otherwise, 2 for bad input. The consistency
groups asked for are the command line's (``--groups`` / ``--measurements``), else the scenario's ``consistency:``
expectation's, else attitude, velocity and position, with ``heading`` added wherever the scenario has a heading
source; every other group and measurement type is shown, marked *informative*, and does not decide the exit code. A
check that could not be applied (no samples, no rows, a campaign-level expectation inside one member) is shown as
*not applied*, never as a pass.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

from ..distributed.campaign import CampaignConfig, CampaignError, parse_vary, run_campaign
from ..scenario.consistency_schema import MEASUREMENT_TYPES, STATE_GROUPS

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
    c.add_argument("--groups", default=None, metavar="G,G,...",
                   help="state groups that decide the exit code (attitude, heading, velocity, position, "
                        "horizontal_position); default: the scenario's consistency: expectation, else attitude, "
                        "velocity, position (+ heading with a camera or compass)")
    c.add_argument("--measurements", default=None, metavar="M,M,...",
                   help="measurement types whose NIS decides the exit code (gnss_position, gnss_velocity, "
                        "solar_vector, compass; 'none' for none); default: the expectation's, else none")
    c.add_argument("--set", action="append", default=[], metavar="KEY=VALUE",
                   help="override a scenario key in every member (as psns-hil run --set), e.g. "
                        "sky.neutral_point_sep_deg=60")
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
    groups = parse_names(args.groups, "--groups", STATE_GROUPS) if args.groups else None
    measurements = parse_names(args.measurements, "--measurements", MEASUREMENT_TYPES) \
        if args.measurements is not None else None
    seeds = parse_seeds(args.seeds) if args.seeds else None
    runs = args.runs if args.runs is not None else (len(seeds) if seeds else None)
    if runs is None:
        raise CampaignError("give --runs N or --seeds A-B")
    cfg = CampaignConfig(scenario=Path(args.scenario), runs=runs, seeds=seeds,
                         variations=[parse_vary(v) for v in args.vary], seed=args.seed, scheduler=args.scheduler,
                         workers=args.workers, out_dir=Path(args.out) if args.out else None,
                         keep_all=args.keep_all, plots=not args.no_plots, dashboard=args.dashboard,
                         consistency=args.consistency, consistency_after_s=args.after_s, envelope=args.envelope,
                         envelope_groups=args.envelope_groups.split(",") if args.envelope_groups else None,
                         consistency_groups=groups, consistency_measurements=measurements, overrides=list(args.set))
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
                if not d["runs"]:  # applied in no member: a campaign-level check (consistency, below)
                    verdict = "not applied in the members"
                    if "consistency" in d["description"] and res.consistency is not None:
                        verdict += " (campaign: " + ("pass" if res.consistency.get("passed") else "FAIL") + ")"
                    e.add_row(str(d["index"]), d["description"], verdict, "-")
                    continue
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


def parse_names(text: str, option: str, known: Any) -> list[str]:
    """``"a,b"`` -> ``["a", "b"]``, each one of ``known``; ``"none"`` -> ``[]``; CampaignError otherwise."""
    names = [n.strip() for n in text.split(",") if n.strip()]
    if names == ["none"]:
        return []
    bad = [n for n in names if n not in known]
    if bad or not names:
        raise CampaignError(f"{option}: unknown {bad or text!r}; known: {', '.join(known)}")
    return names


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
    """The consistency check as a rich table: NEES per state group, NIS per measurement type, bounds, and whether
    each row decides the result (asked for) or is informative; a row without samples reads *not applied*."""
    from rich.table import Table

    t = Table(title=f"consistency over {c['runs']} runs ({100 * c['confidence']:.0f} % two-sided chi-square bounds): "
                    + ("pass" if c.get("passed") else "FAIL") + " (the asked rows decide)",
              title_justify="left")
    for col in ("quantity", "dof / rows", "average", "lower", "upper", "inside (share of times)", "role", "result"):
        t.add_column(col, justify="left" if col == "quantity" else "right", no_wrap=True)

    def num(v: Any) -> str:
        return "-" if v is None else f"{v:.3g}"

    def result(d: dict[str, Any]) -> str:
        status = d.get("status") or ("not applied" if d.get("passed") is None else "pass" if d["passed"] else "FAIL")
        if status == "not applied":
            return "[bold red]not applied[/]" if d.get("asked") else "[dim]not applied[/]"
        if status == "FAIL":
            return "[bold red]FAIL[/]" if d.get("asked") else "[yellow]outside[/]"
        if d.get("conservative"):  # under the lower bound, passed one-sided (upper_only)
            return "[green]pass[/] (conservative)"
        return "[green]pass[/]" if d.get("asked") else "inside"

    for g, d in c.get("groups", {}).items():
        share = "-" if d.get("share_inside") is None else f"{100 * d['share_inside']:.0f} %"
        role = ("asked, upper bound only" if d.get("upper_only") else "asked") if d.get("asked") else \
            "[dim]informative[/]"
        t.add_row(f"NEES {g}", str(d["dof"]), num(d["mean_nees"]), num(d["lower"]), num(d["upper"]), share, role,
                  result(d))
    for m, d in c.get("measurements", {}).items():
        t.add_row(f"NIS {m}", str(d["rows"]), num(d["mean_nis"]), num(d["lower"]), num(d["upper"]), "-",
                  "asked" if d.get("asked") else "[dim]informative[/]", result(d))
    cap = []
    h = c.get("heading_in_3sigma") or {}
    if h.get("mean") is not None:
        cap.append(f"heading error inside 3 sigma: {100 * h['mean']:.1f} % of navigating frames on average "
                   f"(worst run {100 * h['min']:.1f} %)")
    he = c.get("heading_error") or {}
    if he.get("mean_deg") is not None:
        cap.append(f"mean heading error {he['mean_deg']:+.3f} deg (positive in {he['positive_runs']}/{he['runs']} "
                   f"runs) against a mean heading sigma of {he['sigma_mean_deg']:.3f} deg")
    if c.get("not_applied"):
        cap.append(f"asked but not applied (no samples or rows): {', '.join(c['not_applied'])}")
    if cap:
        t.caption = "; ".join(cap)
    return t
