"""The house rules on imports, as import-linter contracts (pyproject.toml, ``[tool.importlinter]``).

``lint-imports`` parses every module, imports inside functions included, so these tests see what an
import-at-module-load check would miss. ``.ci/run`` runs the same contracts in its lint step; the test keeps them
enforced wherever the test suite runs.
"""

import subprocess
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _lint_imports() -> subprocess.CompletedProcess[str]:
    code = "import sys; from importlinter.cli import lint_imports_command; sys.exit(lint_imports_command())"
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=120)


def test_every_import_contract_is_kept():
    out = _lint_imports()
    assert out.returncode == 0, out.stdout + out.stderr
    assert "0 broken" in out.stdout


def test_the_contracts_name_the_three_layers_and_the_forbidden_libraries():
    config = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["importlinter"]
    contracts = config["contracts"]
    layers = [c["layers"] for c in contracts if c["type"] == "layers" and "emulator" in c["layers"]]
    assert ["emulator", "firmware_model", "protocols"] in layers
    forbidden: dict[str, set[str]] = {}
    for c in contracts:
        if c["type"] == "forbidden":
            for source in c["source_modules"]:
                forbidden.setdefault(source, set()).update(c["forbidden_modules"])
    assert {"numpy", "asyncio"} <= forbidden["protocols"]
    assert "asyncio" in forbidden["firmware_model"]
    for package in ("protocols", "firmware_model", "emulator"):  # the product sits below its benches and studies
        assert {"benchmarks", "studies", "tests"} <= forbidden[package]


def test_one_exception_root():
    from emulator.errors import LinkError, ScenarioError
    from firmware_model.errors import FirmwareError
    from protocols.errors import ChecksumError, PsnsHilError

    for cls in (LinkError, ScenarioError, FirmwareError, ChecksumError):
        assert issubclass(cls, PsnsHilError)
