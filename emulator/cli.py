"""The ``psns-hil`` command line.

Exit codes: 0 run finished and every expectation passed; 1 an expectation failed (or the run
was interrupted); 2 bad input (missing or invalid scenario, bad link URL) -- one clear message
per problem, no traceback.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any, Sequence

from protocols import __version__
from protocols.errors import PsnsHilError

__all__ = ["main"]

EXIT_OK, EXIT_FAILED, EXIT_USAGE = 0, 1, 2


def _console(stderr: bool = False) -> Any:
    from rich.console import Console

    return Console(stderr=stderr, highlight=False)


def _print_error(exc: PsnsHilError) -> None:
    from .errors import ScenarioError

    err = _console(stderr=True)
    if isinstance(exc, ScenarioError):
        for issue in exc.issues:
            err.print(f"[bold red]error:[/] {issue}", markup=True, soft_wrap=True)
    else:
        err.print(f"[bold red]error:[/] {exc}", markup=True, soft_wrap=True)


def _fmt(v: Any, digits: int = 3) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        return f"{v:.{digits}f}"
    return str(v)


def print_port_map(ports: list[dict[str, Any]]) -> None:
    from rich.table import Table

    t = Table(title="ports", title_justify="left")
    for col in ("port", "role", "baud", "mode", "endpoint"):
        t.add_column(col)
    for p in ports:
        t.add_row(p["name"], p["role"], str(p["baud"]), p["mode"], p["path"])
    _console().print(t)


def print_summary(s: dict[str, Any]) -> None:
    from rich.table import Table

    c = _console()
    head = Table(title=f"psns-hil run: {s['scenario']}", title_justify="left", show_header=False)
    head.add_column("k")
    head.add_column("v")
    rtf = s.get("realtime_factor")
    head.add_row("mode / seed", f"{s['mode']} / {s['seed']}")
    head.add_row("simulated", f"{s['sim_duration_s']:.2f} s in {s['wall_s']:.2f} s wall"
                 + (f" ({rtf:.1f}x real time)" if rtf else ""))
    head.add_row("nav frames", str(s.get("nav_frames")))
    head.add_row("run directory", s["run_dir"])
    if s.get("interrupted"):
        head.add_row("interrupted", "yes")
    c.print(head)

    err = Table(title="navigation error against truth (while navigating)", title_justify="left")
    for col in ("quantity", "rms", "max"):
        err.add_column(col, justify="right" if col != "quantity" else "left")
    for k, v in s["nav_error"].items():
        err.add_row(k, _fmt(v["rms"]), _fmt(v["max"]))
    c.print(err)

    links = Table(title="links", title_justify="left")
    for col in ("link", "bytes", "frames", "crc_errors", "dropped"):
        links.add_column(col, justify="right" if col != "link" else "left")
    for name, v in s["links"].items():
        links.add_row(name, str(v["bytes"]), str(v["frames"]), str(v["crc_errors"]), str(v["dropped"]))
    c.print(links)

    d = s["dsp"]
    cyc = Table(title=f"DSP cycles @ {d['clock_hz'] / 1e6:.0f} MHz, tick budget {d['tick_budget_cycles']} "
                      f"cycles ({d['cost_model']})", title_justify="left")
    for col in ("task", "calls", "min", "avg", "max", "max % of budget"):
        cyc.add_column(col, justify="right" if col != "task" else "left")
    for t in d["tasks"]:
        cyc.add_row(t["task"], str(t["calls"]), str(t["cycles_min"]), f"{t['cycles_avg']:.0f}",
                    str(t["cycles_max"]), f"{t['utilization_max_pct']:.3f}")
        for k, v in sorted(t["kernels"].items(), key=lambda kv: -kv[1]):
            cyc.add_row(f"  {k}", "", "", f"{v / max(t['calls'], 1):.0f}", "", "")
    c.print(cyc)
    c.print(f"CPU load (worst 1 s): {d['cpu_load_pct_max']:.3f} %   deadline misses: {d['deadline_misses']}")

    if s.get("expectations"):
        ex = Table(title="expectations", title_justify="left")
        for col in ("#", "check", "value", "result"):
            ex.add_column(col)
        for r in s["expectations"]:
            ex.add_row(str(r["index"]), r["description"], _fmt(r["value"]),
                       "[green]pass[/]" if r["passed"] else "[bold red]FAIL[/]")
        c.print(ex)


def _cmd_validate(args: argparse.Namespace) -> int:
    from .scenario import load_scenario

    scn = load_scenario(args.scenario)
    if args.json:
        print(scn.model_dump_json(indent=2))
    else:
        _console().print(f"{args.scenario}: ok ({scn.name}, {scn.duration_s:g} s, mode {scn.mode})")
    return EXIT_OK


def _cmd_run(args: argparse.Namespace) -> int:
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from .runner import default_run_dir, run_scenario
    from .scenario import load_scenario

    scn = load_scenario(args.scenario)
    mode = "realtime" if args.realtime else scn.mode
    run_dir = Path(args.out) if args.out else default_run_dir(scn.name)
    console = _console()
    console.print(f"psns-hil {__version__}: running {args.scenario} ({scn.duration_s:g} s, {mode}) -> {run_dir}")
    show_progress = not args.quiet and console.is_terminal
    progress = Progress(TextColumn("{task.description}"), BarColumn(), TextColumn("{task.fields[t]:.1f}/{task.total:.0f} s"),
                        TimeElapsedColumn(), console=console, transient=True, disable=not show_progress)
    task = progress.add_task("simulating", total=scn.duration_s, t=0.0)

    def on_progress(t: float, total: float) -> None:
        progress.update(task, completed=t, t=t)

    def on_started(emu: Any) -> None:
        print_port_map(emu.ports)

    with progress:
        summary = run_scenario(scn, run_dir, mode=mode, speed=args.speed, seed=args.seed,
                               progress=on_progress, on_started=on_started)
    if args.json:
        print(json.dumps(summary, indent=2))
    else:
        print_summary(summary)
    if summary.get("interrupted"):
        console.print("[yellow]run interrupted; captures and summary were kept[/]")
        return EXIT_FAILED
    return EXIT_OK if summary.get("passed", True) else EXIT_FAILED


def _cmd_campaign(args: argparse.Namespace) -> int:
    from .campaign import cli_main

    return cli_main(args)


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="psns-hil", description="PSNS/GNSS/SINS navigation computer HIL emulator")
    p.add_argument("--version", action="version", version=f"psns-hil {__version__}")
    sub = p.add_subparsers(dest="command", required=True)

    r = sub.add_parser("run", help="run a scenario")
    r.add_argument("scenario", help="scenario YAML file")
    r.add_argument("--out", help="run directory (default runs/<scenario>-<UTC time>)")
    r.add_argument("--realtime", action="store_true", help="follow the wall clock (default: the scenario's mode)")
    r.add_argument("--speed", type=float, default=None, help="real-time scale factor in realtime mode")
    r.add_argument("--seed", type=int, default=None, help="override the scenario's seed")
    r.add_argument("--json", action="store_true", help="print the summary as JSON")
    r.add_argument("--quiet", action="store_true", help="no progress bar")
    r.set_defaults(func=_cmd_run)

    v = sub.add_parser("validate", help="check a scenario file and report every problem")
    v.add_argument("scenario")
    v.add_argument("--json", action="store_true", help="print the validated scenario with defaults")
    v.set_defaults(func=_cmd_validate)

    from .campaign import add_cli_parser

    add_cli_parser(sub).set_defaults(func=_cmd_campaign)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "speed", None) is not None and args.speed <= 0:
        parser.error("--speed must be > 0")
    try:
        return int(args.func(args))
    except PsnsHilError as exc:
        _print_error(exc)
        return EXIT_USAGE
    except KeyboardInterrupt:
        return EXIT_FAILED


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
