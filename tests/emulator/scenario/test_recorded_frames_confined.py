"""Camera recordings confined entry by entry (issue 41 item 5): every index entry and every glob match goes through
:func:`emulator.scenario.paths.confine`, and the answer never depends on what lies outside (no existence oracle).

Each case is run twice, once with the outside file present and once without it: ``validate`` must exit 2 with the
same one-line message (naming the scenario file and line, and for an index the index file and its line)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from emulator.devices.recorded import RecordedImages
from emulator.errors import RecordingError
from emulator.scenario.paths import ALLOW_HOOKS_ENV, ALLOW_PATHS_ENV, PathNotAllowed, confined_glob

ROOT = Path(__file__).resolve().parents[3]
QUICKSTART = (ROOT / "scenarios" / "quickstart.yaml").read_text()
CAMERA_LINE = "  camera: {preset: reference, fidelity: binned, rate_hz: 5}"
#: the camera's line in the scenario (1-based), which the messages name
CAMERA_LINENO = QUICKSTART.splitlines().index(CAMERA_LINE) + 1


def _cli(*args: str) -> subprocess.CompletedProcess[str]:
    e = {k: v for k, v in os.environ.items() if k not in (ALLOW_HOOKS_ENV, ALLOW_PATHS_ENV)}
    e["PYTHONPATH"] = str(ROOT)
    return subprocess.run([sys.executable, "-m", "emulator", *args], capture_output=True, text=True, timeout=120,
                          env=e, cwd=ROOT)


def _scenario(d: Path, recorded: str) -> Path:
    assert CAMERA_LINE in QUICKSTART
    p = d / "s.yaml"
    p.write_text(QUICKSTART.replace(CAMERA_LINE, f"  camera: {{preset: reference, fidelity: binned, rate_hz: 5, "
                                                 f"recorded: {recorded}}}"))
    return p


def _world(tmp_path: Path, outside_exists: bool) -> tuple[Path, Path]:
    """``(scenario dir, outside dir)``: the scenario's directory holds one good frame and a symbolic link
    ``frames_link`` to a directory outside it, which holds ``x.npz`` or not."""
    scen, out = tmp_path / "scen", tmp_path / "secret"
    scen.mkdir(parents=True)
    out.mkdir()
    np.savez(scen / "good.npz", I0=np.zeros((2, 2)), I45=0, I90=0, I135=0)
    if outside_exists:
        np.savez(out / "x.npz", I0=np.zeros((2, 2)), I45=0, I90=0, I135=0)
    (scen / "frames_link").symlink_to(out, target_is_directory=True)
    return scen, out


def _validate_both_ways(tmp_path: Path, recorded: str, index_text: str | None = None) -> str:
    """Validate the same scenario with the outside file present and absent; both exit 2 with one message line,
    the same but for the temporary directory; that line is returned."""
    lines = []
    for exists in (True, False):
        scen, out = _world(tmp_path / f"case{int(exists)}", exists)
        if index_text is not None:
            (scen / "index.csv").write_text(index_text.replace("OUT", str(out)))
        r = _cli("validate", str(_scenario(scen, recorded)))
        assert r.returncode == 2, (r.stdout, r.stderr)
        assert "Traceback" not in r.stderr
        msg = [ln for ln in r.stderr.splitlines() if "outside the scenario's directory" in ln]
        assert len(msg) == 1, r.stderr
        lines.append(msg[0].replace(str(tmp_path / f"case{int(exists)}"), "TMP"))
    assert lines[0] == lines[1]  # no existence oracle
    return lines[0]


def test_a_glob_through_a_symlink_is_refused_whatever_lies_behind_it(tmp_path: Path) -> None:
    line = _validate_both_ways(tmp_path, "{files: 'frames_lin?/x.npz', rate_hz: 5}")
    assert f"s.yaml:{CAMERA_LINENO}:" in line and "sensors.camera.recorded.files" in line and "frames_link" in line


@pytest.mark.parametrize("entry", ["OUT/x.npz", "frames_link/x.npz", "../secret/x.npz"])
def test_an_index_entry_outside_is_refused_by_line_never_by_existence(tmp_path: Path, entry: str) -> None:
    line = _validate_both_ways(tmp_path, "{index: index.csv}", f"time_s,file\n0.0,good.npz\n0.2,{entry}\n")
    assert f"s.yaml:{CAMERA_LINENO}:" in line and "index.csv: line 3, column 5" in line
    assert "secret" not in line.replace("TMP", "")  # the entry's text is not echoed


@pytest.mark.parametrize("field", ["data/drive_imu.csv", "data/drive_gnss.nmea"])
def test_a_recorded_file_outside_gives_the_same_answer_whether_it_exists_or_not(tmp_path: Path, field: str) -> None:
    """Before, validate said "outside" for both and added "no such file" only when the outside file was missing."""
    lib = (ROOT / "scenarios" / "recorded_replay.yaml").read_text()
    outs = []
    for exists in (True, False):
        d = tmp_path / f"c{int(exists)}"
        (d / "scen").mkdir(parents=True)
        target = d / "secret.csv"
        if exists:
            target.write_text("time_s\n")
        p = d / "scen" / "s.yaml"
        p.write_text(lib.replace(field, str(target)))
        r = _cli("validate", str(p))
        assert r.returncode == 2 and "Traceback" not in r.stderr
        outs.append(r.stderr.replace(str(d), "D"))
    assert outs[0] == outs[1] and "outside the scenario's directory" in outs[0]


def test_the_camera_itself_refuses_them_before_looking(tmp_path: Path) -> None:
    """The run's loader (not only validate) confines each entry and match, with the same message both ways."""
    msgs = []
    for exists in (True, False):
        scen, out = _world(tmp_path / f"c{int(exists)}", exists)
        (scen / "index.csv").write_text(f"time_s,file\n0.0,good.npz\n0.2,{out}/x.npz\n")
        with pytest.raises(RecordingError) as e1:
            RecordedImages(index=scen / "index.csv", base_dir=scen)
        with pytest.raises(RecordingError) as e2:
            RecordedImages(files="frames_lin?/x.npz", rate_hz=5.0, base_dir=scen)
        msgs.append((str(e1.value).replace(str(scen), "S"), str(e2.value).replace(str(scen), "S")))
    assert msgs[0] == msgs[1]
    assert "line 3, column 5: the frame file is outside" in msgs[0][0]
    assert "frames_link" in msgs[0][1] and "outside the scenario's directory" in msgs[0][1]


def test_confined_glob_matches_like_glob_inside(tmp_path: Path) -> None:
    import glob

    (tmp_path / "a").mkdir()
    for n in ("f1.npz", "f2.npz", ".hidden.npz", "g.png"):
        (tmp_path / "a" / n).write_text("x")
    (tmp_path / "a" / "sub").mkdir()
    (tmp_path / "a" / "sub" / "f3.npz").write_text("x")
    for pattern in ("a/*.npz", "a/f?.npz", "a/[fg]*", "*/sub/*.npz", "a/.*", "a/f1.npz", "a/none*"):
        want = sorted(Path(p).resolve() for p in glob.glob(str(tmp_path / pattern)))
        assert confined_glob(tmp_path, pattern) == want, pattern
    with pytest.raises(PathNotAllowed):
        confined_glob(tmp_path / "a", "../*.npz")
