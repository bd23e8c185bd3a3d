"""docs/icd.md is generated from the specs and must be current; its link rates are the scenario defaults."""

from pathlib import Path

from protocols.icd import LINK_BAUD, budget_rows, generate, spec_rows
from protocols.imu_frame import IMU_FRAME_SPEC

ICD = Path(__file__).resolve().parents[2] / "docs" / "icd.md"


def test_committed_icd_is_current():
    assert ICD.read_text() == generate(), "run: .venv/bin/python -m protocols.icd > docs/icd.md"


def test_link_rates_are_the_scenario_defaults():
    from benchmarks.bench_decoders import LINK_BAUD as BENCH_BAUD
    from emulator.scenario.runtime_schema import FpgaSpec, Links

    links, fpga = Links(), FpgaSpec()
    for name in ("gyro", "gnss", "host"):
        assert LINK_BAUD[name] == getattr(links, name).baud
    for name, spec in fpga.uarts.items():
        assert LINK_BAUD[name] == spec.baud
    assert all(BENCH_BAUD[k] == LINK_BAUD[k] for k in BENCH_BAUD)


def test_rows_walk_the_spec():
    rows = spec_rows(IMU_FRAME_SPEC)
    assert [r[0] for r in rows][:5] == ["0", "2", "3", "4", "6"]
    assert rows[-1][:4] == ("38", "2", "u16 LE", "crc")
    assert rows[-3][:4] == ("28", "3 x 3", "s24 LE x 3", "accel")


def test_every_link_fits_its_line():
    for row in budget_rows():
        assert float(row[-1].rstrip(" %")) < 60.0, row
