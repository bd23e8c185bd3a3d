"""Emulated devices: sensors that turn truth into bytes, the virtual FPGA and DSP."""
