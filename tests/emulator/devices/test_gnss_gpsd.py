"""gpsd 3.22 talks to the modelled u-blox receiver over a pty: it identifies it through its UBX polls (MON-VER),
shows its sky (GSV) and its fixes. The receiver runs in-process on a mem link; the test bridges that link's host
end to a pty (the other side of a real serial port), where gpsd reads and writes as on a real device."""

from __future__ import annotations

import asyncio
import datetime as dt
import json
import os
import pty
import shutil
import socket
import subprocess
import tty

import numpy as np
import pytest

from emulator.clock import EmulatorLoop
from emulator.devices.gnss import MON_VER, GnssConfig, GnssErrors, GnssReceiver, constellation
from emulator.links import LineConfig, MemHub
from emulator.world.trajectory import StaticTrajectory

pytestmark = [pytest.mark.realtime, pytest.mark.pty,
              pytest.mark.skipif(not shutil.which("gpsd") and not os.path.exists("/usr/sbin/gpsd"),
                                 reason="gpsd not installed (.ci/run installs it)")]

GPSD = shutil.which("gpsd") or "/usr/sbin/gpsd"
LAT, LON, H = 39.979, 116.339, 50.0


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_gpsd_identifies_the_u_blox_by_its_polls_and_shows_its_sky_and_fixes(tmp_path) -> None:
    master, slave = pty.openpty()
    tty.setraw(master)
    tty.setraw(slave)
    path = os.ttyname(slave)
    port = _free_port()
    loop = EmulatorLoop("realtime")
    dev, host = MemHub().pair("gnss", LineConfig(baud=115200), loop)
    cfg = GnssConfig(sentences=("RMC", "GGA", "GSA", "GSV"), ubx=("NAV-PVT",), num_sats=10,
                     errors=GnssErrors(pos_sigma_h_m=0.0, pos_sigma_v_m=0.0, vel_sigma_h_mps=0.0,
                                       vel_sigma_v_mps=0.0))
    rx = GnssReceiver(dev, StaticTrajectory(LAT, LON, H), dt.datetime.now(dt.UTC).replace(microsecond=0),
                      np.random.default_rng(1), cfg)
    host.on_receive = lambda d: os.write(master, d)
    os.set_blocking(master, False)

    def from_gpsd() -> None:
        try:
            data = os.read(master, 4096)
        except BlockingIOError:
            return
        if data:
            host.send(data)

    gpsd = subprocess.Popen([GPSD, "-N", "-n", "-S", str(port), "-F", str(tmp_path / "gpsd.sock"),
                             "-P", str(tmp_path / "gpsd.pid"), path],
                            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    reports: list[dict] = []

    async def main() -> None:
        loop.add_reader(master, from_gpsd)
        rx.start()
        await asyncio.sleep(1.0)
        pipe = subprocess.Popen(["gpspipe", "-w", f"127.0.0.1:{port}"], stdout=subprocess.PIPE,
                                stderr=subprocess.DEVNULL)
        assert pipe.stdout is not None
        os.set_blocking(pipe.stdout.fileno(), False)
        buf = bytearray()

        def on_pipe() -> None:
            chunk = os.read(pipe.stdout.fileno(), 65536)  # type: ignore[union-attr]
            buf.extend(chunk)

        loop.add_reader(pipe.stdout.fileno(), on_pipe)
        def query_devices() -> list[dict]:
            """gpsd's answer to ?DEVICES: the identification it keeps (subtype = our MON-VER's versions; gpsd
            sends the subtype to watchers only once, so it is asked for)."""
            with socket.create_connection(("127.0.0.1", port), timeout=3.0) as c:
                c.sendall(b"?DEVICES;\n")
                got = b""
                while b'"class":"DEVICES"' not in got or not got.endswith(b"\n"):
                    part = c.recv(65536)
                    if not part:
                        break
                    got += part
            return [json.loads(x) for x in got.splitlines() if x.startswith(b"{")]

        # polled in the emulator's (wall) clock: gpsd polls MON-VER only after it identified the u-blox, which on
        # a loaded machine comes well after the first fixes
        deadline = loop.time() + 40.0
        devices: list[dict] = []
        while loop.time() < deadline:
            await asyncio.sleep(0.2)
            lines = [json.loads(x) for x in bytes(buf).splitlines() if x.startswith(b"{")]
            drivers = [r.get("driver", "") for r in lines if r.get("class") == "DEVICE"]
            sky = [r for r in lines if r.get("class") == "SKY" and r.get("satellites")]
            tpv = [r for r in lines if r.get("class") == "TPV" and r.get("mode", 0) >= 3]
            if any("u-blox" in d for d in drivers) and sky and len(tpv) >= 2:
                devices = query_devices()
                if any(MON_VER.swVersion in d.get("subtype", "") for r in devices
                       for d in r.get("devices", [])):
                    break
        reports.extend(devices)
        reports.extend(json.loads(x) for x in bytes(buf).splitlines() if x.startswith(b"{"))
        loop.remove_reader(pipe.stdout.fileno())
        pipe.terminate()
        pipe.wait(5)
        loop.remove_reader(master)

    try:
        loop.run_until_complete(main())
    finally:
        gpsd.terminate()
        gpsd.wait(5)
        loop.close()
        os.close(master)
        os.close(slave)
    dev_reports = [r for r in reports if r.get("class") == "DEVICE" and "u-blox" in r.get("driver", "")]
    dev_reports += [d for r in reports if r.get("class") == "DEVICES" for d in r.get("devices", [])]
    assert dev_reports, f"gpsd did not identify a u-blox: {[r for r in reports if r.get('class') == 'DEVICE']}"
    assert any(MON_VER.swVersion in r.get("subtype", "") for r in dev_reports), (dev_reports, rx.host_polls,
                                                                                 rx.host_acks, rx.host_ignored)
    assert rx.host_polls >= 1  # gpsd polled (MON-VER at least) and was answered
    sky = [r for r in reports if r.get("class") == "SKY" and r.get("satellites")][-1]
    want = {(e[1], e[2], e[3]) for e in constellation("GP", 10)}
    got = {(s["PRN"], round(s["el"]), round(s["az"])) for s in sky["satellites"]}
    assert want <= got
    tpv = [r for r in reports if r.get("class") == "TPV" and r.get("mode", 0) >= 3][-1]
    m_per_deg = 111_000.0
    assert abs(tpv["lat"] - LAT) * m_per_deg < 0.01 and abs(tpv["lon"] - LON) * m_per_deg < 0.01
