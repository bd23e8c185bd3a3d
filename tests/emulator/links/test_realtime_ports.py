"""Real tools on the emulator's ports, in real time: pyserial, an external GNSS simulator, socat.

Each test runs a few seconds of wall time; the rates are measured over the frames' own arrival
times, so a loaded machine shifts them together instead of skewing the result.
"""

from __future__ import annotations

import asyncio
import datetime as dt
import os
import shutil
import socket
import stat
import time

import pytest

from protocols.host import HostFormat, NavMode, NavSolution
from protocols.nmea import build_gga, build_rmc
from protocols.stream import StreamDecoder
from tests.conftest import SCENARIOS

pytestmark = [pytest.mark.pty, pytest.mark.realtime]

QUICKSTART = SCENARIOS / "quickstart.yaml"


def _overrides(duration: float, **links: str) -> dict:
    ov = {"duration_s": duration, "motion": [{"static": {"duration_s": duration}}], "expectations": []}
    for port, url in links.items():
        ov[f"links.{port}.url"] = url
    return ov


def _robust_rate(frames: list[tuple[float, NavSolution]]) -> float:
    """Frames per wall second, Theil-Sen style: the median over frame pairs half the record
    apart of (frames between them) / (wall time between their arrivals). A host too busy to
    read for a moment delivers a burst; a burst moves a few pairs, not the median."""
    n = len(frames)
    h = n // 2
    ratios = sorted((h / (frames[i + h][0] - frames[i][0])) for i in range(n - h) if frames[i + h][0] > frames[i][0])
    return ratios[len(ratios) // 2]


class _SerialReader:
    """pyserial on a pty, read from the event loop (add_reader), frames decoded as they come."""

    def __init__(self, path, baud: int = 460800) -> None:
        import serial

        self.ser = serial.Serial(str(path), baud, timeout=0)
        self.dec = StreamDecoder([HostFormat()])
        self.frames: list[tuple[float, NavSolution]] = []
        self.loop = asyncio.get_running_loop()
        self.loop.add_reader(self.ser.fileno(), self._on)

    def _on(self) -> None:
        data = self.ser.read(65536)
        t = time.monotonic()
        for f in self.dec.feed(data):
            if isinstance(f, NavSolution):  # the 1 Hz STATUS and ACK frames share the port
                self.frames.append((t, f))

    def close(self) -> None:
        self.loop.remove_reader(self.ser.fileno())
        self.ser.close()


@pytest.mark.psns_emulator(mode="realtime")
async def test_pyserial_decodes_nav_frames_from_uart0_pty_at_the_configured_rate(tmp_path):
    from emulator.testing import start_emulator

    async with start_emulator(QUICKSTART, run_dir=tmp_path, overrides=_overrides(10.0, host="pty://uart0")) as emu:
        link = tmp_path / "ports" / "uart0"
        # private run directory, stable symlink, a 0600 pty behind it, announced in the port map
        assert stat.S_IMODE(os.stat(tmp_path / "ports").st_mode) == 0o700
        assert link.is_symlink() and os.readlink(link).startswith("/dev/pts/")
        assert stat.S_IMODE(os.stat(os.readlink(link)).st_mode) == 0o600
        host_row = next(p for p in emu.emulator.ports if p["name"] == "host")
        assert str(link) in host_row["path"] and os.readlink(link) in host_row["path"]
        rd = _SerialReader(link)
        try:
            await emu.run_for(3.2)
        finally:
            rd.close()
        frames = rd.frames
        assert len(frames) > 250, f"only {len(frames)} frames in 3.2 s"
        seqs = [f.seq for _t, f in frames]
        assert seqs == list(range(seqs[0], seqs[0] + len(seqs))), "frames lost or reordered"
        configured = emu.emulator.scn.firmware.output_rate_hz
        rate = _robust_rate(frames)
        assert abs(rate / configured - 1.0) < 0.02, f"{rate:.2f} frames/s vs {configured} configured"
        assert rd.dec.stats.crc_errors == 0 and rd.dec.stats.garbage_bytes == 0
        # nothing was dropped while attached (the first frames before the attach poll may be)
        st = emu.link_stats("host")
        assert st["dropped_out"] <= 10 * 109
        # the paced writer wrote them: its process on Linux (D-10.E11), alive to the end
        from emulator.paced_writer import default_writer_backend

        ws = emu.emulator.loop.writer_summary()
        assert ws is not None and ws["writing"] == default_writer_backend() and ws["error"] is None


@pytest.mark.psns_emulator(mode="realtime")
async def test_external_gnss_simulator_writes_nmea_into_the_gnss_pty(tmp_path):
    import serial

    async with start_emulator_rt(tmp_path, _overrides(8.0, gnss="pty://gnss")) as emu:
        assert emu.emulator.gnss is None  # the port is external: no GNSS model runs
        sim = serial.Serial(str(tmp_path / "ports" / "gnss"), 9600, timeout=0)
        try:
            await emu.wait_until(lambda: emu.emulator.links["gnss"].attached, timeout=1.0)
            epoch = dt.datetime(2019, 9, 18, 8, 14, 0)
            for k in range(4):
                tm = (epoch + dt.timedelta(seconds=k)).time()
                sim.write(build_gga(tm, 39.979, 116.339, 50.0, 0.0, quality=1, num_sats=10, hdop=0.8)
                          + build_rmc(tm, epoch.date(), 39.979, 116.339, 0.0, 0.0))
                if k < 3:
                    await emu.run_for(0.5)
            await emu.wait_until(lambda: emu.fw.counters["gnss_fixes"] >= 4, timeout=2.0)
            nav = await emu.wait_for_frame(
                "host", lambda f: isinstance(f, NavSolution) and bool(f.mode & NavMode.NAVIGATING), timeout=3.0)
        finally:
            sim.close()
        # the firmware navigates from the external fixes: position at the simulator's point
        assert abs(nav.lat_deg - 39.979) < 1e-4 and abs(nav.lon_deg - 116.339) < 1e-4
        assert abs(nav.height_m - 50.0) < 1.0
        assert emu.fw.decoder_stats()["uart3"]["crc_errors"] == 0


def start_emulator_rt(tmp_path, overrides):
    from emulator.testing import start_emulator

    return start_emulator(QUICKSTART, run_dir=tmp_path, overrides=overrides)


@pytest.mark.skipif(shutil.which("socat") is None,
                    reason="socat is not installed (apt-get install socat; .ci/run installs it)")
@pytest.mark.psns_emulator(mode="realtime")
async def test_socat_bridges_the_uart0_pty_to_tcp_and_a_client_reads_frames(tmp_path):
    async with start_emulator_rt(tmp_path, _overrides(10.0, host="pty://uart0")) as emu:
        with socket.socket() as s:
            s.bind(("127.0.0.1", 0))
            port = s.getsockname()[1]
        pty_path = tmp_path / "ports" / "uart0"
        proc = await asyncio.create_subprocess_exec(
            "socat", f"{pty_path},raw,echo=0", f"tcp-listen:{port},bind=127.0.0.1,reuseaddr",
            stdout=asyncio.subprocess.DEVNULL, stderr=asyncio.subprocess.PIPE)
        try:
            reader = writer = None
            for _ in range(100):  # socat needs a moment to listen
                try:
                    reader, writer = await asyncio.open_connection("127.0.0.1", port)
                    break
                except OSError:
                    await asyncio.sleep(0.02)
            assert reader is not None, "socat never accepted the TCP connection"
            dec = StreamDecoder([HostFormat()])
            frames = []
            t_end = emu.time + 1.5
            while emu.time < t_end:
                try:
                    data = await asyncio.wait_for(reader.read(65536), 0.5)
                except TimeoutError:
                    continue
                if not data:
                    break
                frames += dec.feed(data)
            writer.close()
        finally:
            if proc.returncode is None:
                proc.terminate()
            await proc.wait()
        navs = [f for f in frames if isinstance(f, NavSolution)]
        assert len(navs) > 100, f"{len(navs)} frames over TCP in 1.5 s"
        assert dec.stats.crc_errors == 0
        seqs = [f.seq for f in navs]
        assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))


