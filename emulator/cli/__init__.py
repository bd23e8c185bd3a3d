"""The command line: ``psns-hil`` (:func:`main`: run, validate, report, monitor, replay, campaign, golden) and
the DSP process of a split run (:mod:`emulator.cli.dsp_process`). No other package parses arguments."""

from .main import main

__all__ = ["main"]
