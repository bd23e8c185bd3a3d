"""can:// links: NAV_SOLUTION frames out of the host port become DBC-encoded CAN frames (python-can virtual
bus), decoded back with cantools."""

from __future__ import annotations

import asyncio
import glob
import os
from pathlib import Path

import cantools
import numpy as np
import pytest

can = pytest.importorskip("can")

from emulator.clock import EmulatorLoop  # noqa: E402
from emulator.errors import LinkBrokenError, LinkConfigError  # noqa: E402
from emulator.links import LineConfig, open_link  # noqa: E402
from emulator.links.can import NavCanEncoder, nav_signal_values  # noqa: E402
from protocols.host import NavMode, NavSolution, encode_nav_solution  # noqa: E402

DBC = Path(__file__).with_name("minimal_psns_nav.dbc")


def _nav(k: int, rng: np.random.Generator) -> NavSolution:
    return NavSolution(
        seq=k, time_s=0.01 * k, lat_deg=float(rng.uniform(-89, 89)), lon_deg=float(rng.uniform(-179, 179)),
        height_m=float(rng.uniform(-100, 5000)), vel_enu_mps=tuple(float(v) for v in rng.uniform(-50, 50, 3)),
        roll_deg=float(rng.uniform(-179, 179)), pitch_deg=float(rng.uniform(-89, 89)),
        heading_deg=float(rng.uniform(0, 359.99)), sigma=tuple(float(v) for v in rng.uniform(0, 1, 9)),
        mode=int(NavMode.NAVIGATING | NavMode.GNSS_AIDED), gnss_status=int(rng.integers(0, 9)), psns_status=0,
        cpu_load_pct=round(float(rng.uniform(0, 100)), 2), deadline_misses=0)


@pytest.fixture
def fast_loop():
    loop = EmulatorLoop("fast")
    yield loop
    loop.close()


@pytest.fixture
def rx_bus(request):
    channel = f"psns-test-{request.node.name}"
    bus = can.Bus(interface="virtual", channel=channel)
    yield channel, bus
    bus.shutdown()


def _drain(bus) -> list:
    out = []
    while (m := bus.recv(timeout=0)) is not None:
        out.append(m)
    return out


def _run_link(loop, link, frames: list[bytes], chunk: int = 29) -> None:
    blob = b"".join(frames)

    async def main():
        await link.open()
        try:
            for i in range(0, len(blob), chunk):
                link.send(blob[i:i + chunk])
                await asyncio.sleep(0.001)
            await asyncio.sleep(1.0)
        finally:
            await link.close()

    loop.run_until_complete(main())


def test_nav_frames_become_dbc_frames_that_cantools_decodes(fast_loop, rx_bus):
    channel, bus = rx_bus
    rng = np.random.default_rng(3)
    navs = [_nav(k, rng) for k in range(40)]
    link = open_link(f"can://virtual/{channel}?dbc={DBC}", "host", fast_loop,
                     default_line=LineConfig(baud=460800, tx_queue_bytes=1 << 16))
    _run_link(fast_loop, link, [encode_nav_solution(n) for n in navs])
    msgs = _drain(bus)
    db = cantools.database.load_file(str(DBC))
    assert len(msgs) == 40 * len(db.messages) == link.can_frames_sent
    assert link.nav_frames == 40 and link.can_send_errors == 0
    by_nav: dict[int, dict[str, float]] = {}
    k = -1
    for m in msgs:
        d = db.decode_message(m.arbitration_id, m.data)
        if m.arbitration_id == db.get_message_by_name("NAV_STATUS").frame_id:
            k += 1
        by_nav.setdefault(k, {}).update(d)
    assert len(by_nav) == 40
    for k, n in enumerate(navs):
        want = nav_signal_values(n)
        got = by_nav[k]
        for sig in (s for msg in db.messages for s in msg.signals):
            tol = abs(sig.scale) / 2 + 1e-9 + 1e-6 * abs(want[sig.name])
            assert got[sig.name] == pytest.approx(want[sig.name], abs=tol), sig.name


