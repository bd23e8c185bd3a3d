"""The opt-in compiled path (tools/build_compiled.py, ``make compiled``): declared once, picked up under the same
import names, and bit for bit the pure-Python path.

Without a build (the default, and CI's ``make test``) the tests that need the extensions skip with the reason;
the declaration and the pure-Python switch are tested either way.
"""

from __future__ import annotations

import importlib
import importlib.util
import json
import os
import subprocess
import sys
import sysconfig
from pathlib import Path
from types import ModuleType

import numpy as np
import pytest

from tools.build_compiled import ROOT, built, extension_of, modules, source_of

EXT = sysconfig.get_config_var("EXT_SUFFIX")
BUILT = [m for m in modules() if extension_of(m).exists()]
needs_build = pytest.mark.skipif(not BUILT, reason="compiled modules not built (`make compiled`); pure Python only")
SCRIPT = str(ROOT / "tools" / "build_compiled.py")
ENV = {**os.environ, "PYTHONPATH": str(ROOT)}

#: the reference scenario cut to 20 s: coarse alignment ends at 2 s, then the strapdown, the filter, PSNS frames
SCENARIO = ROOT / "scenarios" / "bench_vehicle_loop_10min.yaml"
CUT_S = 20
#: summary.json keys that depend on the wall clock or the run directory, not on the computation
WALL_KEYS = ("wall_s", "realtime_factor", "run_dir")


def _files(pure: bool) -> dict[str, str]:
    """Where a fresh interpreter imports the declared modules from (``--pure``: forced to the sources)."""
    cmd = [sys.executable, SCRIPT, "--pure", "-m", "tools.build_compiled", "--files"] if pure else \
        [sys.executable, SCRIPT, "--files"]
    res = subprocess.run(cmd, cwd=ROOT, env=ENV, check=True, capture_output=True, text=True)
    return dict(json.loads(res.stdout))


def test_declared_modules_have_one_python_source() -> None:
    names = modules()
    assert names, "no modules declared in pyproject.toml [tool.psns-hil.compiled]"
    assert len(set(names)) == len(names)
    for m in names:
        assert (ROOT / source_of(m)).is_file(), m
        assert extension_of(m).name == m.split(".")[-1] + EXT


def test_build_is_all_or_nothing() -> None:
    """A partial build (some declared modules without their extension) would test neither path."""
    assert BUILT in ([], modules()), f"built {BUILT} of {modules()}: run `make compiled` or `make clean`"
    if not BUILT:
        assert built() == []


def test_pure_switch_imports_the_sources() -> None:
    """``--pure`` gives the plain path whether or not the extensions are built (the A/B measurements rely on it)."""
    files = _files(pure=True)
    assert sorted(files) == sorted(modules())
    for m, f in files.items():
        assert Path(f) == ROOT / source_of(m)


@needs_build
def test_compiled_modules_are_the_ones_imported() -> None:
    for m in modules():
        f = importlib.import_module(m).__file__
        assert f is not None and Path(f) == extension_of(m), f"{m} imported from {f}, not its extension"
    assert {m: Path(f) for m, f in _files(pure=False).items()} == {m: extension_of(m) for m in modules()}


def _run(out: Path, pure: bool) -> int:
    """Exit status of the run: 1 when its expectations (written for 600 s) fail on the cut, which is no error here."""
    head = [sys.executable, SCRIPT, "--pure"] if pure else [sys.executable]
    res = subprocess.run([*head, "-m", "emulator", "run", str(SCENARIO), "--fast", "--set", f"duration_s={CUT_S}",
                          "--out", str(out), "--quiet", "--no-report"], cwd=ROOT, env=ENV, capture_output=True,
                         text=True)
    assert res.returncode in (0, 1) and (out / "summary.json").is_file(), res.stderr[-2000:]
    return res.returncode


