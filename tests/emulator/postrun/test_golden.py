"""Change indicator: golden records are small text, every library scenario has one, a replay within float noise
passes and any real change (inputs or estimator state) is reported with where it happened."""

from __future__ import annotations

import subprocess
import sys

import pytest

from emulator.assembly.session import run_scenario
from emulator.postrun.golden import (
    GOLDEN_DIR,
    compare_golden,
    compare_inputs,
    compare_state,
    golden_paths,
    library,
    row_interval,
    write_golden,
)
from emulator.scenario import load_scenario
from emulator.testing import load_test_scenario
from tests.conftest import ROOT, SCENARIOS

STATE = """time_s,lat_deg,heading_deg,mode,p0,gyro_bias_z
1,39.979000000000,359.99,263,1.0e-06,1.0e-07
2,39.979000001000,0.01,263,2.0e-06,2.0e-07
"""


def test_state_comparison_tolerates_float_noise_only():
    assert compare_state(STATE, STATE) == []
    noise = STATE.replace("39.979000001000", "39.979000001004").replace("2.0e-06", "2.00000001e-06")
    assert compare_state(noise, STATE) == []  # 0.4 mm and a relative 5e-9: float noise
    moved = STATE.replace("39.979000001000", "39.979000101000")  # 1.1 cm
    d = compare_state(moved, STATE)
    assert len(d) == 1 and d[0].startswith("lat_deg: 1 of 2 rows differ beyond tolerance")
    assert "first at t = 2 s: 39.979000101000 vs golden 39.979000001000" in d[0]
    p_changed = STATE.replace("2.0e-06", "2.01e-06")  # 0.5 % of a covariance element
    assert compare_state(p_changed, STATE)[0].startswith("p0:")
    assert compare_state(STATE.replace(",263,1.0e-06", ",271,1.0e-06"), STATE)[0].startswith("mode:")


def test_heading_wraps_and_rows_or_columns_that_change_are_reported():
    wrapped = STATE.replace("359.99", "-0.01")
    assert compare_state(wrapped, STATE) == []
    fewer = "\n".join(STATE.splitlines()[:2]) + "\n"
    assert "rows differ" in compare_state(fewer, STATE)[0]
    renamed = STATE.replace("gyro_bias_z", "gyro_bias_w")
    assert "columns differ" in compare_state(renamed, STATE)[0]


INPUTS = """# header
gyro in 300 20 aaaa
gyro in blocks_10s 111111111111 222222222222 333333333333
"""


def test_input_digests_must_match_exactly_and_the_first_differing_block_is_named():
    assert compare_inputs(INPUTS, INPUTS) == []
    changed = INPUTS.replace("aaaa", "bbbb").replace("222222222222 333333333333", "222222222222 999999999999")
    d = compare_inputs(changed, INPUTS)
    assert d[0] == "input bytes on gyro (in) differ: 300 bytes in 20 chunks vs golden 300 in 20"
    assert d[1] == "  first difference on gyro (in) in the block 20-30 s"
    assert "input gnss in: new" in compare_inputs(INPUTS + "gnss in 1 1 cc\n", INPUTS)[0]


def _short(tmp_path, seed=1):
    scn = load_test_scenario(SCENARIOS / "quickstart.yaml", {"duration_s": 6, "motion": [{"static": {"duration_s": 6}}],
                                                              "expectations": [], "seed": seed})
    d = tmp_path / f"run{seed}-{len(list(tmp_path.iterdir()))}"
    run_scenario(scn, d)
    return scn, d


def test_a_replay_matches_its_golden_and_another_seed_does_not(tmp_path):
    scn, d1 = _short(tmp_path)
    gdir = tmp_path / "golden"
    ps, _pi = write_golden(d1, scn.name, scn.seed, scn.duration_s, gdir)
    assert ps.read_text().count("\n") == 7  # header + 6 rows at 1 s
    _, d2 = _short(tmp_path)
    assert compare_golden(d2, scn.name, scn.seed, scn.duration_s, gdir) == []
    _scn3, d3 = _short(tmp_path, seed=2)
    diffs = compare_golden(d3, scn.name, scn.seed, scn.duration_s, gdir)
    assert any(x.startswith("input bytes on gyro (in) differ") for x in diffs)
    assert any(x.startswith("  first difference on gyro (in) in the block 0-10 s") for x in diffs)
    assert any(x.startswith(("lat_deg:", "height_m:", "p0:")) for x in diffs)


def test_every_library_scenario_has_small_text_goldens_and_no_orphans():
    names = {load_scenario(p).name for p in library()}
    assert names, "the library is empty"
    for n in names:
        ps, pi = golden_paths(n)
        assert ps.exists() and pi.exists(), f"no golden for {n}: run `make golden`"
        assert ps.stat().st_size < 100_000 and pi.stat().st_size < 100_000
        ps.read_text(encoding="ascii")  # plain text
    files = {p.name.split(".")[0] for p in GOLDEN_DIR.iterdir() if p.suffix in (".csv", ".txt")}
    assert files == names, f"golden files without a scenario: {sorted(files - names)}"


def test_row_interval_keeps_long_scenarios_small():
    assert row_interval(120) == 1 and row_interval(600) == 5 and row_interval(7200) == 60


def test_golden_cli_checks_and_regenerates_one_scenario(tmp_path):
    gdir = tmp_path / "g"
    lib = tmp_path / "lib"
    lib.mkdir()
    (lib / "tiny.yaml").write_text((SCENARIOS / "quickstart.yaml").read_text().replace("name: quickstart", "name: tiny")
                                   .replace("duration_s: 120", "duration_s: 3")
                                   .replace("{duration_s: 120}", "{duration_s: 3}"))
    cmd = [sys.executable, "-m", "emulator", "golden", "--library", str(lib), "--golden", str(gdir)]
    r = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 1 and "no golden record for tiny" in r.stdout
    r = subprocess.run([*cmd, "--update", "tiny"], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0 and "tiny: wrote" in r.stdout
    r = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 0 and "tiny: unchanged" in r.stdout
    r = subprocess.run([*cmd, "nope"], capture_output=True, text=True, cwd=ROOT)
    assert r.returncode == 2 and "unknown scenario" in r.stderr


def test_the_committed_recording_is_what_its_generator_makes(tmp_path):
    sys.path.insert(0, str(SCENARIOS / "data"))
    try:
        import make_recording  # type: ignore[import-not-found]  # scenarios/data/make_recording.py
    finally:
        sys.path.pop(0)
    imu, gnss = make_recording.make(tmp_path)
    assert imu.read_bytes() == (SCENARIOS / "data" / "drive_imu.csv").read_bytes()
    assert gnss.read_bytes() == (SCENARIOS / "data" / "drive_gnss.nmea").read_bytes()
    size = sum(p.stat().st_size for p in (SCENARIOS / "data").iterdir() if p.is_file())
    assert size < 1_000_000


@pytest.mark.slow
def test_every_library_scenario_matches_its_golden_twice_in_a_row(tmp_path):
    """The change indicator is deterministic: two replays of each scenario give identical records."""
    from emulator.postrun.golden import record

    for p in library():
        scn = load_scenario(p)
        texts = []
        for k in range(2):
            d = tmp_path / f"{scn.name}-{k}"
            run_scenario(scn, d, mode="fast")
            texts.append(record(d, scn.name, scn.seed, scn.duration_s))
        assert texts[0] == texts[1], scn.name
