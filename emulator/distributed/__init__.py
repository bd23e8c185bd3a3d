"""Distributed runs: the split FPGA/DSP processes and Monte-Carlo campaigns."""