@needs_build
def test_compiled_run_is_bit_identical_to_pure_python(tmp_path: Path) -> None:
    """Every file of a run (captured bytes, nav and filter state, PSNS solves, truth, events) byte for byte; the
    summary and clock.json equal but for their wall-clock fields."""
    compiled, pure = tmp_path / "compiled", tmp_path / "pure"
    assert _run(compiled, pure=False) == _run(pure, pure=True)
    names = sorted(p.name for p in compiled.iterdir())
    assert names == sorted(p.name for p in pure.iterdir())
    assert {"capture.psnscap", "nav.csv", "filter_state.csv", "psns.csv"} <= set(names)
    nav = (compiled / "nav.csv").read_text().splitlines()
    assert len(nav) > 100 * (CUT_S - 3), "the run navigated for less time than the cut"
    for name in names:
        a, b = (compiled / name).read_bytes(), (pure / name).read_bytes()
        if name == "summary.json":
            sa, sb = json.loads(a), json.loads(b)
            for k in WALL_KEYS:
                sa.pop(k, None)
                sb.pop(k, None)
            assert sa == sb
        elif name == "clock.json":  # the wall clock's instant of scenario time 0 (D-7.33): equal but for it
            ca, cb = json.loads(a), json.loads(b)
            assert ca.keys() == cb.keys() and {k: v for k, v in ca.items() if "monotonic" not in k} == \
                {k: v for k, v in cb.items() if "monotonic" not in k}
        else:
            assert a == b, f"{name} differs between the compiled and the pure-Python run"


def _pure_twin(module: str) -> ModuleType:
    """A second copy of ``module`` loaded from its ``.py`` source (beside the compiled one, same package)."""
    name = module.rsplit(".", 1)[0] + "._pure_" + module.rsplit(".", 1)[1]
    spec = importlib.util.spec_from_file_location(name, ROOT / source_of(module))
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules[name] = mod  # dataclasses look their module up while the class is made
    try:
        spec.loader.exec_module(mod)
    finally:
        del sys.modules[name]
    return mod


@needs_build
def test_compiled_kernels_equal_their_sources_bit_for_bit() -> None:
    """The kernels on random inputs, compiled against the same source run by the interpreter: ``==`` on every
    float (the whole-run test above only sees what survives into the outputs)."""
    from firmware_model import c674x, strapdown
    from firmware_model.nav_state import NavState
    from protocols import crc

    rng = np.random.default_rng(20)
    sd, cm, cr = _pure_twin("firmware_model.strapdown"), _pure_twin("firmware_model.c674x"), _pure_twin("protocols.crc")
    for dtype in (np.float64, np.float32):
        for _ in range(300):
            q = rng.normal(size=4)
            q = (q / np.linalg.norm(q)).astype(dtype)
            v, a = rng.normal(0, 20, 3).astype(dtype), rng.normal(0, 1, 3).astype(dtype)
            pos = np.array([rng.uniform(-1.4, 1.4), rng.uniform(-3, 3), rng.uniform(-100, 5000)])
            phi = np.asarray(rng.normal(0, 1e-3, 3), dtype).tolist()
            dv = np.asarray(rng.normal(0, 5e-2, 3), dtype).tolist()
            T = float(rng.choice([0.005, 0.01, 0.0049]))
            out = []
            for mod in (strapdown, sd):
                s = NavState(q.copy(), v.copy(), pos.copy(), 1.0, a.copy())
                p, d = mod.coning_sculling_fast(phi, dv, dtype)
                mod.strapdown_step_fast(s, list(p), list(d), T, dtype)
                out.append((tuple(p), tuple(d), s.as_floats(), s.t))
            assert out[0] == out[1]
    for n in (1, 7, 20, 64, 300):
        data = rng.integers(0, 256, n, dtype=np.uint8).tobytes()
        for f in ("crc8_stim", "crc8_stim_fast", "crc16_ccitt", "crc32_mpeg2", "crc32_mpeg2_fast", "nmea_checksum",
                  "ubx_fletcher"):
            assert getattr(crc, f)(data) == getattr(cr, f)(data), f
    meters = [c674x.CycleMeter(300e6, 200.0), cm.CycleMeter(300e6, 200.0)]
    script = [(int(k), int(c)) for k, c in zip(rng.integers(0, 4, 2000), rng.integers(0, 5000, 2000))]
    ends = []
    for meter in meters:
        e = []
        for op, cycles in script:
            if op == 0:
                meter.begin(f"task{cycles % 3}", 0.005)
            elif op == 3:
                e.append(meter.end())
            else:
                meter.charge(f"k{op}", cycles)
                e.append(meter.elapsed)
        ends.append(e)
    assert ends[0] == ends[1]
    assert meters[0].table() == meters[1].table()
