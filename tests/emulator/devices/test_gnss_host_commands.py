"""The modelled u-blox answers a host on its own link (issue 18 item 1, the receiver half): MON-VER, CFG-PRT,
CFG-MSG and CFG-RATE polls and sets with ACK-ACK / ACK-NAK, the changes taking effect. The host's messages are
built by pyubx2 (an independent implementation) and the answers decoded by pyubx2 and by ours."""

from __future__ import annotations

import asyncio
import datetime as dt
import io

import numpy as np
from pyubx2 import POLL, SET, UBXMessage, UBXReader

from emulator.clock import EmulatorLoop
from emulator.devices.gnss import GnssConfig, GnssReceiver
from emulator.links import LineConfig, MemHub
from emulator.world.trajectory import StaticTrajectory
from protocols.nmea import Gga, Gsv, NmeaFormat, Rmc
from protocols.stream import StreamDecoder
from protocols.ubx import NavPvt, UbxFormat, UbxFrame

EPOCH = dt.datetime(2019, 9, 18, 8, 14, tzinfo=dt.UTC)


def _session(cfg: GnssConfig, script: list[tuple[float, bytes]], seconds: float) -> tuple[
        GnssReceiver, list[tuple[float, object]], bytes, list[float]]:
    """Run the receiver on a mem link; the host writes ``script`` (time, bytes); returns what the host read."""
    loop = EmulatorLoop("fast")
    dev, host = MemHub().pair("gnss", LineConfig(baud=115200), loop)
    pps: list[float] = []
    rx = GnssReceiver(dev, StaticTrajectory(39.979, 116.339, 50.0), EPOCH, np.random.default_rng(1), cfg,
                      pps=pps.append)
    dec = StreamDecoder([NmeaFormat(), UbxFormat()])
    got: list[tuple[float, object]] = []
    raw = bytearray()

    def on(data: bytes) -> None:
        raw.extend(data)
        got.extend((loop.time(), f) for f in dec.feed(data))

    host.on_receive = on

    async def main() -> None:
        rx.start()
        for t, data in script:
            loop.call_at(t, host.send, data)
        await asyncio.sleep(seconds)

    loop.run_until_complete(main())
    loop.close()
    assert dec.stats.crc_errors == 0 and dec.stats.length_errors == 0
    return rx, got, bytes(raw), pps


def _peer(raw: bytes) -> list:
    return [m for _, m in UBXReader(io.BytesIO(raw), protfilter=2)]


def test_polls_are_answered_and_acknowledged_as_a_u_blox_does() -> None:
    script = [
        (0.30, UBXMessage("MON", "MON-VER", POLL).serialize()),
        (0.40, UBXMessage("CFG", "CFG-PRT", POLL, portID=1).serialize()),
        (0.50, UBXMessage("CFG", "CFG-MSG", POLL, msgClass=0xF0, msgID=0x00).serialize()),
        (0.60, UBXMessage("CFG", "CFG-RATE", POLL).serialize()),
        (0.70, UBXMessage("CFG", "CFG-PRT", POLL, portID=3).serialize()),  # USB: not this receiver's port
    ]
    rx, _got, raw, _ = _session(GnssConfig(sentences=("GGA", "RMC")), script, 0.9)
    peer = [m for m in _peer(raw) if not m.identity.startswith("NAV")]
    assert [m.identity for m in peer] == ["MON-VER", "CFG-PRT", "ACK-ACK", "CFG-MSG", "ACK-ACK", "CFG-RATE",
                                          "ACK-ACK", "ACK-NAK"]
    ver, prt, msg, rate = peer[0], peer[1], peer[3], peer[5]
    assert ver.swVersion.rstrip(b"\0") == b"ROM CORE 3.01 (107888)" and ver.extension_02.startswith(b"PROTVER=18")
    assert (prt.portID, prt.baudRate, prt.outUBX, prt.outNMEA, prt.charLen, prt.parity) == (1, 115200, 1, 1, 3, 4)
    assert (msg.msgClass, msg.msgID, msg.rateUART1) == (0xF0, 0x00, 1)
    assert (rate.measRate, rate.navRate) == (1000, 1)
    assert (rx.host_polls, rx.host_acks, rx.host_naks) == (4, 3, 1)


