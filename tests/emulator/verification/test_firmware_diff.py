"""Differential testing (``psns-hil diff-firmware``, :mod:`emulator.verification.firmware_diff`): the built-in
firmware behind the out-of-process lockstep interface (``emulator.dsp.lockstep_server``) must give zero differences
against itself in the virtual DSP, and a change injected after frame N must be reported at frame N."""

from __future__ import annotations

import json
from pathlib import Path

import pytest
import yaml

from emulator.cli.main import main as cli_main
from emulator.verification.firmware_diff import compare_nav_frames

SCENARIO = {"name": "diff", "seed": 11, "epoch": "2019-09-18T02:30:00Z", "duration_s": 4.0, "mode": "fast",
            "origin": {"lat_deg": 39.979, "lon_deg": 116.339, "height_m": 50.0},
            "attitude": {"heading_deg": 30.0, "pitch_deg": 2.0, "roll_deg": -1.5},
            "motion": [{"static": {"duration_s": 4.0}}]}


@pytest.fixture
def scenario(tmp_path) -> Path:
    p = tmp_path / "diff.yaml"
    p.write_text(yaml.safe_dump(SCENARIO, sort_keys=False))
    return p


def test_the_builtin_firmware_behind_the_process_interface_gives_zero_differences(scenario, tmp_path):
    out = tmp_path / "cmp"
    rc = cli_main(["diff-firmware", str(scenario), "--out", str(out), "--reference-server", "--allow-firmware"])
    rep = json.loads((out / "diff.json").read_text())
    assert rc == 0 and rep["identical"] is True, rep["first_difference"]
    assert rep["frames"]["compared"] == rep["frames"]["reference"] == 400  # 100 Hz output, 4 s
    assert rep["foreign_firmware"]["transport"] == "out-of-process" and not rep["foreign_firmware"]["failed"]
    assert "heading_deg" in rep["columns_compared"] and "sig_pos_u_m" in rep["columns_compared"]
    # the same cycles, so the same instants: the runs are the same, byte for byte
    assert (out / "reference" / "nav.csv").read_bytes() == (out / "foreign" / "nav.csv").read_bytes()
    assert rep["arrival"]["max_abs_diff_s"] == 0.0


def test_a_change_after_frame_n_is_reported_at_frame_n(scenario, tmp_path, capsys):
    out = tmp_path / "cmp"
    rc = cli_main(["diff-firmware", str(scenario), "--out", str(out), "--reference-server", "--allow-firmware",
                   "--perturb", "pitch_deg:150:0.002"])
    rep = json.loads((out / "diff.json").read_text())
    assert rc == 1 and rep["identical"] is False
    first = rep["first_difference"]
    assert first["frame"] == 150 and list(first["fields"]) == ["pitch_deg"]
    assert first["fields"]["pitch_deg"]["abs_diff"] == pytest.approx(0.002, rel=1e-3)  # float32 on the wire
    assert list(rep["fields"]) == ["pitch_deg"]
    f = rep["fields"]["pitch_deg"]
    assert f["first_frame"] == 150 and f["frames_differing"] == 400 - 150
    assert f["first_time_s"] == pytest.approx(150 * 0.01 + 0.005)
    assert sorted(rep["max_abs_diff_per_second"]) == ["1", "2", "3"]
    assert "first difference at frame 150" in capsys.readouterr().out


def test_diff_firmware_needs_allow_firmware(scenario, tmp_path, capsys):
    rc = cli_main(["diff-firmware", str(scenario), "--out", str(tmp_path / "cmp"), "--reference-server"])
    assert rc == 2 and "--allow-firmware" in capsys.readouterr().err
    assert not (tmp_path / "cmp").exists()


def _nav(path: Path, rows: list[tuple[str, str, str]]) -> Path:
    lines = ["time_s,lat_deg,heading_deg,arrival_s,err_att_deg"]
    lines += [f"{t},{lat},{hdg},{float(t) + 0.001},0.1" for t, lat, hdg in rows]
    path.write_text("\n".join(lines) + "\n")
    return path


def test_frames_pair_by_time_and_missing_frames_and_heading_wrap_count(tmp_path):
    ref = _nav(tmp_path / "r.csv", [("0.005", "1.0", "359.99"), ("0.015", "1.0", "10.0"), ("0.025", "1.0", "0.0")])
    # the same instants printed differently, a heading across the wrap (0.02 deg apart), a missing frame
    foreign = _nav(tmp_path / "f.csv", [("0.0050000000000000001", "1.0", "0.01"), ("0.025", "1.0", "0.0")])
    rep = compare_nav_frames(ref, foreign)
    assert rep["frames"] == {"reference": 3, "foreign": 2, "compared": 2, "missing_in_foreign": 1,
                             "missing_in_reference": 0}
    assert rep["first_difference"]["frame"] == 0
    assert rep["fields"]["heading_deg"]["max_abs_diff"] == pytest.approx(0.02)
    assert "lat_deg" not in rep["fields"] and "err_att_deg" not in rep["columns_compared"]
    assert compare_nav_frames(ref, ref)["identical"] is True
