"""The Renode-style test API (emulator.testing): waits on port traffic in the emulator's clock."""

from __future__ import annotations

import time

import pytest

from emulator.errors import LinkTimeoutError
from emulator.testing import start_emulator
from protocols.host import NavMode, NavSolution
from protocols.imu_frame import ImuFrame
from protocols.nmea import build_gga, build_rmc
from tests.conftest import SCENARIOS


def _static(seconds: int) -> dict:
    """Scenario overrides: stand still for ``seconds`` s, s."""
    return {"duration_s": float(seconds), "motion": [{"static": {"duration_s": seconds}}]}

QUICKSTART = SCENARIOS / "quickstart.yaml"
#: a light variant: 10 Hz IMU and output, no GNSS receiver (its port stays open for injection)
LIGHT = {
    "sensors.imu.rate_hz": 10.0,
    "firmware.output_rate_hz": 10.0,
    "sensors.gnss.enabled": False,
    "duration_s": 100.0,
    "motion": [{"static": {"duration_s": 100.0}}],
}


@pytest.mark.psns_emulator
async def test_sixty_virtual_seconds_of_waiting_do_not_wait_on_the_wall_clock(tmp_path):
    async with start_emulator(QUICKSTART, run_dir=tmp_path, overrides=LIGHT) as emu:
        t0 = emu.time
        wall0 = time.perf_counter()
        with pytest.raises(LinkTimeoutError, match="within 60 s"):
            await emu.wait_for_frame("host", lambda f: False, timeout=60.0)
        wall = time.perf_counter() - wall0
        assert emu.time == pytest.approx(t0 + 60.0, abs=1e-9)
        # the emulator really ran those 60 s: ~600 nav frames at 10 Hz went by
        assert emu.watcher("host").total_frames >= 595
        # a loop that waited on the wall clock would take 60 s; how fast it is instead is make bench's business
        # (about 0.3 s on an idle machine), so the bound leaves room for a loaded CI machine
        assert wall < 15.0, f"60 virtual seconds took {wall:.2f} s of wall time"


@pytest.mark.psns_emulator
async def test_wait_for_frame_line_and_bytes(tmp_path):
    async with start_emulator(QUICKSTART, run_dir=tmp_path, overrides=_static(20)) as emu:
        nav = await emu.wait_for_frame(
            "host", lambda f: isinstance(f, NavSolution) and bool(f.mode & NavMode.NAVIGATING), timeout=10.0)
        # alignment takes 2 s plus the first GNSS fix; the frame arrived after its time of validity
        assert 2.0 <= nav.time_s < 4.0
        assert emu.last_match_time > nav.time_s
        assert abs(nav.lat_deg - 39.979) < 1e-3 and abs(nav.heading_deg - 30.5) < 1.0
        line = await emu.wait_for_line("gnss", "GPGGA", timeout=2.0)
        assert line.startswith("$GPGGA,") and "*" in line and not line.endswith("\r")
        sync = await emu.wait_for_bytes("uart1", b"\x55\xaa\x01\x22", timeout=0.01)
        assert sync == b"\x55\xaa\x01\x22"
        imu = await emu.wait_for_frame("uart1", lambda f: isinstance(f, ImuFrame), timeout=0.01)
        assert imu.t_trigger_us % 5000 == 0
        # the UART0 side carries the same frames the host port gets
        n0 = await emu.wait_for_frame("uart0", timeout=0.05)
        assert isinstance(n0, NavSolution)


@pytest.mark.psns_emulator
async def test_assert_not_seen_fails_fast_when_the_pattern_appears(tmp_path):
    async with start_emulator(QUICKSTART, run_dir=tmp_path, overrides=_static(10)) as emu:
        await emu.assert_not_seen("host", lambda f: f.deadline_misses > 0, during=2.0)
        t0 = emu.time
        with pytest.raises(AssertionError, match="GPRMC"):
            await emu.assert_not_seen("gnss", b"GPRMC", during=5.0)
        assert emu.time - t0 < 1.3  # the next GNSS epoch, not the end of the window


@pytest.mark.psns_emulator
async def test_wait_idle_finds_the_gap_between_gnss_epochs(tmp_path):
    async with start_emulator(QUICKSTART, run_dir=tmp_path, overrides=_static(10)) as emu:
        await emu.wait_for_line("gnss", "GPRMC", timeout=2.0)
        last = await emu.wait_idle("gnss", quiet_time=0.5, timeout=2.0)
        # GGA + RMC leave the receiver 50 ms after the whole second and take ~0.15 s at 9600 baud
        frac = last % 1.0
        assert 0.05 < frac < 0.35
        assert emu.time == pytest.approx(last + 0.5)
        with pytest.raises(LinkTimeoutError, match="never stayed quiet"):
            await emu.wait_idle("host", quiet_time=0.5, timeout=1.0)


@pytest.mark.psns_emulator
async def test_injected_nmea_reaches_the_firmware(tmp_path):
    """With no GNSS model, the test plays an external GNSS simulator on the in-process port."""
    import datetime as dt

    async with start_emulator(QUICKSTART, run_dir=tmp_path, overrides=dict(LIGHT, **{"duration_s": 10.0,
                              "motion": [{"static": {"duration_s": 10}}]})) as emu:
        assert emu.fw.counters["gnss_fixes"] == 0
        for k in range(3):
            tm = dt.time(8, 14, k)
            emu.send("gnss", build_gga(tm, 39.979, 116.339, 50.0, 0.0, quality=1, num_sats=9, hdop=0.9)
                     + build_rmc(tm, dt.date(2019, 9, 18), 39.979, 116.339, 0.0, 0.0))
            await emu.run_for(1.0)
        t = await emu.wait_until(lambda: emu.fw.counters["gnss_fixes"] >= 3, timeout=1.0)
        assert t <= 3.5
        assert emu.link_stats("gnss")["bytes_in"] > 0


@pytest.mark.psns_emulator
async def test_emulator_started_with_await_is_stopped_by_the_runner(tmp_path):
    emu = await start_emulator(QUICKSTART, run_dir=tmp_path, overrides=LIGHT)
    await emu.run_for(1.0)
    # no explicit stop: the psns_emulator runner stops it and the summary gets written


def test_runner_wrote_the_summary_of_an_unstopped_emulator(tmp_path):
    from emulator.testing import run

    async def main():
        emu = await start_emulator(QUICKSTART, run_dir=tmp_path / "r", overrides=LIGHT)
        await emu.run_for(2.0)
        return emu

    emu = run(main)
    assert emu.summary is not None and (tmp_path / "r" / "summary.json").exists()
    assert emu.summary["sim_duration_s"] == pytest.approx(2.0, abs=0.01)


def test_a_second_emulator_in_the_same_loop_is_refused(tmp_path):
    from emulator.errors import EmulatorError
    from emulator.testing import run

    async def main():
        await start_emulator(QUICKSTART, run_dir=tmp_path / "a", overrides=LIGHT)
        with pytest.raises(EmulatorError, match="one emulator per test"):
            await start_emulator(QUICKSTART, run_dir=tmp_path / "b", overrides=LIGHT)

    run(main)
