"""``python -m emulator.cli.dsp_process``: the DSP process of a split run (started by ``psns-hil run --split``).

Not a command for users: the FPGA process (:class:`emulator.distributed.split.SplitFpgaEmulator`) starts it with
the scenario file it wrote, the run's zenoh key and its own zenoh endpoint; :func:`emulator.distributed.split.
run_dsp_process` does the work.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

from ..distributed.split import run_dsp_process

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="python -m emulator.cli.dsp_process",
                                description="run the virtual DSP of a split run (started by psns-hil run --split)")
    p.add_argument("--spec", required=True, help="split-scenario.json written by the FPGA process")
    p.add_argument("--key", required=True, help="zenoh run key")
    p.add_argument("--connect", required=True, help="zenoh endpoint of the FPGA process")
    p.add_argument("--parent-pid", type=int, default=None, help="the FPGA process (its end ends this one)")
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Parse the DSP process's arguments and run it; its exit code (see :func:`run_dsp_process`)."""
    args = build_parser().parse_args(argv)
    return run_dsp_process(Path(args.spec), args.key, args.connect, args.parent_pid)


if __name__ == "__main__":  # pragma: no cover - the DSP process
    sys.exit(main())
