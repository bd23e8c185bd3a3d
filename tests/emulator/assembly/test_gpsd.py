"""gpsd 3.22 (the Debian package; .ci/run installs it) on the emulator's ports, in real time.

* The modelled u-blox receiver's stream bound out to a pty (``links.gnss: {url: pty://gnss, direction: tee}``):
  gpsd reads it straight from the pty, no bridge, and its TPV fixes are the emitted GGA positions to 0.01 m.
* The firmware's NMEA navigation output on the host pty (``firmware.nmea``), interleaved with the binary
  NAV_SOLUTION frames: gpsd's TPV position, speed and track and its ATT heading match the NAV_SOLUTION frames of
  the same ticks, decoded from the run's capture.

gpsd runs as ``gpsd -N -n -b -S PORT -F SOCKET DEVICE``: foreground, no waiting for a client, read-only
(``-b``: it never writes to the device), its TCP port on loopback (gpsd listens on loopback unless ``-G``).
Every wait counts in the emulator's clock (real time here), with room for a loaded machine.
"""

from __future__ import annotations

import asyncio
import contextlib
import datetime as dt
import json
import math
import socket
from pathlib import Path

import pytest

from protocols.host import HostFormat, NavSolution
from protocols.nmea import NmeaFormat
from protocols.stream import StreamDecoder
from tests.conftest import SCENARIOS

GPSD = "/usr/sbin/gpsd"
QS = SCENARIOS / "quickstart.yaml"
#: one arc-minute of latitude, m (NMEA rounds to 1e-5 arc-minute: 1.85 cm, half of it 0.93 cm)
M_PER_ARCMIN = 1852.0

pytestmark = [
    pytest.mark.pty, pytest.mark.realtime,
    pytest.mark.skipif(not Path(GPSD).exists(), reason="gpsd is not installed (apt-get install gpsd; .ci/run does)"),
]


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class Gpsd:
    """gpsd on ``device``, and a JSON watcher on its TCP port collecting TPV and ATT reports."""

    def __init__(self, device: Path, workdir: Path) -> None:
        self.device = device
        self.sock = workdir / "gpsd.sock"
        self.port = _free_port()
        self.proc: asyncio.subprocess.Process | None = None
        self.reports: list[dict] = []
        self._reader_task: asyncio.Task | None = None
        self._writer: asyncio.StreamWriter | None = None

    async def start(self, emu, timeout: float) -> None:
        self.proc = await asyncio.create_subprocess_exec(
            GPSD, "-N", "-n", "-b", "-S", str(self.port), "-F", str(self.sock), str(self.device),
            stdout=asyncio.subprocess.DEVNULL, stderr=asyncio.subprocess.PIPE)
        conn: list = []

        async def try_connect() -> bool:
            with contextlib.suppress(OSError):
                conn.append(await asyncio.open_connection("127.0.0.1", self.port))
            return bool(conn)

        deadline = emu.time + timeout
        while not await try_connect():
            assert self.proc.returncode is None, f"gpsd exited: {await self._stderr()}"
            assert emu.time < deadline, f"gpsd did not listen on 127.0.0.1:{self.port} within {timeout} s"
            await asyncio.sleep(0.05)
        reader, self._writer = conn[0]
        self._writer.write(b'?WATCH={"enable":true,"json":true};\n')
        await self._writer.drain()
        self._reader_task = asyncio.get_running_loop().create_task(self._read(reader))

    async def _read(self, reader: asyncio.StreamReader) -> None:
        while line := await reader.readline():
            with contextlib.suppress(ValueError):
                self.reports.append(json.loads(line))

    def of(self, cls: str, **has) -> list[dict]:
        return [r for r in self.reports if r.get("class") == cls and all(k in r for k in has)]

    async def _stderr(self) -> str:
        if self.proc is None or self.proc.stderr is None:
            return ""
        with contextlib.suppress(TimeoutError):
            return (await asyncio.wait_for(self.proc.stderr.read(4096), 1.0)).decode(errors="replace")
        return ""

    async def stop(self) -> None:
        if self._reader_task is not None:
            self._reader_task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._reader_task
        if self._writer is not None:
            self._writer.close()
        if self.proc is not None and self.proc.returncode is None:
            self.proc.terminate()
            try:
                await asyncio.wait_for(self.proc.wait(), 5.0)
            except TimeoutError:
                self.proc.kill()
                await self.proc.wait()


def _utc(tpv: dict) -> dt.datetime:
    return dt.datetime.fromisoformat(tpv["time"].replace("Z", "+00:00")).replace(tzinfo=None)


def _host_stream(run_dir: Path, link: str, direction: str) -> list:
    from emulator.recording.capture import read_capture

    _hdr, recs = read_capture(run_dir / "capture.psnscap")
    dec = StreamDecoder([HostFormat(), NmeaFormat()] if link == "host" else [NmeaFormat()])
    frames: list = []
    for r in recs:
        if r.link == link and r.direction == direction:
            frames.extend(dec.feed(r.data))
    assert dec.stats.crc_errors == 0
    return frames


def _kind(f) -> str:
    return str(getattr(f, "sentence", "") or getattr(f, "kind", "") or type(f).__name__)


