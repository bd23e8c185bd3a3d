"""The project's root conftest: loaded before any test module imports numpy, it pins the numeric baseline
(:mod:`emulator.numeric_baseline`: OpenBLAS's Haswell kernels and numpy's x86-64-v3 loops on x86-64), so that the
golden state histories compare the same arithmetic on every machine."""

from emulator.numeric_baseline import pin

pin()
