"""The numeric baseline (emulator.numeric_baseline, D-8.8): pinned before numpy loads, by the command line and the
root conftest; a user's value wins; too late once numpy is loaded. Each case runs in a fresh interpreter."""

from __future__ import annotations

import os
import platform
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.skipif(platform.machine().lower() not in ("x86_64", "amd64"),
                                reason="the baseline is pinned on x86-64 only")


def _python(code: str, **env: str) -> list[str]:
    clean = {k: v for k, v in os.environ.items()
             if k not in ("OPENBLAS_CORETYPE", "NPY_DISABLE_CPU_FEATURES", "PSNS_HIL_NUMERICS")}
    r = subprocess.run([sys.executable, "-c", code], env={**clean, **env, "PYTHONPATH": str(ROOT)},
                       capture_output=True, text=True, timeout=120, check=True)
    return r.stdout.split("\n")


def _has_avx2() -> bool:
    try:
        return " avx2 " in f" {Path('/proc/cpuinfo').read_text()} ".replace("\n", " ")
    except OSError:
        return False


@pytest.mark.skipif(not _has_avx2(), reason="the baseline needs an x86-64-v3 CPU (AVX2)")
def test_pin_before_numpy_runs_haswell_kernels_and_v3_loops():
    out = _python("import emulator.numeric_baseline as b; print(b.pin()); print(b.describe())")
    assert out[0] == "True"
    assert out[1].startswith("OpenBLAS Haswell,") and out[1].endswith("dispatch x86-64-v3")


def test_pin_after_numpy_is_too_late_and_says_so():
    out = _python("import numpy, emulator.numeric_baseline as b; print(b.pin()); import os; "
                  "print(os.environ.get('OPENBLAS_CORETYPE'))")
    assert out[:2] == ["False", "None"]


def test_the_users_value_wins_and_native_keeps_the_machines_kernels():
    out = _python("import emulator.numeric_baseline as b; print(b.pin()); print(b.describe())",
                  OPENBLAS_CORETYPE="Sandybridge")
    assert out[0] == "False" and out[1].startswith("OpenBLAS Sandybridge,")
    out = _python("import emulator.numeric_baseline as b, os; print(b.pin()); "
                  "print(os.environ.get('OPENBLAS_CORETYPE'))", PSNS_HIL_NUMERICS="native")
    assert out[:2] == ["False", "None"]


def test_the_command_line_and_the_root_conftest_pin_it():
    out = _python("import os, emulator.cli; print(os.environ.get('OPENBLAS_CORETYPE'), "
                  "os.environ.get('NPY_DISABLE_CPU_FEATURES'))")
    assert out[0] == "Haswell X86_V4 AVX512_ICL AVX512_SPR"
    # this very test session ran through the root conftest
    from emulator.numeric_baseline import pinned

    assert pinned() or os.environ.get("PSNS_HIL_NUMERICS") == "native"
