"""The ``psns-hil`` command line.

``run`` (a scenario; writes ``report.html`` into the run directory at the end), ``validate`` (a
scenario file), ``report`` (write ``report.html`` for a run directory), ``monitor`` (decode a port, a
serial device, a zenoh key or a capture, live), ``replay`` (re-run the firmware on a capture), ``campaign``
(a Monte-Carlo campaign on Dask, :mod:`emulator.cli.campaign`), ``golden`` (check or regenerate the scenario
library's change-indicator records, :mod:`emulator.cli.golden`).
``docs/runtime.md`` and ``docs/scenarios.md`` have them all.

Exit codes: 0 run finished and every expectation passed; 1 an expectation failed, a scheduled
fault never took effect (the run is invalid), the run was interrupted, or a replay differs from
its original; 2 bad input (missing or invalid scenario, bad link URL, unreadable capture) -- one
clear message per problem, no traceback.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import signal
import sys
from collections.abc import Iterator, Sequence
from pathlib import Path
from typing import Any

from protocols import __version__
from protocols.errors import PsnsHilError

from ..errors import STORAGE_ERRNOS, StorageError
from . import export

__all__ = ["main"]

EXIT_OK, EXIT_FAILED, EXIT_USAGE = 0, 1, 2


def _console(stderr: bool = False) -> Any:
    from rich.console import Console

    c = Console(stderr=stderr, highlight=False)
    if not c.is_terminal:
        c.width = 160  # logs and pipes: keep table rows (pty paths) on one line
    return c


def escape_markup(text: Any) -> str:
    """``text`` safe to print through rich with markup on (a scenario key ``[/]`` is text, not a closing tag)."""
    from rich.markup import escape

    return escape(str(text))


def _print_error(exc: PsnsHilError) -> None:
    from ..errors import ScenarioError

    err = _console(stderr=True)
    if isinstance(exc, ScenarioError):
        for issue in exc.issues:
            err.print(f"[bold red]error:[/] {escape_markup(issue)}", markup=True, soft_wrap=True)
    else:
        err.print(f"[bold red]error:[/] {escape_markup(exc)}", markup=True, soft_wrap=True)


def strict_json(obj: Any) -> str:
    """Strict JSON (NaN as null, flagged): :func:`emulator.recording.formatting.strict_json`."""
    from ..recording.formatting import strict_json as _strict

    return _strict(obj)


def _fmt(v: Any, digits: int = 3) -> str:
    """A value on the console: the report's format (emulator/recording/formatting.py ``readable_number``) for
    numbers, ``digits`` decimals for a float given a precision (fault times)."""
    from ..recording.formatting import readable_number

    if isinstance(v, float) and digits != 3 and math.isfinite(v):
        return f"{v:.{digits}f}"
    return readable_number(v)


def print_port_map(ports: list[dict[str, Any]], out: Any = None) -> None:
    """One plain line per port (never wrapped: users copy the pty paths from here); on ``out`` (stdout)."""
    rows = [("port", "role", "baud", "mode", "dir", "endpoint")]
    rows += [(p["name"], p["role"], str(p["baud"]), p["mode"], str(p.get("direction", "")), p["path"])
             for p in ports]
    w = [max(len(r[i]) for r in rows) for i in range(5)]
    out = out if out is not None else sys.stdout
    out.write("ports:\n")
    for r in rows:
        out.write("  " + "  ".join(r[i].ljust(w[i]) for i in range(5)) + "  " + r[5] + "\n")
    out.flush()  # tools waiting for the pty paths must see them now, even through a pipe


def status_line(st: dict[str, Any]) -> str:
    """The realtime status line: sim time, real-time factor, nav frames/s, errors."""
    rtf = st.get("realtime_factor")
    return (f"t = {st['t_s']:8.1f} s   x{rtf if rtf is not None else float('nan'):5.2f} real time   "
            f"nav {st['nav_fps']:6.1f} frames/s   crc errors {st['crc_errors']}   dropped {st['dropped']}   "
            f"framing errors {st['framing_errors']}   deadline misses {st['deadline_misses']}")


def print_summary(s: dict[str, Any]) -> None:
    from rich.table import Table

    c = _console()
    what = "replay" if s.get("replay") else "run"
    head = Table(title=escape_markup(f"psns-hil {what}: {s['scenario']}"), title_justify="left", show_header=False)
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

    c.print("navigation error against truth, over every frame with NAVIGATING set (fine alignment included; "
            "docs/runtime.md 5)", soft_wrap=True)
    err = Table()
    for col in ("quantity", "rms", "max"):
        err.add_column(col, justify="right" if col != "quantity" else "left")
    for k, v in s["nav_error"].items():
        err.add_row(k, _fmt(v["rms"]), _fmt(v["max"]))
    c.print(err)
    phases = s.get("nav_error_by_phase") or {}
    fine, nav = (phases.get(ph, {}).get("position_m", {}).get("rms") for ph in ("fine_alignment", "navigating"))
    if fine is not None or nav is not None:
        def part(v: Any) -> str:
            return "no frame" if v is None else f"{_fmt(v)} m"

        c.print(f"  the position rms split by phase: {part(fine)} during fine alignment (ALIGNING set too: the "
                f"filter still settling), {part(nav)} after it (summary.json nav_error_by_phase)", soft_wrap=True)

    links = Table(title="links", title_justify="left")
    for col in ("link", "bytes", "frames", "crc_errors", "dropped"):
        links.add_column(col, justify="right" if col != "link" else "left")
    for name, v in s["links"].items():
        links.add_row(name, str(v["bytes"]), str(v["frames"]), str(v["crc_errors"]), str(v["dropped"]))
    c.print(links)

    d = s["dsp"]
    ext = s.get("external_dsp")
    if ext is not None:  # the DSP is outside (dsp.external): what it sent, not what it spent
        et = Table(title="external DSP (dsp.external)", title_justify="left")
        for col in ("nav_frames", "garbage_bytes", "crc_errors", "length_errors", "silences", "silent_s"):
            et.add_column(col, justify="right")
        et.add_row(str(ext["nav_frames"]), str(ext["garbage_bytes"]), str(ext["crc_errors"]),
                   str(ext["length_errors"]), str(ext["silences"]), f"{ext['silent_s']:.3f}")
        c.print(et)
    else:
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
        lock = s.get("lockstep")
        if lock is not None:  # a foreign firmware in lockstep (docs/icd.md section 10): what it did and sent
            c.print(escape_markup(
                f"lockstep firmware ({lock['transport']}): {lock['steps']} steps, {lock['idle_steps']} idle, "
                f"host frames {lock['host_frames']}, garbage bytes {lock['garbage_bytes']}, CRC errors "
                f"{lock['crc_errors']}" + (f"; FAILED at {lock['failed_at_s']:.3f} s: {lock['failure']}"
                                           if lock["failed"] else "")))
        if s.get("split") and d.get("deadline_misses"):
            over = d.get("over_budget_ticks")
            c.print("  --split: the DSP process follows the wall clock, so a tick that started late because the "
                    "host scheduled the process late counts as a miss too; "
                    + (f"{over} of the {d['deadline_misses']} were ticks over the cycle budget by themselves "
                       "(dsp.over_budget_ticks), the rest host scheduling jitter or its backlog"
                       if over is not None else "dsp.over_budget_ticks is not known for this DSP"), soft_wrap=True)
    ps = s.get("psns")
    if ps and ps["solar_vector_error_deg"]["median"] is not None:
        e = ps["solar_vector_error_deg"]
        c.print(f"solar vector against truth (psns.csv): median {e['median']:.4g} deg, p95 {e['p95']:.4g} deg, "
                f"max {e['max']:.4g} deg over {ps['solves']} solves")
        az, el = ps.get("azimuth_error_deg") or {}, ps.get("elevation_error_deg") or {}
        if az.get("median") is not None and el.get("median") is not None:
            c.print(f"  of it in azimuth (heading): median {az['median']:.4g} deg, p95 {az['p95']:.4g} deg; "
                    f"in elevation (tilt): median {el['median']:.4g} deg, p95 {el['p95']:.4g} deg")

    if s.get("faults"):
        ft = Table(title="faults", title_justify="left")
        for col in ("#", "fault", "target", "active (s)", "evidence", "took effect"):
            ft.add_column(col)
        for f in s["faults"]:
            span = "-" if f.get("active_from_s") is None else \
                f"{f['active_from_s']:.2f} - {_fmt(f.get('active_until_s'), 2)}"
            ev = ", ".join(f"{k} {v}" for k, v in f.get("evidence", {}).items())
            fired = f.get("fired")
            ft.add_row(str(f["index"]), f["kind"], f["target"], span, ev,
                       "-" if fired is None else "[green]yes[/]" if fired else "[bold red]NO[/]")
        c.print(ft)
    if s.get("expectations"):
        ex = Table(title="expectations", title_justify="left")
        for col in ("#", "check", "value", "result"):
            ex.add_column(col)
        for r in s["expectations"]:
            na = r.get("applicable") is False
            not_run = r.get("status") == "not_run"
            note = f" ({r['message']})" if r.get("message") and (na or not r["passed"]) else ""
            ex.add_row(str(r["index"]), escape_markup(r["description"] + note), escape_markup(_fmt(r["value"])),
                       "[yellow]not run[/]" if not_run else "[dim]not applied[/]" if na else
                       "[green]pass[/]" if r["passed"] else "[bold red]FAIL[/]")
        c.print(ex)
        skipped = [r for r in s["expectations"] if r.get("status") == "not_run"]
        if skipped:
            c.print(f"[yellow]{len(skipped)} python hook expectation(s) not run[/] (neither passed nor failed; "
                    "psns-hil run --allow-hooks runs them): "
                    + ", ".join(f"#{r['index']}" for r in skipped))
    taken = [w for w in s.get("warnings") or [] if w.get("source") == "run"]
    for w in taken:
        c.print(f"[yellow]fallback taken:[/] {escape_markup(w['message'])}", soft_wrap=True)
    if s.get("valid") is False:
        for f in s.get("faults", []):
            if f.get("fired") is False:
                c.print(f"[bold red]run invalid:[/] fault #{f['index']} {f['kind']} on {f['target']} never took "
                        f"effect (evidence: {', '.join(f'{k} {v}' for k, v in f['evidence'].items()) or 'none'})")


def _cmd_validate(args: argparse.Namespace) -> int:
    from ..dsp.firmware_setup import check_firmware
    from ..scenario import load_scenario

    scn = load_scenario(args.scenario, args.set or ())
    # the firmware side, as a run would build it (issue 41): the named filter plugin is a NavFilter, the firmware
    # plugin a factory, the spec sheet reads and validates; only the named plugins are imported, nothing runs
    check_firmware(scn)
    if getattr(args, "effective", False):
        # what a run builds from (emulator.scenario.resolved): the envelope's draw for the seed, every sensor preset
        # merged with the file's overrides, every port's URL parsed; the same function the run calls
        from ..assembly.build import resolve_run

        print(json.dumps(resolve_run(scn, args.seed).as_dict(), indent=2))
    elif args.json:
        print(scn.model_dump_json(indent=2, exclude_none=True))
    else:
        _console().print(f"{args.scenario}: ok ({scn.name}, {scn.duration_s:g} s, mode {scn.mode})")
    _print_scenario_warnings(scn)
    return EXIT_OK


def _check_firmware_allowed(scn: Any, allow: bool) -> None:
    """A scenario naming a lockstep firmware (docs/icd.md section 10) runs only with ``--allow-firmware``, which
    lets this process (and nothing else) load or start it."""
    from ..dsp.lockstep import ALLOW_FIRMWARE_ENV, FirmwareNotAllowed

    ext = scn.dsp.external
    lock = ext.lockstep if ext is not None else None
    if lock is None:
        return
    if not allow:
        what = f"library {lock.library}" if lock.library is not None else f"program {lock.command[0]}"
        raise FirmwareNotAllowed(f"{scn.source_file}: dsp.external.lockstep names a foreign firmware ({what}); "
                                 "running it loads native code or starts a process: pass --allow-firmware to run "
                                 "it (only for a firmware you trust)")
    os.environ[ALLOW_FIRMWARE_ENV] = "1"


def _print_scenario_warnings(scn: Any) -> None:
    """The scenario's fallbacks (emulator/assembly/fallbacks.py), one ``warning: file:line:col: path: message``
    line each, on stderr (the exit code stays 0: a warning is not an error)."""
    from ..assembly.fallbacks import scenario_warnings

    err = _console(stderr=True)
    for w in scenario_warnings(scn):
        err.print(f"[yellow]warning:[/] {escape_markup(str(w))}", soft_wrap=True)


def _cmd_run(args: argparse.Namespace) -> int:
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from ..assembly.ports import real_time_ports, resolve_mode
    from ..assembly.session import default_run_dir, run_scenario
    from ..errors import EmulatorError
    from ..scenario import load_scenario
    from ..scenario.paths import ALLOW_HOOKS_ENV

    if getattr(args, "allow_hooks", False):  # the run (and a --split DSP process) may import the scenario's hooks
        os.environ[ALLOW_HOOKS_ENV] = "1"
    scn = load_scenario(args.scenario, args.set or ())
    _check_firmware_allowed(scn, getattr(args, "allow_firmware", False))
    mode = resolve_mode(scn, "realtime" if args.realtime else "fast" if args.fast else None)
    real = real_time_ports(scn)
    if mode == "fast" and real and not args.fast and not getattr(args, "split", False):
        raise EmulatorError(f"{args.scenario}: mode fast with a real peer on {', '.join(real)}: in virtual time a "
                            "tool on that port would see frames far faster than the line's rate; pass --realtime "
                            "(what a peer expects) or --fast to run in virtual time anyway")
    if getattr(args, "split", False):
        if args.fast:
            raise EmulatorError("--split runs the DSP in another process on the wall clock: it cannot be --fast")
        mode = "realtime"
    run_dir = Path(args.out) if args.out else default_run_dir(scn.name)
    from ..recording.rundir import preflight_run_dir

    preflight_run_dir(run_dir, force=bool(getattr(args, "force", False)))  # refused --out: no "running ..." first
    console = _console(stderr=args.json)  # --json: stdout carries the one JSON document, nothing else
    _print_scenario_warnings(scn)
    speed = args.speed if args.speed is not None else scn.speed
    console.print(f"psns-hil {__version__}: running {args.scenario} ({scn.duration_s:g} s, {mode}"
                  + (f" x{speed:g}" if mode == "realtime" else "") + f") -> {run_dir}")
    realtime = mode == "realtime"
    show_progress = not args.quiet and console.is_terminal and not realtime
    progress = Progress(TextColumn("{task.description}"), BarColumn(),
                        TextColumn("{task.fields[t]:.1f}/{task.total:.0f} s"), TimeElapsedColumn(),
                        console=console, transient=True, disable=not show_progress)
    task = progress.add_task("simulating", total=scn.duration_s, t=0.0)
    err = sys.stderr
    tty = err.isatty()
    status_every = args.status if args.status is not None else (1.0 if tty else 5.0)
    state: dict[str, Any] = {"emu": None, "next": status_every}

    def on_progress(t: float, total: float) -> None:
        progress.update(task, completed=t, t=t)
        emu = state["emu"]
        if not realtime or args.quiet or emu is None or status_every <= 0 or t + 1e-9 < state["next"]:
            return
        state["next"] = t + status_every
        line = status_line(emu.status())
        if tty:
            err.write("\r" + line + "\x1b[K")
        else:
            err.write(line + "\n")
        err.flush()

    def on_started(emu: Any) -> None:
        state["emu"] = emu
        export.on_started(args, emu)  # the live Foxglove view (issue 39)
        print_port_map(emu.ports, sys.stderr if args.json else None)

    with progress:
        if getattr(args, "split", False):
            from ..distributed.split import run_split

            summary = run_split(scn, run_dir, speed=speed, seed=args.seed, progress=on_progress,
                                on_started=on_started)
        else:
            summary = run_scenario(scn, run_dir, mode=mode, speed=speed, seed=args.seed,
                                   progress=on_progress, on_started=on_started, force=args.force)
    if realtime and tty and not args.quiet:
        err.write("\n")
    after = _AfterRun()  # a signal from here on: the report is dropped, the run's files are complete (exit 1)
    report = None
    if not after.signals:
        try:
            with after.armed():
                export.after_run(args, run_dir)  # the viewer outputs: raw sensor tables, run.mcap (issue 39)
                if not args.no_report and (run_dir / "summary.json").exists():
                    from ..postrun.report import write_report

                    report = write_report(run_dir)
        except _AfterRunInterrupted:
            report = None
        except OSError as exc:
            if exc.errno not in STORAGE_ERRNOS:
                raise
            raise StorageError(f"{run_dir}: the run finished (summary.json and captures written) but its report "
                               f"could not be written: {exc.strerror or exc} (errno {exc.errno})") from None
    if args.json:
        print(strict_json(summary))
    else:
        print_summary(summary)
        if report is not None:
            console.print(f"report: {report}")
    if after.signals:
        console.print(f"[yellow]psns-hil run: interrupted after the run ended: summary.json and the captures are "
                      f"complete; {'report.html was written' if report is not None else 'no report was written'}"
                      f" (psns-hil report {escape_markup(str(run_dir))} writes it)[/]")
        return EXIT_FAILED
    if summary.get("interrupted"):
        console.print("[yellow]run interrupted; captures and summary were kept[/]")
        return EXIT_FAILED
    lock = summary.get("lockstep")
    if lock is not None and lock.get("failed"):
        console.print(escape_markup(f"lockstep firmware failed at t = {lock['failed_at_s']:.3f} s: {lock['failure']} "
                                    f"(the DSP was silent from then on; run directory {run_dir} written)"),
                      style="bold red")
        return EXIT_FAILED
    return EXIT_OK if summary.get("passed", True) else EXIT_FAILED


class _AfterRunInterrupted(BaseException):
    """SIGINT / SIGTERM while the report of a finished run is written (a BaseException: no ``except Exception``
    in matplotlib or an exporter swallows it)."""


class _AfterRun:
    """SIGINT and SIGTERM once ``psns-hil run``'s run has returned, until the process exits (docs/hostile-input.md
    section 8). Before (issue 41): the run restored Python's default handlers, so the first Ctrl-C while the report
    was written said "interrupted again" and one after ``report.html`` existed ended the process with rc -2 (or a
    traceback from the interpreter's exit handlers with rc 0). Now every such signal is remembered (the command
    then exits 1 saying that the run's files are complete); while :meth:`armed` it also abandons the report, which
    is written aside and renamed, so no partial page is left. The handlers stay installed through the
    interpreter's shutdown. A signal that came between the run's end and this object (``early_signals.PENDING``)
    counts as well."""

    def __init__(self) -> None:
        from .. import early_signals

        self.signals: list[int] = list(early_signals.PENDING)
        early_signals.PENDING.clear()
        self._armed = False
        for sig in (signal.SIGINT, signal.SIGTERM):
            with contextlib.suppress(ValueError, OSError):  # not the main thread: nothing to install
                signal.signal(sig, self._on_signal)

    def _on_signal(self, signum: int, _frame: Any) -> None:
        self.signals.append(signum)
        if self._armed:
            self._armed = False
            with contextlib.suppress(OSError, ValueError):
                sys.stderr.write("\npsns-hil run: interrupted while writing the report: report.html is not written; "
                                 "the run's summary and captures are complete\n")
                sys.stderr.flush()
            raise _AfterRunInterrupted

    @contextlib.contextmanager
    def armed(self) -> Iterator[None]:
        self._armed = True
        try:
            yield
        finally:
            self._armed = False


def _cmd_report(args: argparse.Namespace) -> int:
    from ..postrun.report import write_report
    from ..recording.summary_model import load_summary

    run_dir = Path(args.run_dir)
    if not run_dir.exists():
        from ..errors import RecordingError

        raise RecordingError(f"{run_dir}: no such run directory")
    load_summary(run_dir)  # a run directory with a valid summary, or exit 2 saying what is wrong
    out = write_report(run_dir)
    _console().print(f"report: {out}")
    return EXIT_OK


def _cmd_monitor(args: argparse.Namespace) -> int:
    from .monitor import run_monitor

    stats = run_monitor(args.endpoint, protocol=args.protocol, baud=args.baud, links=args.link or None,
                        count=args.count, duration_s=args.duration, as_json=args.json, port_name=args.port)
    cap = stats.get("capture")
    if cap and (cap["bad_time_records"] or cap["backward_time_records"]):  # always said, not only with --stats
        print(f"warning: {args.endpoint}: {cap['bad_time_records']} record(s) with a time that is not finite or "
              f"negative, {cap['backward_time_records']} going back in time within their link and direction",
              file=sys.stderr)  # one line, never wrapped
    if args.stats:
        err = _console(stderr=True)
        err.print(f"{stats['frames']} frames")
        for key, st in stats["decoders"].items():
            err.print(f"  {key}: frames {st['frames']}, crc errors {st['crc_errors']}, "
                      f"garbage bytes {st['garbage_bytes']}, resyncs {st['resyncs']}, "
                      f"frames with non-finite values {st['nonfinite_frames']}")
    return EXIT_OK


def _cmd_replay(args: argparse.Namespace) -> int:
    from ..assembly.session import default_run_dir
    from ..postrun.replay import run_replay

    cap = Path(args.capture)
    if not cap.exists():
        from ..errors import RecordingError

        raise RecordingError(f"{cap}: no such capture file")
    run_dir = Path(args.out) if args.out else default_run_dir(cap.parent.name + "-replay")
    mode = "realtime" if args.realtime else "fast"
    console = _console(stderr=args.json)
    console.print(f"psns-hil {__version__}: replaying {cap} ({mode}) -> {run_dir}")
    summary = run_replay(cap, run_dir, mode=mode, speed=args.speed or 1.0, force=args.force)
    if args.json:
        print(strict_json(summary))
    else:
        print_summary(summary)
        console.print(f"replayed {summary['replay']['records']} captured DSP UART records")
    original = Path(args.compare) if args.compare else cap.parent
    rep = summary.get("replay") or {}
    if rep.get("bad_time_records") or rep.get("backward_time_records"):
        console.print(f"[yellow]the capture's time stamps are damaged: {rep['bad_time_records']} record(s) with a time "
                      f"that is not finite or negative (dropped), {rep['backward_time_records']} going back in time "
                      f"(delivered at the previous record's time); replayed {rep['records']} of "
                      f"{rep['records_in_capture']} DSP UART records[/]")
    if rep.get("truncated"):
        console.print(f"[yellow]the capture is truncated: it holds {rep['captured_s']:.3f} s of the scenario's "
                      f"{rep['scenario_duration_s']:g} s; replayed that much[/]")
    na = [r for r in summary.get("expectations", []) if r.get("applicable") is False]
    if na:
        console.print(f"{len(na)} expectation(s) not applicable to a replay (not counted)")
    rc = EXIT_OK if summary.get("passed", True) else EXIT_FAILED
    if (original / "nav.csv").exists():
        from ..postrun.replay import compare_nav

        cmp = compare_nav(original / "nav.csv", run_dir / "nav.csv")
        same = bool(cmp["identical"])
        detail = ""
        if not same:
            ra, rb = cmp["rows"]
            detail = (" (only the arrival times differ: the solutions are identical)" if cmp["only_arrival"] else
                      f" (differing columns: {', '.join(cmp['differing_columns']) or 'none'}"
                      + (f"; rows {ra} vs {rb}" if ra != rb else "") + ")")
        console.print(f"nav.csv identical to {original / 'nav.csv'}: {'yes' if same else '[bold red]no[/]'}"
                      + escape_markup(detail))
        if args.compare and not same:
            rc = EXIT_FAILED
    return rc


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="psns-hil", description="PSNS/GNSS/SINS navigation computer HIL emulator")
    p.add_argument("--version", action="version", version=f"psns-hil {__version__}")
    sub = p.add_subparsers(dest="command", required=True)

    r = sub.add_parser("run", help="run a scenario")
    r.add_argument("scenario", help="scenario YAML file")
    r.add_argument("--out", help="run directory (default runs/<scenario>-<UTC time>); a new or empty directory")
    r.add_argument("--force", action="store_true",
                   help="replace a finished run in --out (its contents are removed first)")
    m = r.add_mutually_exclusive_group()
    m.add_argument("--realtime", action="store_true",
                   help="follow the wall clock (default: the scenario's mode; realtime when a port is pty/serial)")
    m.add_argument("--fast", action="store_true", help="virtual time, as fast as the CPU allows")
    r.add_argument("--speed", type=float, default=None, help="real-time scale factor in realtime mode")
    r.add_argument("--status", type=float, default=None, metavar="S",
                   help="realtime status line every S simulated seconds (default 1 on a terminal, 5 otherwise; 0 off)")
    r.add_argument("--seed", type=int, default=None, help="override the scenario's seed")
    r.add_argument("--set", action="append", metavar="KEY=VALUE",
                   help="override one scenario value, validated like the file (repeatable): --set duration_s=30, "
                        "--set links.host.url=pty://uart0, --set faults.0.start_s=12")
    r.add_argument("--json", action="store_true",
                   help="print the summary as one strict JSON document on stdout (everything else on stderr)")
    r.add_argument("--quiet", action="store_true", help="no progress bar")
    r.add_argument("--no-report", action="store_true", help="do not write report.html at the end")
    export.add_run_arguments(r)
    r.add_argument("--split", action="store_true",
                   help="run the virtual DSP in its own process, joined to the FPGA over zenoh (realtime)")
    r.add_argument("--allow-hooks", action="store_true",
                   help="import and run the scenario's Python expectation hooks (expectations[].python): only for "
                        "a scenario you trust, they run any code (docs/hostile-input.md)")
    r.add_argument("--allow-firmware", action="store_true",
                   help="load the scenario's lockstep firmware library or start its firmware process "
                        "(dsp.external.lockstep, docs/icd.md section 10): only for a firmware you trust")
    r.set_defaults(func=_cmd_run)

    rep = sub.add_parser("report", help="write report.html (plots of errors, modes, faults, links, DSP load) "
                                        "for a run directory")
    rep.add_argument("run_dir", help="a run directory (with summary.json, nav.csv, events.jsonl, timeline.csv)")
    rep.set_defaults(func=_cmd_report)

    v = sub.add_parser("validate", help="check a scenario file and report every problem")
    v.add_argument("scenario")
    v.add_argument("--set", action="append", metavar="KEY=VALUE", help="override one value, as for run (repeatable)")
    v.add_argument("--json", action="store_true",
                   help="print the validated scenario with defaults (keys left unset, null, are omitted)")
    v.add_argument("--effective", action="store_true",
                   help="print, as JSON, the resolved configuration a run is built from: each sensor's preset merged "
                        "with the file's overrides, each port's URL parsed, the routing, the time mode, the "
                        "envelope's draws")
    v.add_argument("--seed", type=int, default=None, help="with --effective: the run's seed (default the scenario's)")
    v.set_defaults(func=_cmd_validate)

    mo = sub.add_parser("monitor", help="decode a port live (pty, serial device, zenoh key), a capture file or a "
                                        "byte dump into frames")
    mo.add_argument("endpoint", help="capture file (.psnscap), a plain file of a port's bytes, pty/serial device "
                                     "path, serial:///dev/ttyXXX, or zenoh://RUN/PORT[?connect=tcp/HOST:PORT] "
                                     "(default connect tcp/127.0.0.1:7447)")
    mo.add_argument("--protocol", default="auto",
                    help="decoders: auto (by port name) or a comma list of host, imu, stim210[:FMT], nmea, psns, "
                         "ubx, monitor")
    mo.add_argument("--baud", type=int, default=460800, help="baud for a serial device (ptys ignore it); a byte "
                                                              "dump's time base")
    mo.add_argument("--port", help="port name for auto decoding when the path's name does not tell it")
    mo.add_argument("--link", action="append", help="capture files: only this link (repeatable)")
    mo.add_argument("--count", type=int, help="stop after N frames")
    mo.add_argument("--duration", type=float, help="stop after S wall-clock seconds (live endpoints)")
    mo.add_argument("--json", action="store_true", help="one JSON object per frame")
    mo.add_argument("--stats", action="store_true", help="print the decoder statistics at the end (stderr)")
    mo.set_defaults(func=_cmd_monitor)

    rp = sub.add_parser("replay", help="re-run the firmware on a capture's DSP UART input")
    rp.add_argument("capture", help="capture.psnscap of an earlier run")
    rp.add_argument("--out", help="run directory (default runs/<capture dir>-replay-<UTC time>)")
    rp.add_argument("--force", action="store_true",
                    help="replace a finished run in --out (its contents are removed first)")
    rp.add_argument("--realtime", action="store_true", help="replay in real time (default: fast)")
    rp.add_argument("--speed", type=float, default=None, help="real-time scale factor")
    rp.add_argument("--compare", metavar="RUN_DIR",
                    help="exit 1 unless nav.csv equals RUN_DIR/nav.csv (default: just report against the "
                         "capture's own directory)")
    rp.add_argument("--json", action="store_true", help="print the summary as JSON")
    rp.set_defaults(func=_cmd_replay)

    from . import campaign, diff_firmware, golden, sweep

    campaign.add_parser(sub).set_defaults(func=campaign.run)
    sweep.add_parser(sub).set_defaults(func=sweep.run)
    golden.add_parser(sub).set_defaults(func=golden.run)
    diff_firmware.add_parser(sub).set_defaults(func=diff_firmware.run)
    export.add_parser(sub).set_defaults(func=export.run)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if argv is None and args.command == "run":  # catch SIGINT/SIGTERM before any work (docs/hostile-input.md)
        from ..early_signals import install

        install()  # (already done by emulator.cli for the usual entry points)
    if getattr(args, "speed", None) is not None and args.speed <= 0:
        parser.error("--speed must be > 0")
    if hasattr(signal, "SIGXFSZ"):  # a file at the size limit (ulimit -f): EFBIG, reported below, not a kill
        with contextlib.suppress(ValueError, OSError):
            signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
    try:
        return int(args.func(args))
    except BrokenPipeError:
        # the reader went away (``psns-hil validate --json | head``): what it wanted it has; no traceback. Point
        # stdout at /dev/null so that the interpreter's final flush does not raise again.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        return EXIT_OK
    except PsnsHilError as exc:
        _print_error(exc)
        return EXIT_USAGE
    except OSError as exc:
        if exc.errno not in STORAGE_ERRNOS:
            raise
        # the machine, not the input: disk full, file-size limit, read-only or forbidden output (one line, no
        # traceback; the run command says more about what it kept)
        where = f"{exc.filename}: " if exc.filename else ""
        _print_error(StorageError(f"{where}cannot write: {exc.strerror or exc} (errno {exc.errno})"))
        return EXIT_USAGE
    except KeyboardInterrupt:
        # the first Ctrl-C of a run is handled by the run (it stops and keeps its data; after the run, _AfterRun);
        # one that gets here during `run` is a second one; in another command (report, monitor) the first
        if args.command == "run":
            sys.stderr.write("\npsns-hil run: interrupted again: stopped at once without finishing; the run "
                             "directory may lack its summary and report (captures written so far are kept)\n")
        else:
            sys.stderr.write(f"\npsns-hil {args.command}: interrupted\n")
        return EXIT_FAILED


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