def test_cfg_msg_and_cfg_prt_sets_change_the_output() -> None:
    script = [
        (0.3, UBXMessage("CFG", "CFG-MSG", SET, msgClass=0xF0, msgID=0x03, rateUART1=1).serialize()),  # GSV on
        (0.4, UBXMessage("CFG", "CFG-MSG", SET, msgClass=0xF0, msgID=0x04, rateUART1=0).serialize()),  # RMC off
        (0.5, UBXMessage("CFG", "CFG-MSG", SET, msgClass=0x01, msgID=0x07, rateUART1=2).serialize()),  # PVT / 2
        (0.6, UBXMessage("CFG", "CFG-MSG", SET, msgClass=0xF0, msgID=0x0A, rateUART1=1).serialize()),  # DTM: NAK
        (4.3, UBXMessage("CFG", "CFG-PRT", SET, portID=1, baudRate=115200, charLen=3, parity=4,
                         inUBX=1, inNMEA=1, outUBX=1, outNMEA=0).serialize()),                          # UBX only
    ]
    rx, got, raw, _ = _session(GnssConfig(sentences=("GGA", "RMC")), script, 7.5)
    acks = [m.identity for m in _peer(raw) if m.identity.startswith("ACK")]
    assert acks == ["ACK-ACK", "ACK-ACK", "ACK-ACK", "ACK-NAK", "ACK-ACK"]

    def when(cls: type, lo: float, hi: float) -> int:
        return sum(1 for t, f in got if isinstance(f, cls) and lo <= t < hi)
    assert when(Rmc, 0, 0.3) == 1 and when(Rmc, 0.5, 8) == 0
    assert when(Gsv, 0, 0.3) == 0 and when(Gsv, 0.5, 4.3) == 4 * 3  # epochs 1..4, 12 satellites: 3 sentences each
    assert when(NavPvt, 0.5, 4.3) == 2  # every second epoch: 2 and 4
    assert when(Gga, 0.5, 4.3) == 4 and when(Gga, 4.5, 8) == 0  # NMEA off from the CFG-PRT set on
    assert when(NavPvt, 4.5, 8) == 1  # epochs 5..7: only 6 (every second epoch)
    assert rx.host_naks == 1 and not [f for _, f in got if isinstance(f, UbxFrame) and f.cls not in (0x05,)]


def test_cfg_rate_set_takes_effect_at_the_next_second_and_pps_stays_1_hz() -> None:
    script = [
        (0.2, UBXMessage("CFG", "CFG-RATE", SET, measRate=100, navRate=1, timeRef=1).serialize()),
        (0.3, UBXMessage("CFG", "CFG-RATE", SET, measRate=10, navRate=1, timeRef=1).serialize()),  # 100 Hz: NAK
        (2.5, UBXMessage("CFG", "CFG-RATE", POLL).serialize()),
    ]
    _rx, got, raw, pps = _session(GnssConfig(sentences=("GGA",)), script, 3.05)
    t_gga = np.array([t for t, f in got if isinstance(f, Gga)])
    assert len(t_gga[t_gga < 1.0]) == 1 and len(t_gga[t_gga >= 1.0]) == 20  # 1 Hz, then 10 Hz from t = 1 s (to 2.9)
    assert np.allclose(np.diff(t_gga[1:]), 0.1)
    assert len(pps) == 4 and np.allclose(pps, [0, 1, 2, 3], atol=1e-6)
    peer = [m for m in _peer(raw)]
    assert [m.identity for m in peer] == ["ACK-ACK", "ACK-NAK", "CFG-RATE", "ACK-ACK"]
    assert peer[2].measRate == 100
