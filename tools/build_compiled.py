"""Build (or remove) the opt-in compiled path: mypyc extension modules of the hot modules, in place.

The modules are listed once, in ``pyproject.toml`` under ``[tool.psns-hil.compiled] modules``. Each is
compiled by mypyc from its one Python source into a C extension placed beside the ``.py`` file
(``firmware_model/strapdown.cpython-311-x86_64-linux-gnu.so``, plus one shared ``*__mypyc.*.so`` at the
repository root). Python's import system prefers an extension module to a ``.py`` file of the same name in
the same directory, so the same import names pick the compiled code up; removing the files
(``make clean`` or ``--clean``) brings the pure-Python modules back. Nothing else changes: the default
install is pure Python, which is what ``make test`` (the CI) tests.

Bit identity with the pure-Python path (docs/decisions/performance.md D-10.F3): the compiled code does the
same IEEE double operations in the same order; the C compiler is told not to contract ``a * b + c`` into
fused multiply-adds (``-ffp-contract=off``), the one transformation gcc would otherwise be allowed to make.

Usage (from the repository root; needs gcc, the Python headers and mypy, which the ``dev`` extra installs)::

    .venv/bin/python tools/build_compiled.py            # build (what `make compiled` runs)
    .venv/bin/python tools/build_compiled.py --list     # the declared modules
    .venv/bin/python tools/build_compiled.py --files    # the file each of them is imported from (JSON)
    .venv/bin/python tools/build_compiled.py --clean    # remove the extension modules (what `make clean` runs)
    .venv/bin/python tools/build_compiled.py --pure -m emulator run ...   # run pure Python beside a build

``--pure -m MODULE ARGS...`` runs a module the way ``python -m`` does, but with the declared modules imported
from their ``.py`` sources even where the extensions are built (:func:`pure_python`): the plain path, for the
before/after measurements and the bit-identity test (``tests/test_compiled.py``) without rebuilding.
"""

from __future__ import annotations

import argparse
import importlib.abc
import importlib.machinery
import importlib.util
import os
import runpy
import shutil
import sys
import sysconfig
import tomllib
from collections.abc import Sequence
from pathlib import Path
from types import ModuleType

ROOT = Path(__file__).resolve().parents[1]
BUILD_DIR = ROOT / "build" / "mypyc"


def modules() -> list[str]:
    """The compiled modules' dotted names, as declared in ``pyproject.toml`` ([tool.psns-hil.compiled])."""
    with open(ROOT / "pyproject.toml", "rb") as f:
        return list(tomllib.load(f)["tool"]["psns-hil"]["compiled"]["modules"])


def source_of(module: str) -> Path:
    """The ``.py`` file of a dotted module name, relative to the repository root."""
    return Path(*module.split(".")).with_suffix(".py")


def extension_of(module: str) -> Path:
    """Where the built extension of ``module`` lives (absolute path; it may not exist)."""
    suffix = sysconfig.get_config_var("EXT_SUFFIX")
    return ROOT / Path(*module.split(".")).with_name(module.split(".")[-1] + suffix)


PACKAGES = ("protocols", "firmware_model", "emulator")


def built() -> list[Path]:
    """Every extension module this script may have placed in the tree, also of modules no longer declared: each
    package's ``*.so`` that has a ``.py`` twin beside it, and mypyc's shared ``*__mypyc.*.so`` at the root."""
    suffix = sysconfig.get_config_var("EXT_SUFFIX")
    twins = [p for pkg in PACKAGES for p in sorted((ROOT / pkg).rglob("*" + suffix))
             if p.with_name(p.name.removesuffix(suffix) + ".py").exists()]
    return twins + sorted(ROOT.glob("*__mypyc" + suffix))


def clean() -> None:
    """Remove the extension modules and mypyc's build directory."""
    for p in built():
        p.unlink()
        print(f"removed {p.relative_to(ROOT)}")
    shutil.rmtree(BUILD_DIR, ignore_errors=True)
    if BUILD_DIR.parent.is_dir() and not any(BUILD_DIR.parent.iterdir()):
        BUILD_DIR.parent.rmdir()  # build/ was made for mypyc alone


class _PureFinder(importlib.abc.MetaPathFinder):
    """Finds the declared modules' ``.py`` sources ahead of the path finder (which prefers extensions)."""

    def __init__(self, names: Sequence[str]) -> None:
        self.names = frozenset(names)

    def find_spec(self, fullname: str, path: Sequence[str] | None, target: ModuleType | None = None
                  ) -> importlib.machinery.ModuleSpec | None:
        if fullname not in self.names:
            return None
        return importlib.util.spec_from_file_location(fullname, ROOT / source_of(fullname))


def pure_python() -> None:
    """Import the declared modules from their ``.py`` sources from now on (call before anything imports them)."""
    loaded = [m for m in modules() if m in sys.modules]
    if loaded:
        raise RuntimeError(f"pure_python() called after {loaded} were imported")
    sys.meta_path.insert(0, _PureFinder(modules()))


def build() -> None:
    """Compile the declared modules with mypyc and place the extensions beside their sources."""
    from mypyc.build import mypycify
    from setuptools import Distribution

    os.chdir(ROOT)
    os.environ["CFLAGS"] = (os.environ.get("CFLAGS", "") + " -ffp-contract=off").strip()
    clean()
    exts = mypycify([str(source_of(m)) for m in modules()], opt_level="3", target_dir=str(BUILD_DIR))
    # A bare Distribution: setup() would parse pyproject.toml, which older setuptools reject (PEP 639 license).
    dist = Distribution({"name": "psns-hil-compiled", "ext_modules": exts})
    cmd = dist.get_command_obj("build_ext")
    cmd.inplace = True
    cmd.build_temp = str(BUILD_DIR / "temp")
    cmd.build_lib = str(BUILD_DIR / "lib")
    dist.run_command("build_ext")
    missing = [m for m in modules() if not extension_of(m).exists()]
    if missing:
        sys.exit(f"build_compiled: no extension module built for {missing}")
    print(f"compiled {len(modules())} modules: {', '.join(modules())}")


def main(argv: list[str] | None = None) -> None:
    argv = sys.argv[1:] if argv is None else argv
    if "-m" in argv:  # --pure -m MODULE ARGS...: everything after MODULE belongs to it
        i = argv.index("-m")
        if argv[:i] != ["--pure"] or i + 1 >= len(argv):
            sys.exit("usage: build_compiled.py --pure -m MODULE [ARGS...]")
        pure_python()
        sys.argv = [argv[i + 1], *argv[i + 2:]]
        runpy.run_module(argv[i + 1], run_name="__main__", alter_sys=True)
        return
    ap = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0])
    ap.add_argument("--clean", action="store_true", help="remove the extension modules")
    ap.add_argument("--list", action="store_true", help="print the declared modules")
    ap.add_argument("--files", action="store_true", help="print, as JSON, the file each declared module imports from")
    args = ap.parse_args(argv)
    if args.files:
        import importlib
        import json

        print(json.dumps({m: importlib.import_module(m).__file__ for m in modules()}))
    elif args.list:
        print("\n".join(modules()))
    elif args.clean:
        clean()
    else:
        build()


if __name__ == "__main__":
    main()
