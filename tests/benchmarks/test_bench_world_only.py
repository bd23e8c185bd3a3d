"""The real-time-factor table's world-only row (docs/performance.md 5.14) takes the DSP out of the reference and
nothing else: no firmware runs and no nav row is written, while the world, the sensors, the FPGA and the links
make the same bytes as in the reference."""

from __future__ import annotations

from pathlib import Path

from benchmarks.bench_realtime_factor import REFERENCE, WORLD_ONLY
from emulator.assembly.session import run_scenario
from emulator.recording.capture import read_capture
from emulator.scenario import load_scenario

#: simulated seconds of each run: 400 IMU ticks, 10 camera frames, 2 GNSS epochs
CUT_S = 2.0


def _bytes_by_link(run_dir: Path) -> dict[tuple[str, str], bytes]:
    _header, records = read_capture(run_dir / "capture.psnscap")
    out: dict[tuple[str, str], bytearray] = {}
    for r in records:
        out.setdefault((r.link, r.direction), bytearray()).extend(r.data)
    return {k: bytes(v) for k, v in out.items()}


def test_world_only_differs_from_the_reference_in_the_dsp_alone():
    full = load_scenario(REFERENCE)
    world = load_scenario(REFERENCE, WORLD_ONLY)
    assert full.dsp.external is None
    assert world.dsp.external is not None and set(world.dsp.external.uarts) == {"uart0"}
    assert world.model_copy(update={"dsp": full.dsp}) == full


def test_world_only_runs_no_firmware_and_sends_the_reference_bytes_to_the_dsp(tmp_path):
    full = load_scenario(REFERENCE).model_copy(update={"duration_s": CUT_S})
    world = load_scenario(REFERENCE, WORLD_ONLY).model_copy(update={"duration_s": CUT_S})
    s_full = run_scenario(full, tmp_path / "full", mode="fast")
    s_world = run_scenario(world, tmp_path / "world", mode="fast")
    # the reference ran its firmware; the world-only run has none and nothing on the host side
    assert s_full["nav_frames"] > 0 and s_full["firmware"].get("filter")
    assert s_world["nav_frames"] == 0
    assert s_world["firmware"] == {"external": True, "filter": None}
    assert s_world["dsp"]["external"] is True and s_world["dsp"]["ticks"] is None
    # the FPGA still frames every IMU tick and the camera and GNSS data for the DSP's UARTs
    ticks = round(CUT_S * full.sensors.imu.rate_hz)
    assert s_world["fpga"]["imu_frames"] == s_full["fpga"]["imu_frames"] == ticks
    for link in ("gyro", "gnss", "psns", "uart1", "uart2", "uart3"):
        assert s_world["links"][link]["frames"] == s_full["links"][link]["frames"] > 0, link
    # and the bytes towards the DSP are the reference's, byte for byte
    got, ref = _bytes_by_link(tmp_path / "world"), _bytes_by_link(tmp_path / "full")
    for key in (("uart1", "in"), ("uart2", "in"), ("uart3", "in"), ("gyro", "in")):
        assert key in ref and got.get(key) == ref[key], key
