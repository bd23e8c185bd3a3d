"""pty specifics: a peer that does not read, a peer set to another baud."""

from __future__ import annotations

import asyncio

import pytest

from emulator.clock import EmulatorLoop
from emulator.links import LineConfig
from emulator.links.pty import PtyLink

pytestmark = [pytest.mark.pty, pytest.mark.realtime]


def _run(coro_fn, tmp_path):
    loop = EmulatorLoop("realtime")
    try:
        return loop.run_until_complete(coro_fn(loop, tmp_path))
    finally:
        loop.close()


async def _until(cond, what: str, timeout_s: float = 2.0) -> None:
    """Poll ``cond`` every 5 ms until it holds; fail naming ``what`` after ``timeout_s`` (wall clock, s)."""
    deadline = asyncio.get_running_loop().time() + timeout_s
    while not cond():
        if asyncio.get_running_loop().time() > deadline:
            raise AssertionError(f"timed out after {timeout_s} s waiting for {what}")
        await asyncio.sleep(0.005)


async def _attached(link: PtyLink) -> None:
    await _until(lambda: link.attached, "the peer to attach")


def test_peer_that_never_reads_causes_counted_overflow_not_memory(tmp_path):
    import serial

    async def main(loop, d):
        link = PtyLink("p", "pty://p", LineConfig(baud=3_000_000, tx_queue_bytes=4096), loop, target="p",
                       run_dir=d / "ports")
        await link.open()
        peer = serial.Serial(str(link.link_path), 3_000_000, timeout=0)
        try:
            await _attached(link)
            sent = 0
            for _ in range(60):  # 60 x 2 KiB offered over ~0.4 s at 300 kB/s; nobody reads
                sent += link.send(bytes(2048))
                await asyncio.sleep(0.007)
            await _until(lambda: link.stats.bytes_out == sent, "the line to hand every accepted byte to the pty")
            st = link.stats
            offered = 60 * 2048
            queue_drops = offered - sent  # the line model's TX queue (4 KiB) overflowed
            pty_drops = st.dropped_out - queue_drops  # the kernel refused the rest (EAGAIN)
            assert st.bytes_out == sent and pty_drops > 0
            in_kernel = st.bytes_out - pty_drops
            assert in_kernel <= 64 * 1024  # the pty's buffers, not an ever-growing queue
            # every byte is accounted for: the late reader gets exactly what the kernel accepted
            got = 0
            for _ in range(100):
                chunk = peer.read(65536)
                got += len(chunk)
                if not chunk and got:
                    break
                await asyncio.sleep(0.005)
            assert got == in_kernel
        finally:
            peer.close()
            await link.close()

    _run(main, tmp_path)


@pytest.mark.parametrize("check", [False, True])
def test_client_at_another_baud_sees_framing_errors_only_when_checked(tmp_path, check):
    import serial

    async def main(loop, d):
        url = "pty://p?peer_baud=check" if check else "pty://p"
        from emulator.links import parse_link_url

        link = PtyLink("p", url, LineConfig(baud=115200), loop, target="p", run_dir=d / "ports",
                       options=parse_link_url(url).options)
        await link.open()
        got = bytearray()
        link.on_receive = got.extend
        client = serial.Serial(str(link.link_path), 9600, timeout=0)  # 12x slower than the port
        try:
            await _attached(link)
            await _until(lambda: link.peer_baud is not None, "an attach poll to read the client's termios speed")
            assert link.peer_baud == 9600
            payload = bytes(range(256)) * 2
            client.write(payload)
            # 512 bytes at 115200 = 44 ms (the client's speed is not real)
            if check:
                await _until(lambda: link.stats.framing_errors > 0, "framing errors")
            else:
                await _until(lambda: len(got) >= len(payload), "the whole payload")
            if check:
                assert link.stats.framing_errors > 0 and bytes(got) != payload
            else:
                assert bytes(got) == payload and link.stats.framing_errors == 0
        finally:
            client.close()
            await link.close()

    _run(main, tmp_path)
