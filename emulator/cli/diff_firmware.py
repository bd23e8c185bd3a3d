"""``psns-hil diff-firmware SCENARIO --out DIR (--library PATH | --command "PROG ARGS" | --reference-server)
--allow-firmware``: run a scenario once with the built-in firmware and once with a foreign one in lockstep, on the
same seeded world, and report where their outputs diverge (:mod:`emulator.verification.firmware_diff`).

``DIR/reference`` and ``DIR/foreign`` are the two run directories, ``DIR/diff.json`` the comparison. Exit 0: the
navigation output is identical frame for frame; 1: it differs (or the foreign firmware failed); 2: a usage error
(no ``--allow-firmware``, a bad scenario). The firmware is named on the command line, so it is trusted like the
command itself: its directory is added to the allowed paths of this process (``PSNS_HIL_ALLOW_PATHS``).
``--reference-server`` runs the built-in firmware itself behind the out-of-process interface
(``python -m emulator.dsp.lockstep_server``): the check of the check (zero differences), and with ``--perturb
FIELD:AFTER:DELTA`` a known change the report must find at its first frame.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import shutil
import sys
from pathlib import Path
from typing import Any

__all__ = ["add_parser", "diff_firmware", "run"]


def add_parser(sub: Any) -> argparse.ArgumentParser:
    """Register ``psns-hil diff-firmware`` on an argparse sub-parser collection."""
    d: argparse.ArgumentParser = sub.add_parser(
        "diff-firmware", help="run a scenario with the built-in firmware and with a foreign one in lockstep, and "
                              "report where their navigation output diverges",
        description=(__doc__ or "").split("\n\n")[0])
    d.add_argument("scenario", help="scenario YAML file")
    d.add_argument("--out", required=True, help="directory for reference/, foreign/ and diff.json")
    d.add_argument("--force", action="store_true", help="replace an earlier comparison in --out")
    which = d.add_mutually_exclusive_group(required=True)
    which.add_argument("--library", help="the foreign firmware as a lockstep shared library (in-process)")
    which.add_argument("--command", help="the foreign firmware as a lockstep program and its arguments, one string "
                                         "(out-of-process)")
    which.add_argument("--reference-server", action="store_true",
                       help="the built-in firmware behind the out-of-process interface (zero differences expected)")
    d.add_argument("--perturb", metavar="FIELD:AFTER:DELTA",
                   help="with --reference-server: add DELTA to NAV_SOLUTION field FIELD of every frame after the "
                        "AFTER-th (a known change)")
    d.add_argument("--step-timeout", type=float, default=10.0, help="out-of-process: wall-clock s per reply")
    d.add_argument("--seed", type=int, default=None, help="override the scenario's seed (both runs)")
    d.add_argument("--set", action="append", metavar="KEY=VALUE", help="override one scenario value (both runs)")
    d.add_argument("--allow-firmware", action="store_true",
                   help="load or start the foreign firmware (required: it runs native code or a process)")
    d.add_argument("--json", action="store_true", help="print diff.json on stdout")
    return d


def _foreign_spec(args: argparse.Namespace, scenario: Path) -> tuple[dict[str, Any], list[Path]]:
    """The ``dsp.external.lockstep`` of the foreign run and the directories it needs allowed."""
    if args.library:
        lib = Path(args.library).resolve()
        return {"library": str(lib)}, [lib.parent]
    if args.command:
        argv = shlex.split(args.command)
        prog = Path(argv[0]) if "/" in argv[0] else Path(shutil.which(argv[0]) or argv[0])
        prog = prog.absolute()
        return {"command": [str(prog), *argv[1:]], "step_timeout_s": args.step_timeout}, [prog.parent,
                                                                                           prog.resolve().parent]
    exe = Path(sys.executable)
    argv = [str(exe), "-m", "emulator.dsp.lockstep_server", str(scenario.resolve())]
    if args.seed is not None:
        argv += ["--seed", str(args.seed)]
    for s in args.set or ():
        argv += ["--set", s]
    if args.perturb:
        argv += ["--perturb", args.perturb]
    return {"command": argv, "step_timeout_s": args.step_timeout}, [exe.parent, exe.resolve().parent]


def diff_firmware(args: argparse.Namespace) -> dict[str, Any]:
    """Both runs and the comparison (see module docstring); the report (also written to ``--out/diff.json``)."""
    from ..assembly.session import run_scenario
    from ..dsp.lockstep import ALLOW_FIRMWARE_ENV, FirmwareNotAllowed
    from ..errors import EmulatorError
    from ..scenario import load_scenario
    from ..scenario.paths import ALLOW_PATHS_ENV
    from ..scenario.runtime_schema import ExternalDspSpec, LockstepSpec
    from ..verification.firmware_diff import compare_nav_frames

    if args.perturb and not args.reference_server:
        raise EmulatorError("--perturb changes the reference server's output: use it with --reference-server")
    if args.perturb:
        from ..dsp.lockstep_server import perturber

        try:
            perturber(args.perturb)
        except (ValueError, KeyError) as exc:
            raise EmulatorError(f"--perturb {args.perturb!r}: FIELD:AFTER:DELTA with a NAV_SOLUTION field "
                                f"({exc})") from exc
    if not args.allow_firmware:
        raise FirmwareNotAllowed("diff-firmware loads or starts a foreign firmware (native code or a process): pass "
                                 "--allow-firmware (only for a firmware you trust)")
    scenario = Path(args.scenario)
    scn = load_scenario(scenario, args.set or ())
    out = Path(args.out)
    if out.exists() and any(out.iterdir()):
        if not args.force:
            raise EmulatorError(f"{out} is not empty: pass --force to replace the earlier comparison")
        shutil.rmtree(out)
    out.mkdir(parents=True, exist_ok=True)
    spec, allow_dirs = _foreign_spec(args, scenario)
    os.environ[ALLOW_FIRMWARE_ENV] = "1"
    extra = os.pathsep.join(str(p) for p in allow_dirs)
    old = os.environ.get(ALLOW_PATHS_ENV, "")
    os.environ[ALLOW_PATHS_ENV] = f"{old}{os.pathsep}{extra}" if old else extra
    ref_scn = scn.model_copy(update={"dsp": scn.dsp.model_copy(update={"external": None})})
    ext = ExternalDspSpec(lockstep=LockstepSpec(**spec))
    foreign_scn = scn.model_copy(update={"dsp": scn.dsp.model_copy(update={"external": ext})})
    s_ref = run_scenario(ref_scn, out / "reference", mode="fast", seed=args.seed)
    s_for = run_scenario(foreign_scn, out / "foreign", mode="fast", seed=args.seed)
    rep = compare_nav_frames(out / "reference" / "nav.csv", out / "foreign" / "nav.csv")
    lock = s_for.get("lockstep") or {}
    rep["foreign_firmware"] = {"spec": spec, "failed": lock.get("failed"), "failure": lock.get("failure"),
                               "transport": lock.get("transport")}
    rep["cycles"] = {"reference": s_ref["dsp"]["tasks"], "foreign": s_for["dsp"]["tasks"]}
    rep["deadline_misses"] = {"reference": s_ref["dsp"]["deadline_misses"],
                              "foreign": s_for["dsp"]["deadline_misses"]}
    (out / "diff.json").write_text(json.dumps(rep, indent=2, default=str) + "\n")
    return rep


def run(args: argparse.Namespace) -> int:
    """``psns-hil diff-firmware``: 0 identical, 1 differences or a failed firmware."""
    from rich.console import Console
    from rich.table import Table

    rep = diff_firmware(args)
    if args.json:
        print(json.dumps(rep, indent=2, default=str))
    con = Console(stderr=args.json)
    fr = rep["frames"]
    con.print(f"frames: reference {fr['reference']}, foreign {fr['foreign']}; paired by time_s and compared "
              f"{fr['compared']} on {len(rep['columns_compared'])} fields (missing in the foreign run "
              f"{fr['missing_in_foreign']}, in the reference {fr['missing_in_reference']}); diff.json in {args.out}")
    ff = rep["foreign_firmware"]
    if ff.get("failed"):
        con.print(f"[bold red]the foreign firmware failed:[/] {ff['failure']}")
    if rep["identical"]:
        arr = rep.get("arrival") or {}
        con.print("[green]identical navigation output, frame for frame[/]"
                  + (f" (arrival times differ by up to {arr['max_abs_diff_s'] * 1e6:.1f} us)"
                     if arr.get("max_abs_diff_s") else ""))
        return 1 if ff.get("failed") else 0
    first = rep["first_difference"]
    con.print(f"[bold red]first difference at frame {first['frame']}[/] (time_s {first['time_s']})"
              + (f": the {first['missing_in']} run has no such frame" if first.get("missing_in") else ""))
    if not rep["fields"]:
        return 1
    t = Table(title="per field", title_justify="left")
    for c in ("field", "first frame", "first time_s", "frames differing", "max |diff|"):
        t.add_column(c, justify="left" if c == "field" else "right")
    for name, f in sorted(rep["fields"].items(), key=lambda kv: kv[1]["first_frame"]):
        t.add_row(name, str(f["first_frame"]), str(f["first_time_s"]), str(f["frames_differing"]),
                  f"{f['max_abs_diff']:.6g}")
    con.print(t)
    per = rep["max_abs_diff_per_second"]
    if per:
        names = sorted({k for v in per.values() for k in v})
        ts = Table(title="largest difference per second of scenario time", title_justify="left")
        ts.add_column("second", justify="right")
        for n in names:
            ts.add_column(n, justify="right")
        for sec, v in per.items():
            ts.add_row(sec, *(f"{v[n]:.3g}" if n in v else "-" for n in names))
        con.print(ts)
    return 1
