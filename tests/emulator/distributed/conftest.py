"""Fixtures for the distributed transports: free loopback ports, zenoh link pairs that always close."""

from __future__ import annotations

import asyncio
import socket
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
import yaml

from emulator.clock import EmulatorLoop
from emulator.links import LineConfig, open_link

#: the line of the zenoh link pairs unless a test gives its own
DEFAULT_LINE = LineConfig(baud=460800)


def free_tcp_port() -> int:
    """A TCP port on 127.0.0.1 that was free a moment ago (the OS picks it: no fixed-port collisions)."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


async def wait_until(pred: Callable[[], bool], timeout_s: float, poll_s: float = 0.002) -> bool:
    """Wait in the emulator's clock (realtime loop here) until ``pred()``; False on timeout."""
    loop = asyncio.get_running_loop()
    end = loop.time() + timeout_s
    while not pred():
        if loop.time() >= end:
            return False
        await asyncio.sleep(poll_s)
    return True


@pytest.fixture
def rt_loop():
    """A realtime EmulatorLoop, closed after the test."""
    loop = EmulatorLoop("realtime")
    asyncio.set_event_loop(loop)
    yield loop
    asyncio.set_event_loop(None)
    loop.close()


@pytest.fixture
def zenoh_links(rt_loop):
    """Factory ``make(url, name, line=...) -> opened ZenohLink``; every link is closed afterwards and
    the test fails if a zenoh session stays open."""
    from emulator.links.zenoh import open_sessions

    made: list[Any] = []

    def make(url: str, name: str = "port", line: LineConfig = DEFAULT_LINE) -> Any:
        link = open_link(url, name, rt_loop, default_line=line)
        rt_loop.run_until_complete(link.open())
        made.append(link)
        return link

    yield make
    for link in made:
        rt_loop.run_until_complete(link.close())
    assert open_sessions() == 0


def write_short_scenario(path, duration_s: float, name: str = "short", links: dict | None = None,
                         mode: str | None = None, expectations: list | None = None) -> Path:
    """The library quickstart scenario cut to ``duration_s`` (and optionally other links/mode), as a file."""
    root = Path(__file__).resolve().parents[3]
    data = yaml.safe_load((root / "scenarios" / "quickstart.yaml").read_text())
    data["name"] = name
    # the IMU + GNSS box these link tests were written for: without the camera the quickstart now carries
    data["sensors"].pop("camera", None)
    data["links"].pop("psns", None)
    data["firmware"]["alignment"] = {"time_s": 2.0, "heading_deg": 30.5, "heading_sigma_deg": 1.0}
    data["expectations"] = [e for e in data.get("expectations", [])
                            if e.get("nav_error", {}).get("metric") != "heading_deg"]
    data["duration_s"] = duration_s
    data["motion"] = [{"static": {"duration_s": duration_s}}]
    data["expectations"] = [e for e in data.get("expectations", [])
                            if "nav_error" not in e or e["nav_error"].get("after_s", 0) < duration_s]
    if expectations is not None:
        data["expectations"] = expectations
    if links:
        data.setdefault("links", {}).update(links)
    if mode is not None:
        data["mode"] = mode
    p = Path(path)
    p.write_text(yaml.safe_dump(data, sort_keys=False))
    return p
