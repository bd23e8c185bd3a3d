"""Untrusted scenarios (docs/hostile-input.md): opening or validating a scenario runs no code, every file it names
is confined to its directory, YAML aliases are refused, error messages never echo a file's contents."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from emulator.errors import ScenarioError
from emulator.scenario import load_scenario
from emulator.scenario.expectations_schema import HookError, load_hook
from emulator.scenario.paths import ALLOW_HOOKS_ENV, ALLOW_PATHS_ENV, PathNotAllowed, confine

ROOT = Path(__file__).resolve().parents[3]
QUICKSTART = (ROOT / "scenarios" / "quickstart.yaml").read_text()


def _cli(*args: str, env: dict[str, str] | None = None) -> subprocess.CompletedProcess[str]:
    import os

    e = {k: v for k, v in os.environ.items() if k not in (ALLOW_HOOKS_ENV, ALLOW_PATHS_ENV)}
    e["PYTHONPATH"] = str(ROOT)
    e.update(env or {})
    return subprocess.run([sys.executable, "-m", "emulator", *args], capture_output=True, text=True, timeout=120,
                          env=e, cwd=ROOT)


def _with_expectation(tmp_path: Path, line: str) -> Path:
    text = QUICKSTART
    text = text.replace("expectations:\n", f"expectations:\n{line}\n", 1) if "expectations:\n" in text \
        else text + f"\nexpectations:\n{line}\n"
    p = tmp_path / "s.yaml"
    p.write_text(text)
    return p


def test_validate_never_imports_a_hook(tmp_path: Path) -> None:
    marker = tmp_path / "pwned"
    (tmp_path / "evil.py").write_text(f"open({str(marker)!r}, 'w').write('x')\ndef f(summary, run_dir):\n"
                                      "    return True\n")
    p = _with_expectation(tmp_path, "  - python: {file: evil.py, function: f}")
    r = _cli("validate", str(p))
    assert r.returncode == 0, r.stderr
    assert not marker.exists()


def test_hooks_are_refused_without_allow_hooks(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(ALLOW_HOOKS_ENV, raising=False)
    marker = tmp_path / "pwned"
    (tmp_path / "evil.py").write_text(f"open({str(marker)!r}, 'w').write('x')\ndef f(summary, run_dir):\n"
                                      "    return True\n")
    with pytest.raises(HookError, match="--allow-hooks"):
        load_hook(tmp_path, "evil.py", "f")
    assert not marker.exists()
    assert load_hook(tmp_path, "evil.py", "f", allow=True)({}, None) is True
    assert marker.exists()


@pytest.mark.parametrize("name", ["../x.py", "/etc/passwd", "sub/../../x.py"])
def test_paths_outside_the_scenario_directory_are_refused(tmp_path: Path, name: str) -> None:
    (tmp_path / "sub").mkdir()
    with pytest.raises(PathNotAllowed, match="outside the scenario's directory"):
        confine(tmp_path / "sub", name)


def test_a_symlink_out_of_the_directory_is_refused(tmp_path: Path) -> None:
    d = tmp_path / "scn"
    d.mkdir()
    (d / "link.csv").symlink_to("/etc/passwd")
    with pytest.raises(PathNotAllowed):
        confine(d, "link.csv")


def test_allow_paths_widens_the_roots(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    d = tmp_path / "scn"
    d.mkdir()
    other = tmp_path / "data"
    other.mkdir()
    monkeypatch.setenv(ALLOW_PATHS_ENV, str(other))
    assert confine(d, "../data/x.csv") == (other / "x.csv").resolve()


def test_recorded_file_outside_is_a_validation_error_that_echoes_nothing(tmp_path: Path) -> None:
    lib = (ROOT / "scenarios" / "recorded_replay.yaml").read_text()
    text = lib.replace("data/drive_imu.csv", "/etc/passwd").replace("data/drive_gnss.nmea", "../x.nmea")
    assert text != lib
    p = tmp_path / "s.yaml"
    p.write_text(text)
    with pytest.raises(ScenarioError) as ei:
        load_scenario(p)
    msg = str(ei.value)
    assert msg.count("outside the scenario's directory") == 2, msg
    assert "root:" not in msg


def test_recorded_csv_errors_do_not_echo_contents(tmp_path: Path) -> None:
    from emulator.devices.recorded import RecordedImu
    from emulator.errors import RecordingError

    secret = "s3cr3t-token-value"
    (tmp_path / "imu.csv").write_text(f"{secret},b,c\n1,2,3\n")
    with pytest.raises(RecordingError) as ei:
        RecordedImu(tmp_path / "imu.csv", 0.0)
    assert secret not in str(ei.value)
    cols = "time_s,gyro_x_dps,gyro_y_dps,gyro_z_dps,accel_x_mps2,accel_y_mps2,accel_z_mps2\n"
    (tmp_path / "imu2.csv").write_text(cols + "0,1,2,3,4,5," + secret + "\n")
    with pytest.raises(RecordingError) as ei:
        RecordedImu(tmp_path / "imu2.csv", 0.0)
    assert secret not in str(ei.value)


@pytest.mark.parametrize("text", [
    "a: &a [x, x]\nb: &b [*a, *a, *a, *a, *a, *a, *a, *a, *a]\nc: [*b, *b, *b, *b, *b, *b, *b, *b, *b]\n",
    "a: &a [*a]\n",
    "base: &b {x: 1}\nother:\n  <<: *b\n",
])
def test_yaml_aliases_are_refused_with_exit_2(tmp_path: Path, text: str) -> None:
    p = tmp_path / "a.yaml"
    p.write_text(text)
    with pytest.raises(ScenarioError, match="aliases are not allowed"):
        load_scenario(p)
    r = _cli("validate", str(p))
    assert r.returncode == 2
    assert "aliases are not allowed" in r.stderr and "Traceback" not in r.stderr