def _ov(duration: float, motion: list, **extra) -> dict:
    """The quickstart without the camera (lighter in real time), heading from the configuration."""
    ov = {"duration_s": duration, "motion": motion, "expectations": [], "links.psns": None, "sensors.camera": None,
          "firmware.alignment.heading_source": "config", "firmware.alignment.heading_deg": 30.0}
    ov.update(extra)
    return ov


@pytest.mark.psns_emulator(mode="realtime")
async def test_gpsd_reads_the_modelled_gnss_from_its_pty_and_reports_the_emitted_fixes(tmp_path):
    from emulator.testing import start_emulator

    ov = _ov(16.0, [{"static": {"duration_s": 16.0}}],
             **{"links.gnss.url": "pty://gnss", "links.gnss.direction": "tee"})
    gpsd = Gpsd(tmp_path / "ports" / "gnss", tmp_path)
    async with start_emulator(QS, run_dir=tmp_path, overrides=ov) as emu:
        try:
            await gpsd.start(emu, timeout=10.0)
            await emu.wait_until(lambda: len(gpsd.of("TPV", lat=1, lon=1)) >= 4, timeout=14.0,
                                 what="four gpsd TPV fixes")
        finally:
            await gpsd.stop()
    # the GGA sentences the receiver put on its line (the FPGA end's capture: the bytes the pty carried)
    gga = {f.time_utc: f for f in _host_stream(tmp_path, "gnss", "in") if _kind(f) == "Gga" and f.quality > 0}
    tpvs = [t for t in gpsd.of("TPV", lat=1, lon=1, time=1) if t.get("mode", 0) >= 2]
    assert len(tpvs) >= 3, gpsd.reports
    for tpv in tpvs:
        g = gga[_utc(tpv).time()]  # gpsd's fix is the epoch the receiver emitted, by its UTC time
        de = (tpv["lon"] - g.lon_deg) * 60.0 * M_PER_ARCMIN * math.cos(math.radians(g.lat_deg))
        dn = (tpv["lat"] - g.lat_deg) * 60.0 * M_PER_ARCMIN
        assert math.hypot(de, dn) < 0.01, (tpv, g)
        assert abs(tpv["altMSL"] - g.altitude_msl_m) < 0.01, (tpv, g)
        assert tpv["mode"] == 3


@pytest.mark.psns_emulator(mode="realtime")
async def test_gpsd_reads_the_firmware_nmea_output_and_matches_the_nav_frames(tmp_path):
    """Vehicle: static 4 s (alignment), accelerating to 10 m/s on heading 30 deg, then cruising. The NMEA output
    goes out on a second host port (``links.host_nmea``, DSP UART2: no PSNS port here), NAV_SOLUTION on the host
    port. Each gpsd TPV is paired with the NAV_SOLUTION frame of the same tick: among the frames within 10 ms of
    its time (two at 100 Hz, 10 cm apart at 10 m/s) the one it lies within 1 cm of."""
    from emulator.testing import start_emulator

    motion = [{"static": {"duration_s": 4.0}}, {"accelerate": {"duration_s": 3.0, "to_speed_mps": 10.0}},
              {"cruise": {"duration_s": 12.0}}]
    ov = _ov(19.0, motion, **{
        "links.host_nmea": {"url": "pty://nmea", "baud": 115200},
        "fpga.routing": {"host": "uart0", "gnss": "uart3", "host_nmea": "uart2"},
        "firmware.nmea": {"sentences": ["GGA", "RMC", "VTG", "ZDA", "HDT", "PASHR"], "rate_hz": 1.0,
                          "attitude_rate_hz": 1.0}})
    gpsd = Gpsd(tmp_path / "ports" / "nmea", tmp_path)

    def moving() -> list[dict]:
        # the TPV after RMC (speed and track from the sentence); the one gpsd may report after GGA alone carries a
        # speed it differenced from the last two positions, and no track
        return [t for t in gpsd.of("TPV", lat=1, time=1, speed=1, track=1) if t["speed"] > 5.0]

    async with start_emulator(QS, run_dir=tmp_path, overrides=ov) as emu:
        row = next(p for p in emu.emulator.ports if p["name"] == "host_nmea")
        assert row["direction"] == "out" and str(tmp_path / "ports" / "nmea") in row["path"]
        try:
            await gpsd.start(emu, timeout=10.0)
            await emu.wait_until(lambda: len(moving()) >= 3, timeout=17.0, what="three gpsd TPVs at speed")
        finally:
            await gpsd.stop()
    epoch = emu.emulator.scn.epoch.replace(tzinfo=None)
    navs = [f for f in _host_stream(tmp_path, "host", "out") if isinstance(f, NavSolution)]
    assert navs

    def horizontal_m(tpv: dict, n: NavSolution) -> tuple[float, float]:
        de = (tpv["lon"] - n.lon_deg) * 60.0 * M_PER_ARCMIN * math.cos(math.radians(n.lat_deg))
        dn = (tpv["lat"] - n.lat_deg) * 60.0 * M_PER_ARCMIN
        return de, dn

    def frame_of(r: dict, t_utc: dt.datetime) -> NavSolution:
        near = [n for n in navs if abs((epoch + dt.timedelta(seconds=n.time_s) - t_utc).total_seconds()) <= 0.0101]
        assert near, (r, t_utc)
        return min(near, key=lambda n: math.hypot(*horizontal_m(r, n)) if "lat" in r else 0.0)

    tpvs = moving()
    assert len(tpvs) >= 3, gpsd.reports
    by_time: dict[str, NavSolution] = {}
    for tpv in tpvs:
        n = by_time[tpv["time"]] = frame_of(tpv, _utc(tpv))
        ve, vn, _vu = n.vel_enu_mps
        de, dn = horizontal_m(tpv, n)
        assert abs(de) < 0.0095 and abs(dn) < 0.0095, (tpv, n)  # half of 1e-5 arc-minute, per axis
        assert abs(tpv["altHAE"] - n.height_m) < 0.002, (tpv, n)  # GGA: 1 mm, geoid separation 0
        assert abs(tpv["speed"] - math.hypot(ve, vn)) < 2e-3, (tpv, n)  # RMC: 0.001 kn
        course = math.degrees(math.atan2(ve, vn)) % 360.0
        assert abs((tpv["track"] - course + 180.0) % 360.0 - 180.0) < 0.01, (tpv, n)  # 0.01 deg
        assert abs(course - 30.0) < 1.0  # the vehicle's heading: the NMEA track is the navigation's
    # heading: gpsd 3.22 reports HDT as an ATT without a time of its own; the firmware writes the heading group
    # first in its tick, so an ATT belongs to the tick of the next timed TPV in gpsd's report stream
    paired = []
    for i, r in enumerate(gpsd.reports):
        if r.get("class") == "ATT" and "heading" in r:
            nxt = next((x for x in gpsd.reports[i + 1:] if x.get("class") == "TPV" and "time" in x), None)
            if nxt is not None and nxt["time"] in by_time:
                paired.append((r, by_time[nxt["time"]]))
    assert len(paired) >= 2, gpsd.reports
    for a, n in paired:
        assert abs((a["heading"] - n.heading_deg + 180.0) % 360.0 - 180.0) < 0.006, (a, n)  # HDT: 0.01 deg


