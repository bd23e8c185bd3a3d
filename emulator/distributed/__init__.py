"""Distributed runs: the split FPGA/DSP processes (:mod:`.split`) and Monte-Carlo campaigns
(:mod:`~emulator.distributed.campaign`)."""
