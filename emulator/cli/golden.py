"""``psns-hil golden [NAME ...] [--update]``: check or regenerate the change-indicator records of the scenario
library (:mod:`emulator.postrun.golden`).

Each named scenario (default: every file of the library) runs in fast mode in a temporary directory; without
``--update`` its record is compared with ``tests/golden/`` and the differences are printed (exit 1 when any
scenario changed), with ``--update`` the record is rewritten (review and commit the diff). Exit 2: an unknown
scenario name.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path
from typing import Any

from ..postrun.golden import GOLDEN_DIR, LIBRARY_DIR, ROOT, compare_golden, library, write_golden

__all__ = ["add_parser", "run"]


def add_parser(sub: Any) -> argparse.ArgumentParser:
    """Register ``psns-hil golden`` on an argparse sub-parser collection."""
    g: argparse.ArgumentParser = sub.add_parser(
        "golden", help="check (default) or regenerate (--update) the scenario library's golden records",
        description="check (default) or regenerate (--update) the change-indicator records of the scenario "
                    "library in tests/golden/")
    g.add_argument("names", nargs="*", help="scenario names (default: every file in scenarios/)")
    g.add_argument("--update", action="store_true", help="rewrite the golden files from fresh runs")
    g.add_argument("--library", default=str(LIBRARY_DIR), help="scenario directory")
    g.add_argument("--golden", default=str(GOLDEN_DIR), help="golden directory")
    return g


def run(args: argparse.Namespace) -> int:
    """``psns-hil golden``: 0 unchanged (or updated), 1 some scenario changed, 2 an unknown scenario."""
    from ..assembly.session import run_scenario
    from ..scenario import load_scenario

    gdir = Path(args.golden)
    files = library(Path(args.library))
    scns = [(p, load_scenario(p)) for p in files]
    if args.names:
        known = {s.name for _, s in scns}
        unknown = [n for n in args.names if n not in known]
        if unknown:
            print(f"unknown scenario(s): {', '.join(unknown)}; the library has {', '.join(sorted(known))}",
                  file=sys.stderr)
            return 2
        scns = [(p, s) for p, s in scns if s.name in args.names]
    from ..numeric_baseline import describe, pinned

    if args.update and not pinned():
        print(f"warning: recording without the pinned numeric baseline ({describe()}): other machines will find "
              "the state histories changed (emulator.numeric_baseline)", file=sys.stderr)
    rc = 0
    for _path, scn in scns:
        with tempfile.TemporaryDirectory(prefix=f"golden-{scn.name}-") as d:
            summary = run_scenario(scn, Path(d) / "run", mode="fast")
            if args.update:
                ps, pi = write_golden(Path(d) / "run", scn.name, scn.seed, scn.duration_s, gdir)
                print(f"{scn.name}: wrote {ps.relative_to(ROOT) if ps.is_relative_to(ROOT) else ps} "
                      f"({ps.stat().st_size} bytes) and {pi.name} ({pi.stat().st_size} bytes); "
                      f"{summary['wall_s']:.1f} s wall")
            else:
                diffs = compare_golden(Path(d) / "run", scn.name, scn.seed, scn.duration_s, gdir)
                print(f"{scn.name}: {'unchanged' if not diffs else 'CHANGED'}")
                for line in diffs:
                    print(f"  {line}")
                rc = rc or (1 if diffs else 0)
    return rc
