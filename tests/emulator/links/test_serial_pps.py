"""PPS from a serial port's DCD/CTS line (serial:// ?pps=dcd|cts), the TIOCMIWAIT path.

A pseudo-terminal carries no modem lines (TIOCMGET and TIOCMIWAIT fail with ENOTTY on a pty), and this machine
has no serial adapter with a receiver on it. The strongest honest substitute: the link opens a *real* pty with
pyserial (the data path is real), and only the two ioctls at the OS boundary are answered by a fake device
that implements their contract (TIOCMIWAIT blocks until a watched line changes; TIOCMGET packs the line bits).
The second test shows the real pty's refusal and that it is reported, not hidden.
"""

from __future__ import annotations

import asyncio
import os
import pty
import struct
import termios
import threading
import time

import pytest

from emulator.links import LineConfig
from emulator.links.serial import TIOCMIWAIT, ModemPpsWatcher, SerialLink

pytestmark = [pytest.mark.realtime, pytest.mark.pty]


class FakeModemLines:
    """The TIOCMGET / TIOCMIWAIT contract of a serial driver, for one fd; :meth:`set` changes the lines."""

    def __init__(self) -> None:
        self.lines = 0
        self.cond = threading.Condition()
        self.changes = 0
        self.calls: list[int] = []

    def set(self, bits: int) -> None:
        with self.cond:
            self.lines = bits
            self.changes += 1
            self.cond.notify_all()

    def ioctl(self, fd: int, req: int, arg: object) -> object:
        self.calls.append(req)
        if req == termios.TIOCMGET:
            with self.cond:
                return struct.pack("I", self.lines)
        if req == TIOCMIWAIT:
            assert isinstance(arg, int)
            with self.cond:
                start, old = self.changes, self.lines
                while not (self.changes != start and (self.lines ^ old) & arg):
                    if not self.cond.wait(timeout=5.0):
                        raise OSError(5, "fake device: no modem-line change within 5 s")
                return 0
        raise OSError(25, "Inappropriate ioctl for device")


@pytest.mark.parametrize("line", ["dcd", "cts"])
def test_pps_edges_on_a_modem_line_reach_on_pps_with_the_loop_time(line: str) -> None:
    bit = termios.TIOCM_CAR if line == "dcd" else termios.TIOCM_CTS
    other = termios.TIOCM_CTS if line == "dcd" else termios.TIOCM_CAR
    master, slave = pty.openpty()
    loop = asyncio.new_event_loop()
    fake = FakeModemLines()
    link = SerialLink("gnss", f"serial://{os.ttyname(slave)}?pps={line}", LineConfig(baud=9600), loop,
                      target=os.ttyname(slave), options={"pps": line})
    link.ioctl = fake.ioctl
    edges: list[float] = []
    link.on_pps = edges.append
    got = bytearray()
    link.on_receive = got.extend
    asserted: list[tuple[float, float]] = []

    def pulses() -> None:
        time.sleep(0.05)
        for _ in range(5):
            t0 = loop.time()
            fake.set(fake.lines | bit)          # rising edge of the timepulse
            asserted.append((t0, loop.time()))
            time.sleep(0.01)
            fake.set(fake.lines | other)        # the other line changing is no PPS
            time.sleep(0.01)
            fake.set(fake.lines & ~bit & ~other)  # falling edge
            time.sleep(0.03)

    async def main() -> None:
        await link.open()
        th = threading.Thread(target=pulses)
        th.start()
        os.write(master, b"$GPGGA,data path stays real\r\n")
        deadline = loop.time() + 5.0
        while (len(edges) < 5 or not got) and loop.time() < deadline:
            await asyncio.sleep(0.005)
        th.join()
        await link.close()

    try:
        loop.run_until_complete(main())
    finally:
        loop.close()
        os.close(master)
        os.close(slave)
    assert len(edges) == 5 == link.pps_edges and link.pps_error is None
    for t, (t0, _t1) in zip(edges, asserted, strict=True):
        assert t0 <= t < t0 + 0.02  # stamped right after the wake-up (wall clock: scheduling, not modelling)
    assert bytes(got) == b"$GPGGA,data path stays real\r\n"
    assert TIOCMIWAIT in fake.calls and termios.TIOCMGET in fake.calls


def test_a_pty_has_no_modem_lines_and_the_link_says_so() -> None:
    master, slave = pty.openpty()
    loop = asyncio.new_event_loop()
    path = os.ttyname(slave)
    link = SerialLink("gnss", f"serial://{path}?pps=dcd", LineConfig(baud=9600), loop, target=path,
                      options={"pps": "dcd"})
    got = bytearray()
    link.on_receive = got.extend

    async def main() -> None:
        await link.open()
        os.write(master, b"abc")
        deadline = loop.time() + 2.0
        while not got and loop.time() < deadline:
            await asyncio.sleep(0.005)
        await link.close()

    try:
        loop.run_until_complete(main())
    finally:
        loop.close()
        os.close(master)
        os.close(slave)
    assert link.pps_error is not None and "no modem lines" in link.pps_error and "Errno 25" in link.pps_error
    assert "PPS on DCD" in link.describe()
    assert bytes(got) == b"abc"  # the data path is unaffected


def test_unknown_pps_line_is_a_config_error() -> None:
    from emulator.errors import LinkConfigError

    loop = asyncio.new_event_loop()
    try:
        with pytest.raises(LinkConfigError, match="pps='ri'"):
            SerialLink("gnss", "serial:///dev/ttyS0?pps=ri", LineConfig(), loop, target="/dev/ttyS0",
                       options={"pps": "ri"})
        with pytest.raises(LinkConfigError):
            ModemPpsWatcher(0, "ri", loop, print, print)
    finally:
        loop.close()


def test_a_run_with_pps_on_dcd_of_a_pty_reports_that_there_is_no_pps(tmp_path) -> None:
    """End to end: a scenario puts the GNSS port on ``serial://<pty>?pps=dcd``; the run goes on (the data path is
    the pty's) and the summary says why no PPS came."""
    from emulator.assembly.session import run_scenario
    from emulator.scenario.schema import Scenario

    master, slave = pty.openpty()
    try:
        scn = Scenario.model_validate({
            "name": "pps-on-pty", "epoch": "2019-09-18T08:14:00Z", "duration_s": 2, "mode": "realtime",
            "origin": {"lat_deg": 39.979, "lon_deg": 116.339, "height_m": 50},
            "links": {"gnss": {"url": f"serial://{os.ttyname(slave)}?pps=dcd", "baud": 9600}}})
        summary = run_scenario(scn, tmp_path / "run")
    finally:
        os.close(master)
        os.close(slave)
    st = summary["link_stats"]["gnss"]
    assert st["pps_line"] == "dcd" and st["pps_edges"] == 0
    assert "no modem lines" in st["pps_error"] and "Errno 25" in st["pps_error"]
