"""A camera index CSV is read bounded (issue 41): line by line, at most ``FRAME_INDEX_MAX_BYTES`` in all and
``RECORDED_LINE_MAX`` characters a line, UTF-8; a violation is one error naming the index file and the line
(docs/hostile-input.md section 6). Before, the whole file was read at once with no cap."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from emulator.errors import RecordingError
from emulator.scenario import paths
from emulator.scenario.paths import RECORDED_LINE_MAX, read_frame_index

ROOT = Path(__file__).resolve().parents[3]
QUICKSTART = (ROOT / "scenarios" / "quickstart.yaml").read_text()
CAMERA_LINE = "  camera: {preset: reference, fidelity: binned, rate_hz: 5}"


def _frames(d: Path) -> None:
    np.savez(d / "good.npz", I0=np.zeros((2, 2)), I45=0, I90=0, I135=0)


def _refused(path: Path, base: Path) -> str:
    t0 = time.process_time()
    with pytest.raises(RecordingError) as exc:
        read_frame_index(path, base)
    assert time.process_time() - t0 < 5.0
    return str(exc.value)


def test_an_index_line_longer_than_the_cap_is_refused_by_line(tmp_path: Path) -> None:
    _frames(tmp_path)
    idx = tmp_path / "index.csv"
    idx.write_text("time_s,file\n0.0,good.npz\n0.2," + "a" * (3 * RECORDED_LINE_MAX) + "\n")
    msg = _refused(idx, tmp_path)
    assert f"index.csv: line 3, column {RECORDED_LINE_MAX + 1}: line longer than {RECORDED_LINE_MAX}" in msg
    assert "aaaa" not in msg
    # a line of multi-byte characters only just over the cap, and one without any newline at all
    idx.write_text("time_s,file\n0.0,\u00e9" + "\u20ac" * RECORDED_LINE_MAX + "\n")
    assert "line 2, column" in _refused(idx, tmp_path)
    msg = _refused(Path("/dev/zero"), tmp_path)  # endless, no newline: refused after one bounded piece
    assert "line 1" in msg and "line longer than" in msg


def test_a_non_utf8_index_names_the_line(tmp_path: Path) -> None:
    _frames(tmp_path)
    idx = tmp_path / "index.csv"
    idx.write_bytes(b"time_s,file\n0.0,good.npz\n0.2,\xff\xfe.npz\n")
    assert "index.csv: line 3, column 5: not UTF-8 text" in _refused(idx, tmp_path)


def test_an_index_larger_than_the_cap_is_refused_while_reading(tmp_path: Path, monkeypatch) -> None:
    _frames(tmp_path)
    idx = tmp_path / "index.csv"
    body = "time_s,file\n" + "".join(f"{0.2 * k:.1f},good.npz\n" for k in range(2000))
    idx.write_text(body)
    assert len(read_frame_index(idx, tmp_path)[1]) == 2000
    monkeypatch.setattr(paths, "FRAME_INDEX_MAX_BYTES", 16 << 10)  # 16 KB: the 33 KB index goes over at line ~900
    msg = _refused(idx, tmp_path)
    assert "index.csv: line" in msg and "larger than" in msg
    assert paths.FRAME_INDEX_MAX_BYTES < len(body) < 64 << 20


def test_validate_of_a_hostile_index_exits_2_with_one_line(tmp_path: Path) -> None:
    _frames(tmp_path)
    (tmp_path / "index.csv").write_bytes(b"time_s,file\n0.0,good.npz\n0.2," + b"x" * (1 << 20) + b"\n")
    assert CAMERA_LINE in QUICKSTART
    s = tmp_path / "s.yaml"
    s.write_text(QUICKSTART.replace(CAMERA_LINE, "  camera: {preset: reference, fidelity: binned, rate_hz: 5, "
                                                 "recorded: {index: index.csv}}"))
    env = {k: v for k, v in os.environ.items() if k != paths.ALLOW_PATHS_ENV}
    r = subprocess.run([sys.executable, "-m", "emulator", "validate", str(s)], capture_output=True, text=True,
                       timeout=120, env=env, cwd=ROOT)
    assert r.returncode == 2, (r.stdout, r.stderr)
    assert "Traceback" not in r.stderr
    lines = [ln for ln in r.stderr.splitlines() if "index.csv: line 3" in ln]
    assert len(lines) == 1 and "line longer than" in lines[0], r.stderr
