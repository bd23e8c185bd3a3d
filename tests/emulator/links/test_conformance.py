"""Every transport passes the same conformance suite (tests/emulator/links/conformance.py)."""

from __future__ import annotations

import asyncio
import os
import shutil
import subprocess
import time
from pathlib import Path

import pytest

from emulator.links import MemHub
from emulator.links.pty import PtyLink
from emulator.links.serial import SerialLink

from .conformance import check_link_pair


def test_mem_transport_conforms():
    async def make_pair(loop, line_a, line_b):
        hub = MemHub()
        a, b = hub.pair("x", line_a, loop, line_b=line_b)
        a.name, b.name = "a", "b"

        async def cleanup():
            await a.close()
            await b.close()

        return a, b, cleanup

    check_link_pair(make_pair, mode="fast")


async def _wait_attached(link: PtyLink, timeout: float = 2.0) -> None:
    loop = asyncio.get_running_loop()
    deadline = loop.time() + timeout
    while not link.attached:
        assert loop.time() < deadline, "the pty never saw its peer attach"
        await asyncio.sleep(0.005)


@pytest.mark.pty
@pytest.mark.realtime
def test_pty_transport_conforms(tmp_path):
    """The device end is a PtyLink; the peer is pyserial on its stable symlink (a serial:// link)."""
    counter = iter(range(100))

    async def make_pair(loop, line_a, line_b):
        k = next(counter)
        a = PtyLink("a", f"pty://p{k}", line_a, loop, target=f"p{k}", run_dir=tmp_path / "ports")
        await a.open()
        b = SerialLink("b", f"serial://{a.link_path}", line_b, loop, target=str(a.link_path))
        await b.open()
        await _wait_attached(a)

        async def cleanup():
            await b.close()
            await a.close()

        return a, b, cleanup

    check_link_pair(make_pair, mode="realtime")


def _socat_pair(d: Path) -> tuple[subprocess.Popen, Path, Path]:
    a, b = d / "ta", d / "tb"
    proc = subprocess.Popen(["socat", f"pty,raw,echo=0,link={a}", f"pty,raw,echo=0,link={b}"],
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 5.0
    while not (a.exists() and b.exists()):
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            raise RuntimeError("socat did not create its pty pair")
        time.sleep(0.01)
    return proc, a, b


@pytest.mark.pty
@pytest.mark.skipif(shutil.which("socat") is None, reason="socat is not installed (apt-get install socat); "
                    "the serial transport needs a socat pty pair to talk to itself")
@pytest.mark.realtime
def test_serial_transport_conforms(tmp_path):
    """Both ends are serial:// links (pyserial) on the two ptys of a socat pair."""
    procs: list[subprocess.Popen] = []
    counter = iter(range(100))

    async def make_pair(loop, line_a, line_b):
        d = tmp_path / f"s{next(counter)}"
        d.mkdir()
        proc, pa, pb = _socat_pair(d)
        procs.append(proc)
        a = SerialLink("a", f"serial://{pa}", line_a, loop, target=str(pa))
        b = SerialLink("b", f"serial://{pb}", line_b, loop, target=str(pb))
        await a.open()
        await b.open()

        async def cleanup():
            await a.close()
            await b.close()
            proc.terminate()
            proc.wait(5)

        return a, b, cleanup

    try:
        check_link_pair(make_pair, mode="realtime")
    finally:
        for p in procs:
            if p.poll() is None:
                p.kill()
                p.wait(5)


@pytest.mark.realtime
def test_socat_is_available_in_ci():
    """CI (.ci/run) installs socat; say so loudly here rather than silently skipping above."""
    if shutil.which("socat") is None:
        pytest.skip("socat is not installed: the serial conformance and socat bridge tests are skipped")
    assert os.access(shutil.which("socat"), os.X_OK)
