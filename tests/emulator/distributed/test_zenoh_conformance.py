"""The zenoh transport passes the link conformance suite (tests/emulator/links/conformance.py): two sessions
on 127.0.0.1 (fresh port each pair, scouting off), as two emulator processes would use it (``pace=0``) and as a
tool-facing port does (``pace=1``)."""

from __future__ import annotations

import itertools

import pytest

from emulator.links.zenoh import ZenohLink, open_sessions

from ..links.conformance import check_link_pair
from .conftest import free_tcp_port

_keys = itertools.count()

pytestmark = pytest.mark.realtime  # sockets and processes on the wall clock



def _make_pair(pace: int):
    async def make_pair(loop, line_a, line_b):
        port = free_tcp_port()
        key = f"conf{next(_keys)}/x"
        a = ZenohLink("a", f"zenoh://{key}?listen=tcp/127.0.0.1:{port}&pace={pace}", line_a, loop, target=key)
        b = ZenohLink("b", f"zenoh://{key}?role=peer&connect=tcp/127.0.0.1:{port}&pace={pace}", line_b, loop,
                      target=key)
        await a.open()
        await b.open()
        assert await a.wait_matched(5.0) and await b.wait_matched(5.0), "zenoh peers did not discover each other"

        async def cleanup():
            await b.close()
            await a.close()

        return a, b, cleanup

    return make_pair


@pytest.mark.parametrize("pace", [0, 1])
def test_zenoh_transport_conforms(pace):
    check_link_pair(_make_pair(pace), mode="realtime")
    assert open_sessions() == 0


def test_unpaced_end_keeps_the_senders_byte_spacing():
    """pace=0: the receiver sees the transmitter's byte pitch (cut-through timing survives the process hop)."""
    import asyncio

    from emulator.clock import EmulatorLoop
    from emulator.links import LineConfig

    loop = EmulatorLoop("realtime")
    try:
        async def main():
            a, b, cleanup = await _make_pair(0)(loop, LineConfig(baud=9600), LineConfig(baud=460800))
            try:
                got: list[bytes] = []
                b.on_receive = got.append
                a.send(b"x" * 20)  # 20 bytes at 9600 Bd: 1.042 ms per byte
                end = loop.time() + 2.0
                while not got and loop.time() < end:
                    await asyncio.sleep(0.002)
                assert got == [b"x" * 20]
                assert b.last_rx_pitch == pytest.approx(10 / 9600)  # not b's own 460800 Bd byte time
            finally:
                await cleanup()

        loop.run_until_complete(main())
    finally:
        loop.close()
    assert open_sessions() == 0
