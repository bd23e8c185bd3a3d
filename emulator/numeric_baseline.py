"""One numeric baseline, so that a scenario and a seed give the same numbers on every x86-64 machine.

numpy hands the firmware's matrix products (the Kalman filter's 21x21 predict and updates) to OpenBLAS, whose
kernel is chosen at start-up by the CPU: on an AVX-512 Intel machine ``SkylakeX``, on an AMD EPYC with AVX-512
``Haswell``, and each kernel sums in its own order. The roundings differ in the last bit, and a closed-loop filter
carries such differences on in its weakly observable states: between the two kernels the library's golden state
histories differ by up to 1.5e-3 relative in the covariance and 5e-3 in a gyro-bias estimate near zero
(docs/decisions/scenarios.md D-8.8), while the captured sensor bytes stay identical. numpy's own loops also
dispatch by CPU (x86-64-v3 or v4 kernels).

:data:`BASELINE_ENV` pins both to what every x86-64-v3 machine (AVX2 + FMA, Intel Haswell / AMD Zen and newer)
runs: OpenBLAS's ``Haswell`` kernels and numpy's x86-64-v3 loops. :func:`pin` sets it (``os.environ.setdefault``:
a value the user set wins) and must run before numpy is imported: the ``psns-hil`` command line, the project's
root ``conftest.py`` and so ``make test`` / ``make golden`` do; a campaign's Dask workers inherit it. Set
``PSNS_HIL_NUMERICS=native`` to keep the machine's own kernels. This module imports nothing heavy.
"""

from __future__ import annotations

import os
import platform
import sys

__all__ = ["BASELINE_ENV", "describe", "pin", "pinned"]

#: environment of the baseline (x86-64 only; elsewhere nothing is pinned)
BASELINE_ENV = {"OPENBLAS_CORETYPE": "Haswell", "NPY_DISABLE_CPU_FEATURES": "X86_V4 AVX512_ICL AVX512_SPR"}


def _x86_64() -> bool:
    return platform.machine().lower() in ("x86_64", "amd64")


def pin() -> bool:
    """Set :data:`BASELINE_ENV` unless numpy is already loaded, the machine is not x86-64 or
    ``PSNS_HIL_NUMERICS=native``; True when the baseline is (now) in the environment."""
    if os.environ.get("PSNS_HIL_NUMERICS", "").lower() == "native" or not _x86_64() or "numpy" in sys.modules:
        return pinned()
    for k, v in BASELINE_ENV.items():
        os.environ.setdefault(k, v)
    return pinned()


def pinned() -> bool:
    """Whether this process's environment holds the baseline (it takes effect only if set before numpy loaded)."""
    return _x86_64() and all(os.environ.get(k) == v for k, v in BASELINE_ENV.items())


def describe() -> str:
    """What this process runs: the OpenBLAS kernel numpy loaded and numpy's highest x86 dispatch (imports numpy)."""
    import ctypes
    import glob

    import numpy as np
    from numpy._core._multiarray_umath import __cpu_features__ as features  # type: ignore[import-not-found]

    core = "unknown"
    libs = glob.glob(os.path.join(os.path.dirname(np.__file__), os.pardir, "numpy.libs", "libscipy_openblas*.so*"))
    for path in libs:
        try:
            fn = ctypes.CDLL(path).scipy_openblas_get_corename64_
            fn.restype = ctypes.c_char_p
            core = fn().decode()
            break
        except (OSError, AttributeError):
            continue
    level = "x86-64-v4" if features.get("X86_V4") else "x86-64-v3" if features.get("X86_V3") or features.get(
        "AVX2") else "other"
    return f"OpenBLAS {core}, numpy {np.__version__} dispatch {level}"
