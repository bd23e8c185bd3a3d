"""The command line: ``psns-hil`` (:func:`main`: run, validate, report, monitor, replay, campaign, golden) and
the DSP process of a split run (:mod:`emulator.cli.dsp_process`). No other package parses arguments."""

from ..early_signals import install_for_cli
from ..numeric_baseline import pin

install_for_cli()  # before the heavy imports: a SIGTERM during start-up still leaves an interrupted run
pin()  # before numpy loads: the same numbers on every x86-64 machine (emulator.numeric_baseline)

from .main import main  # noqa: E402

__all__ = ["main"]
