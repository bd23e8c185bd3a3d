"""The line model on in-memory links: byte timing, queueing, overflow."""

import asyncio

import pytest

from emulator.clock import EmulatorLoop
from emulator.links import LineConfig, MemHub, open_link


def test_frame_arrives_after_its_wire_time():
    loop = EmulatorLoop("fast")
    hub = MemHub()
    a, b = hub.pair("x", LineConfig(baud=9600), loop)
    got = []
    b.on_receive = lambda d: got.append((loop.time(), d))

    async def main():
        a.send(b"A" * 40)  # 40 bytes * 10 bits / 9600 baud = 41.667 ms
        a.send(b"B" * 10)  # queued behind: ends at 50 bytes -> 52.083 ms
        await asyncio.sleep(1.0)

    loop.run_until_complete(main())
    loop.close()
    assert got[0][0] == pytest.approx(400 / 9600)
    assert got[1][0] == pytest.approx(500 / 9600)
    assert got[0][1] == b"A" * 40 and got[1][1] == b"B" * 10


def test_parity_and_stop_bits_count():
    assert LineConfig(baud=115200, parity="E", stop_bits=2).bits_per_byte == 12
    assert LineConfig(baud=115200).byte_time == pytest.approx(10 / 115200)


def test_saturated_line_overflows_and_counts():
    loop = EmulatorLoop("fast")
    hub = MemHub()
    a, b = hub.pair("x", LineConfig(baud=9600, tx_queue_bytes=100), loop)
    total = []
    b.on_receive = lambda d: total.append(len(d))

    async def main():
        for _ in range(10):
            a.send(b"z" * 40)  # 400 bytes offered at once, queue holds 100
        await asyncio.sleep(2.0)

    loop.run_until_complete(main())
    loop.close()
    assert sum(total) == 100
    assert a.stats.dropped_out == 300


def test_open_link_by_url_pairs_mem_names():
    loop = EmulatorLoop("fast")
    hub = MemHub()
    a = open_link("mem://bus?baud=115200", "a", loop, hub=hub)
    b = open_link("mem://bus", "b", loop, hub=hub)
    assert a.peer is b and b.peer is a and a.line.baud == 115200
    loop.close()


def test_bad_urls_are_clear_errors():
    from emulator.errors import LinkConfigError
    from emulator.links import parse_link_url

    with pytest.raises(LinkConfigError, match="unknown link scheme 'tcp'"):
        parse_link_url("tcp://x")
    with pytest.raises(LinkConfigError, match="unknown option"):
        parse_link_url("pty://uart0?bod=9600")