@pytest.mark.psns_emulator(mode="realtime")
async def test_reopened_pty_gets_no_stale_bytes_and_absent_peer_is_counted(tmp_path):
    import serial

    async with start_emulator_rt(tmp_path, _overrides(8.0, host="pty://uart0")) as emu:
        link = emu.emulator.links["host"]
        path = tmp_path / "ports" / "uart0"
        await emu.run_for(0.3)  # nobody attached: every frame is discarded and counted as unheard, not dropped
        dropped0 = link.stats.no_peer_out
        assert dropped0 >= 20 * 109 and link.stats.dropped_out == 0
        # a peer that opens, reads nothing and leaves behind unread frames
        lazy = serial.Serial(str(path), 460800, timeout=0)
        await emu.wait_until(lambda: link.attached, timeout=1.0)
        await emu.run_for(0.2)
        lazy.close()
        await emu.wait_until(lambda: not link.attached, timeout=1.0)
        assert link.flushed_stale > 0  # what it left unread was discarded
        await emu.run_for(0.2)
        # the next peer starts at a frame boundary with fresh frames, not the old backlog
        fresh = serial.Serial(str(path), 460800, timeout=0)
        try:
            await emu.wait_until(lambda: link.attached, timeout=1.0)
            t_open = emu.time
            await emu.run_for(0.3)
            data = fresh.read(1 << 20)
        finally:
            fresh.close()
        dec = StreamDecoder([HostFormat()])
        navs = [f for f in dec.feed(data) if isinstance(f, NavSolution)]
        assert navs and data[:2] == b"\xa5\x5a"
        assert dec.stats.garbage_bytes == 0
        # time of validity of the first frame read: after the reopen (no stale frame from before)
        assert navs[0].time_s >= t_open - 0.05
        assert link.stats.no_peer_out > dropped0 and link.stats.dropped_out == 0
        assert link.attach_count == 2 and link.detach_count >= 1
