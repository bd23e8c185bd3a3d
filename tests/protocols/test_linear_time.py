"""Linear-time decoding on crafted input (docs/hostile-input.md): every decoder the firmware and the monitor tool
use, and every protocol together, fed 1 MB of a stuck line (0x00, a BREAK) and 1 MB of ``$``, in one chunk and in
4 KB chunks, decodes faster than a floor far above what the quadratic paths managed (monitor on 0x00: ~1 KB/s;
NMEA+UBX on ``$``: 461 s per MB) and keeps a bounded buffer."""

from __future__ import annotations

import time

import pytest

from protocols.host import HostFormat
from protocols.imu_frame import FpgaFrameFormat
from protocols.monitor import MonitorFormat
from protocols.nmea import NmeaFormat
from protocols.psns import PsnsFormat
from protocols.stim import Stim210Format
from protocols.stream import StreamDecoder
from protocols.ubx import UbxFormat

MB = 1 << 20
#: bytes/s every decoder keeps up with on 1 MB of crafted input (the line rate of a 3 Mbaud UART is 300 KB/s; the
#: floor leaves room for a loaded CI core and is 100x what the quadratic paths reached)
FLOOR_BPS = 100_000

DECODERS = {
    "firmware_gnss": lambda: [NmeaFormat(), UbxFormat()],
    "firmware_imu": lambda: [FpgaFrameFormat()],
    "firmware_host": lambda: [HostFormat()],
    "firmware_psns": lambda: [PsnsFormat()],
    "stim210": lambda: [Stim210Format("m")],
    "monitor": lambda: [MonitorFormat()],
    "every_protocol": lambda: [HostFormat(), FpgaFrameFormat(), Stim210Format("m"), NmeaFormat(), PsnsFormat(),
                               UbxFormat(), MonitorFormat()],
}
FLOODS = {"stuck_line_00": bytes(MB), "dollar_flood": b"$" * MB}


@pytest.mark.parametrize("chunk", [MB, 4096])
@pytest.mark.parametrize("flood", sorted(FLOODS))
@pytest.mark.parametrize("decoder", sorted(DECODERS))
def test_one_megabyte_flood_decodes_in_linear_time(decoder: str, flood: str, chunk: int) -> None:
    data = FLOODS[flood]
    dec = StreamDecoder(DECODERS[decoder]())
    t0 = time.perf_counter()
    for k in range(0, len(data), chunk):
        assert dec.feed(data[k : k + chunk]) == []
    dt = time.perf_counter() - t0
    assert len(data) / dt >= FLOOR_BPS, f"{decoder} on {flood}: {len(data) / dt / 1e3:.1f} KB/s"
    assert dec.pending() <= 2048