@pytest.mark.psns_emulator(mode="realtime")
async def test_gpsd_reads_the_full_box_nmea_output_with_the_camera_on(tmp_path):
    """The quickstart as it is (camera on UART2, GNSS on UART3: no free DSP UART) with ``links.host_nmea`` and no
    route of its own: the firmware writes NMEA and NAV_SOLUTION on UART0, the FPGA demultiplexes them (issue 38).
    gpsd on the NMEA pty reports fixes at the NAV_SOLUTION frames' positions; the host port carries no NMEA, the
    NMEA port nothing else."""
    from emulator.testing import start_emulator

    ov = {"duration_s": 14.0, "motion": [{"static": {"duration_s": 14.0}}], "expectations": [],
          "links.host_nmea": {"url": "pty://nmea", "baud": 115200},
          "firmware.nmea": {"sentences": ["GGA", "RMC", "ZDA", "HDT"], "rate_hz": 1.0, "attitude_rate_hz": 1.0}}
    gpsd = Gpsd(tmp_path / "ports" / "nmea", tmp_path)

    def fixes() -> list[dict]:
        return [t for t in gpsd.of("TPV", lat=1, lon=1, time=1) if t.get("mode", 0) >= 2]

    async with start_emulator(QS, run_dir=tmp_path, overrides=ov) as emu:
        assert emu.emulator.scn.sensors.camera is not None and emu.emulator.scn.links.psns is not None
        assert emu.emulator.fpga.host_demux is not None  # UART0 carries both
        try:
            await gpsd.start(emu, timeout=10.0)
            await emu.wait_until(lambda: len(fixes()) >= 3, timeout=13.0, what="three gpsd TPV fixes")
        finally:
            await gpsd.stop()
    host = _host_stream(tmp_path, "host", "out")
    navs = [f for f in host if isinstance(f, NavSolution)]
    assert navs and all(isinstance(f, NavSolution) or type(f).__name__ in ("Status", "Ack", "HostStatus")
                        for f in host), {type(f).__name__ for f in host}
    nmea = _host_stream(tmp_path, "host_nmea", "out")
    assert {_kind(f) for f in nmea} >= {"Gga", "Rmc"}
    epoch = emu.emulator.scn.epoch.replace(tzinfo=None)
    for tpv in fixes():
        t_utc = _utc(tpv)
        near = [n for n in navs if abs((epoch + dt.timedelta(seconds=n.time_s) - t_utc).total_seconds()) <= 0.0051]
        assert near, tpv
        n = near[0]
        de = (tpv["lon"] - n.lon_deg) * 60.0 * M_PER_ARCMIN * math.cos(math.radians(n.lat_deg))
        dn = (tpv["lat"] - n.lat_deg) * 60.0 * M_PER_ARCMIN
        assert abs(de) < 0.0095 and abs(dn) < 0.0095, (tpv, n)
