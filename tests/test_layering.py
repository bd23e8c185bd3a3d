"""The house rule: emulator -> firmware_model -> protocols, one way only."""

import subprocess
import sys

import pytest


@pytest.mark.parametrize(
    "module, forbidden",
    [
        ("protocols", ["firmware_model", "emulator", "asyncio", "numpy"]),
        ("firmware_model", ["emulator", "asyncio"]),
    ],
)
def test_lower_layers_do_not_import_upper_layers(module, forbidden):
    code = (
        f"import sys, {module}\n"
        "import pkgutil, importlib\n"
        f"pkg = sys.modules['{module}']\n"
        "for m in pkgutil.walk_packages(pkg.__path__, pkg.__name__ + '.'):\n"
        "    importlib.import_module(m.name)\n"
        f"bad = [m for m in {forbidden!r} if m in sys.modules]\n"
        "print(','.join(bad))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "", f"{module} pulls in {out.stdout.strip()}"


def test_one_exception_root():
    from emulator.errors import LinkError, ScenarioError
    from firmware_model.errors import FirmwareError
    from protocols.errors import ChecksumError, PsnsHilError

    for cls in (LinkError, ScenarioError, FirmwareError, ChecksumError):
        assert issubclass(cls, PsnsHilError)
