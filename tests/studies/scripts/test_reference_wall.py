"""``studies.scripts.reference_wall``: one fast-mode run of the reference, its wall time printed."""

from __future__ import annotations

import re

import pytest

from studies.scripts.reference_wall import main


def test_prints_the_runs_wall_time_and_real_time_factor(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["world", "0.5", "probe"]) == 0
    line = capsys.readouterr().out.strip()
    m = re.fullmatch(r"probe world 0s wall (\d+\.\d\d) s rtf (\d+\.\d)", line)
    assert m, line
    wall, rtf = float(m.group(1)), float(m.group(2))
    assert wall > 0 and rtf == pytest.approx(0.5 / wall, rel=0.05, abs=0.06)


def test_refuses_an_unknown_kind() -> None:
    with pytest.raises(SystemExit, match="kind must be full or world"):
        main(["dsp", "1", "x"])
    with pytest.raises(SystemExit, match="usage"):
        main(["full"])