def test_rate_option_decimates_in_navigation_time(fast_loop, rx_bus):
    channel, bus = rx_bus
    rng = np.random.default_rng(4)
    link = open_link(f"can://virtual/{channel}?dbc={DBC}&rate=10", "host", fast_loop,
                     default_line=LineConfig(baud=460800, tx_queue_bytes=1 << 16))
    _run_link(fast_loop, link, [encode_nav_solution(_nav(k, rng)) for k in range(100)])  # 1 s at 100 Hz
    msgs = _drain(bus)
    status = [m for m in msgs if m.arbitration_id == 256]
    assert link.nav_frames == 100 and len(status) == 10
    db = cantools.database.load_file(str(DBC))
    assert [db.decode_message(256, m.data)["seq"] for m in status] == list(range(0, 100, 10))


def test_corrupt_bytes_are_skipped_by_the_stream_decoder(fast_loop, rx_bus):
    channel, bus = rx_bus
    rng = np.random.default_rng(5)
    good = [encode_nav_solution(_nav(k, rng)) for k in range(3)]
    bad = bytearray(good[1])
    bad[20] ^= 0x40  # CRC now fails
    link = open_link(f"can://virtual/{channel}?dbc={DBC}", "host", fast_loop,
                     default_line=LineConfig(baud=460800, tx_queue_bytes=1 << 16))
    _run_link(fast_loop, link, [b"\x00junk\xa5", good[0], bytes(bad), good[2]])
    status = [m for m in _drain(bus) if m.arbitration_id == 256]
    db = cantools.database.load_file(str(DBC))
    assert [db.decode_message(256, m.data)["seq"] for m in status] == [0, 2]
    assert link.decoder_stats["crc_errors"] == 1


def test_out_of_range_values_saturate_and_counters_wrap():
    enc = NavCanEncoder(DBC)
    n = NavSolution(seq=70000, time_s=1.0, lat_deg=39.9, lon_deg=116.3, height_m=1e9, vel_enu_mps=(500.0, -500.0, 1.0),
                    roll_deg=0.0, pitch_deg=0.0, heading_deg=359.999, sigma=(0.0,) * 9, mode=0x10002, gnss_status=1,
                    psns_status=0, cpu_load_pct=900.0, deadline_misses=0)
    db = enc.db
    dec = {}
    for fid, ext, data in enc.encode(n):
        assert not ext
        dec.update(db.decode_message(fid, data))
    assert dec["seq"] == 70000 % 65536
    assert dec["mode"] == 0x0002
    assert dec["height_m"] == pytest.approx(100000)  # DBC maximum
    assert dec["vel_e_mps"] == pytest.approx(327.67) and dec["vel_n_mps"] == pytest.approx(-327.68)
    assert dec["cpu_load_pct"] == pytest.approx(655.35)
    assert dec["heading_deg"] == pytest.approx(360.0, abs=0.006)


def test_dbc_with_an_unknown_signal_is_rejected_naming_it(tmp_path):
    text = DBC.read_text().replace("SG_ roll_deg :", "SG_ yaw_rate_dps :")
    p = tmp_path / "x.dbc"
    p.write_text(text)
    with pytest.raises(LinkConfigError, match="NAV_ATT.yaw_rate_dps"):
        NavCanEncoder(p)
    with pytest.raises(LinkConfigError, match="not found"):
        NavCanEncoder(tmp_path / "missing.dbc")


@pytest.mark.parametrize("url", ["can://virtual", "can://pcan/0", "can://virtual/x?rate=0", "can://virtual/x?rate=abc"])
def test_bad_can_urls(fast_loop, url):
    with pytest.raises(LinkConfigError, match="can://"):
        open_link(url, "host", fast_loop)


def test_missing_socketcan_interface_is_a_link_error_with_its_cause(fast_loop):
    link = open_link(f"can://socketcan/psnsnone0?dbc={DBC}", "host", fast_loop)
    with pytest.raises(LinkBrokenError, match="psnsnone0") as ei:
        fast_loop.run_until_complete(link.open())
    assert isinstance(ei.value.__cause__, (OSError, can.CanError))


_VCAN = sorted(os.path.basename(p) for p in glob.glob("/sys/class/net/vcan*"))


@pytest.mark.skipif(not _VCAN, reason="no vcan interface on this machine (creating one needs root and the vcan "
                                      "kernel module, which these machines lack; protocols.md section 0.6)")
def test_socketcan_vcan_carries_decodable_frames(fast_loop):
    iface = _VCAN[0]
    rng = np.random.default_rng(6)
    rx = can.Bus(interface="socketcan", channel=iface)
    try:
        link = open_link(f"can://socketcan/{iface}?dbc={DBC}", "host", fast_loop,
                         default_line=LineConfig(baud=460800, tx_queue_bytes=1 << 16))
        navs = [_nav(k, rng) for k in range(5)]
        _run_link(fast_loop, link, [encode_nav_solution(n) for n in navs])
        msgs = []
        while (m := rx.recv(timeout=0.5)) is not None:
            msgs.append(m)
    finally:
        rx.shutdown()
    db = cantools.database.load_file(str(DBC))
    seqs = [db.decode_message(m.arbitration_id, m.data)["seq"] for m in msgs if m.arbitration_id == 256]
    assert seqs == [0, 1, 2, 3, 4]


def test_a_run_with_the_host_port_on_can_sends_every_nav_frame(tmp_path, rx_bus):
    """The whole box: DSP UART0 -> FPGA HOST port = can://virtual/CH; CAN frames decode to nav.csv's values."""
    import csv

    from emulator.runner import run_scenario
    from emulator.scenario import load_scenario

    from .conftest import write_short_scenario

    channel, bus = rx_bus
    path = write_short_scenario(tmp_path / "can.yaml", 4.0, name="can_out",
                                links={"host": {"url": f"can://virtual/{channel}?dbc={DBC}", "baud": 460800}})
    summary = run_scenario(load_scenario(path), tmp_path / "run")
    msgs = _drain(bus)
    db = cantools.database.load_file(str(DBC))
    # one row per NAV_SOLUTION (time of validity unique); main's recorder may list a frame once per
    # tapped link that carries it (host and uart0), so de-duplicate by time_s
    rows = list({r["time_s"]: r for r in csv.DictReader(open(tmp_path / "run" / "nav.csv"))}.values())
    assert summary["nav_frames"] >= len(rows) > 300
    status = [db.decode_message(256, m.data) for m in msgs if m.arbitration_id == 256]
    times = [db.decode_message(258, m.data)["time_s"] for m in msgs if m.arbitration_id == 258]
    att = [db.decode_message(260, m.data) for m in msgs if m.arbitration_id == 260]
    assert len(msgs) == len(status) * len(db.messages) == link_frames(summary, len(status))
    # the last frame may still be on the HOST line (460800 Bd) when the run ends at duration_s
    assert len(rows) - 1 <= len(status) <= len(rows)
    by_time = {round(float(r["time_s"]), 3): r for r in rows}
    for t, a in list(zip(times, att))[-50:]:
        r = by_time[round(t, 3)]
        assert a["heading_deg"] == pytest.approx(float(r["heading_deg"]), abs=0.005 + 1e-9)
        assert a["roll_deg"] == pytest.approx(float(r["roll_deg"]), abs=0.005 + 1e-9)
        assert a["pitch_deg"] == pytest.approx(float(r["pitch_deg"]), abs=0.005 + 1e-9)


def link_frames(summary, n_nav: int) -> int:
    """CAN frames the run's host link reports sending (5 per nav frame for the minimal DBC)."""
    host = summary["link_stats"]["host"]
    assert host["dropped_out"] == 0
    return n_nav * 5
