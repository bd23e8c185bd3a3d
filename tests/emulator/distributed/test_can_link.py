"""can:// links: NAV_SOLUTION frames out of the host port become DBC-encoded CAN frames (python-can virtual
bus), decoded back with cantools."""

from __future__ import annotations

import asyncio
import glob
import os
from pathlib import Path
from typing import Any

import cantools
import numpy as np
import pytest
from cantools.database.can import Database as CanDatabase

import protocols

can = pytest.importorskip("can")

from emulator.clock import EmulatorLoop  # noqa: E402
from emulator.errors import LinkBrokenError, LinkConfigError  # noqa: E402
from emulator.links import LineConfig, open_link  # noqa: E402
from emulator.links.can import CanLink, DbcNavCanEncoder, DefaultNavCanEncoder, nav_signal_values  # noqa: E402
from protocols.host import HostFormat, NavMode, NavSolution, encode_nav_solution  # noqa: E402

DBC = Path(protocols.__file__).with_name("psns_nav.dbc")
FAST = ("PSNS_NAV_TIME", "PSNS_NAV_POSITION", "PSNS_NAV_HEIGHT_MODE", "PSNS_NAV_VELOCITY", "PSNS_NAV_ATTITUDE")
SLOW = ("PSNS_NAV_SIGMA_ATT", "PSNS_NAV_SIGMA_VEL", "PSNS_NAV_SIGMA_POS", "PSNS_NAV_DSP")


def _nav(k: int, rng: np.random.Generator) -> NavSolution:
    lat, lon, height = float(rng.uniform(-89, 89)), float(rng.uniform(-179, 179)), float(rng.uniform(-100, 5000))
    ve, vn, vu = (float(v) for v in rng.uniform(-50, 50, 3))
    return NavSolution(
        seq=k, time_s=0.005 + 0.01 * k, lat_deg=lat, lon_deg=lon, height_m=height, vel_enu_mps=(ve, vn, vu),
        roll_deg=float(rng.uniform(-179, 179)), pitch_deg=float(rng.uniform(-89, 89)),
        heading_deg=float(rng.uniform(0, 359.9)), sigma=tuple(float(v) for v in rng.uniform(0, 1, 9)),
        mode=int(NavMode.NAVIGATING | NavMode.GNSS_AIDED), gnss_status=int(rng.integers(0, 9)), psns_status=0,
        cpu_load_pct=round(float(rng.uniform(0, 100)), 2), deadline_misses=0)


def _dbc() -> CanDatabase:
    db = cantools.database.load_file(str(DBC))
    assert isinstance(db, CanDatabase)
    return db


def _can_link(url: str, loop: EmulatorLoop) -> CanLink:
    link = open_link(url, "host", loop, default_line=LineConfig(baud=460800, tx_queue_bytes=1 << 16))
    assert isinstance(link, CanLink)
    return link


def _decode_epochs(db, msgs) -> list[dict[str, dict]]:
    """Group decoded frames by epoch: a PSNS_NAV_TIME frame starts one (frames go out in id order)."""
    epochs: list[dict[str, dict]] = []
    for m in msgs:
        assert m.is_extended_id
        msg = db.get_message_by_frame_id(m.arbitration_id)
        if msg.name == "PSNS_NAV_TIME":
            epochs.append({})
        epochs[-1][msg.name] = db.decode_message(m.arbitration_id, m.data, decode_choices=False)
    return epochs


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
            # until every byte has left the line model into the CAN encoder (virtual time; 1 s at most)
            end = loop.time() + 1.0
            while link.stats.bytes_out < len(blob) and loop.time() < end:
                await asyncio.sleep(0.001)
            assert link.stats.bytes_out == len(blob)
        finally:
            await link.close()

    loop.run_until_complete(main())


def test_nav_frames_become_dbc_frames_that_cantools_decodes(fast_loop, rx_bus):
    channel, bus = rx_bus
    rng = np.random.default_rng(3)
    navs = [_nav(k, rng) for k in range(40)]  # 0.4 s of 100 Hz solutions
    link = _can_link(f"can://virtual/{channel}", fast_loop)
    _run_link(fast_loop, link, [encode_nav_solution(n) for n in navs])
    db = _dbc()
    msgs = _drain(bus)
    epochs = _decode_epochs(db, msgs)
    assert len(epochs) == 40 and link.nav_frames == 40 and link.can_send_errors == 0
    assert len(msgs) == link.can_frames_sent == 40 * len(FAST) + 4 * len(SLOW)  # 100 Hz + 10 Hz messages
    for k, (n, ep) in enumerate(zip(navs, epochs)):
        assert set(FAST) <= set(ep) and (set(SLOW) <= set(ep)) == (k % 10 == 0), k
        wire = HostFormat().parse(encode_nav_solution(n))  # f32 fields as the wire has them
        assert isinstance(wire, NavSolution)
        want = nav_signal_values(wire)
        for name, sigs in ep.items():
            for sig in db.get_message_by_name(name).signals:
                tol = abs(sig.scale) / 2 + 1e-9 + 1e-9 * abs(want[sig.name])
                assert sigs[sig.name] == pytest.approx(want[sig.name], abs=tol), (name, sig.name)


def test_the_cantools_path_for_any_dbc_gives_the_same_bytes_as_the_protocols_codec():
    rng = np.random.default_rng(8)
    a, b = DefaultNavCanEncoder(), DbcNavCanEncoder(DBC)
    assert [x[0] for x in a.schedule] == [x[0] for x in b.schedule]
    assert [x[1] for x in a.schedule] == pytest.approx([x[1] for x in b.schedule])
    for k in range(25):
        n = _nav(k, rng)
        assert a.frames(n) == b.frames(n), k


def test_rate_option_decimates_in_navigation_time(fast_loop, rx_bus):
    channel, bus = rx_bus
    rng = np.random.default_rng(4)
    link = _can_link(f"can://virtual/{channel}?rate=20", fast_loop)
    _run_link(fast_loop, link, [encode_nav_solution(_nav(k, rng)) for k in range(100)])  # 1 s at 100 Hz
    db = _dbc()
    epochs = _decode_epochs(db, _drain(bus))
    assert link.nav_frames == 100 and len(epochs) == 20
    assert [e["PSNS_NAV_TIME"]["seq"] for e in epochs] == list(range(0, 100, 5))
    assert sum("PSNS_NAV_DSP" in e for e in epochs) == 10  # its own 100 ms cycle still holds


def test_corrupt_bytes_are_skipped_by_the_stream_decoder(fast_loop, rx_bus):
    channel, bus = rx_bus
    rng = np.random.default_rng(5)
    good = [encode_nav_solution(_nav(k, rng)) for k in range(3)]
    bad = bytearray(good[1])
    bad[20] ^= 0x40  # CRC now fails
    link = _can_link(f"can://virtual/{channel}", fast_loop)
    _run_link(fast_loop, link, [b"\x00junk\xa5", good[0], bytes(bad), good[2]])
    db = _dbc()
    epochs = _decode_epochs(db, _drain(bus))
    assert [e["PSNS_NAV_TIME"]["seq"] for e in epochs] == [0, 2]
    assert link.decoder_stats["crc_errors"] == 1


def test_out_of_range_values_saturate_and_counters_wrap_with_any_dbc():
    enc = DbcNavCanEncoder(DBC)
    n = NavSolution(seq=70000, time_s=1.0, lat_deg=39.9, lon_deg=116.3, height_m=1e9, vel_enu_mps=(500.0, -500.0, 1.0),
                    roll_deg=0.0, pitch_deg=0.0, heading_deg=12.5, sigma=(0.0,) * 9, mode=0x10002, gnss_status=1,
                    psns_status=0, cpu_load_pct=900.0, deadline_misses=0)
    db = enc.db
    assert isinstance(db, CanDatabase)
    dec: dict[str, Any] = {}
    for fid, ext, data in enc.frames(n):
        assert ext
        decoded = db.decode_message(fid, data, decode_choices=False)
        assert isinstance(decoded, dict)
        dec.update(decoded)
    assert dec["seq"] == 70000 and dec["seq8"] == 70000 % 256
    assert dec["mode"] == 0x0002
    assert dec["height_m"] == pytest.approx((2**31 - 1) * 0.001)
    assert dec["vel_e_mps"] == pytest.approx(327.67) and dec["vel_n_mps"] == pytest.approx(-327.68)
    assert dec["cpu_load_pct"] == pytest.approx(655.35)
    assert dec["heading_deg"] == pytest.approx(12.5)


def test_dbc_with_an_unknown_signal_is_rejected_naming_it(tmp_path):
    text = DBC.read_text().replace("SG_ roll_deg :", "SG_ yaw_rate_dps :").replace(" roll_deg ", " yaw_rate_dps ")
    p = tmp_path / "x.dbc"
    p.write_text(text)
    with pytest.raises(LinkConfigError, match=r"PSNS_NAV_ATTITUDE\.yaw_rate_dps"):
        DbcNavCanEncoder(p)
    with pytest.raises(LinkConfigError, match="not found"):
        DbcNavCanEncoder(tmp_path / "missing.dbc")


@pytest.mark.parametrize("url", ["can://virtual", "can://pcan/0", "can://virtual/x?rate=0", "can://virtual/x?rate=abc"])
def test_bad_can_urls(fast_loop, url):
    with pytest.raises(LinkConfigError, match="can://"):
        open_link(url, "host", fast_loop)


def test_missing_socketcan_interface_is_a_link_error_with_its_cause(fast_loop):
    link = open_link("can://socketcan/psnsnone0", "host", fast_loop)
    with pytest.raises(LinkBrokenError, match="psnsnone0") as ei:
        fast_loop.run_until_complete(link.open())
    assert isinstance(ei.value.__cause__, (OSError, can.CanError))


_VCAN = sorted(os.path.basename(p) for p in glob.glob("/sys/class/net/vcan*"))


@pytest.mark.skipif(not _VCAN, reason="no vcan interface on this machine (creating one needs root and the vcan "
                                      "kernel module, which these machines lack; "
                                      "docs/reference/wire-formats.md section 0.6)")
def test_socketcan_vcan_carries_decodable_frames(fast_loop):
    iface = _VCAN[0]
    rng = np.random.default_rng(6)
    rx = can.Bus(interface="socketcan", channel=iface)
    try:
        link = open_link(f"can://socketcan/{iface}", "host", fast_loop,
                         default_line=LineConfig(baud=460800, tx_queue_bytes=1 << 16))
        navs = [_nav(k, rng) for k in range(5)]
        _run_link(fast_loop, link, [encode_nav_solution(n) for n in navs])
        msgs = []
        while (m := rx.recv(timeout=0.5)) is not None:
            msgs.append(m)
    finally:
        rx.shutdown()
    db = _dbc()
    assert [e["PSNS_NAV_TIME"]["seq"] for e in _decode_epochs(db, msgs)] == [0, 1, 2, 3, 4]


def test_a_run_with_the_host_port_on_can_sends_every_nav_frame(tmp_path, rx_bus):
    """The whole box: DSP UART0 -> FPGA HOST port = can://virtual/CH; CAN frames decode to nav.csv's values."""
    import csv

    from emulator.assembly.session import run_scenario
    from emulator.scenario import load_scenario

    from .conftest import write_short_scenario

    channel, bus = rx_bus
    path = write_short_scenario(tmp_path / "can.yaml", 4.0, name="can_out",
                                links={"host": {"url": f"can://virtual/{channel}", "baud": 460800}})
    summary = run_scenario(load_scenario(path), tmp_path / "run")
    db = _dbc()
    epochs = _decode_epochs(db, _drain(bus))
    # one row per solution (an older recorder listed each frame once per tapped link: de-duplicate by time)
    with open(tmp_path / "run" / "nav.csv", newline="") as f:
        rows = list({r["time_s"]: r for r in csv.DictReader(f)}.values())
    assert summary["link_stats"]["host"]["dropped_out"] == 0
    # the last frame may still be on the HOST line (460800 Bd) when the run ends at duration_s
    assert len(rows) - 1 <= len(epochs) <= len(rows) and len(rows) > 300
    by_time = {round(float(r["time_s"]), 3): r for r in rows}
    for ep in epochs[-50:]:
        r = by_time[round(ep["PSNS_NAV_TIME"]["time_s"], 3)]
        att = ep["PSNS_NAV_ATTITUDE"]
        for k in ("roll_deg", "pitch_deg", "heading_deg"):
            assert att[k] == pytest.approx(float(r[k]), abs=0.005 + 1e-9), k
        pos = ep["PSNS_NAV_POSITION"]
        assert pos["lat_deg"] == pytest.approx(float(r["lat_deg"]), abs=0.5e-7 + 1e-12)
        assert pos["lon_deg"] == pytest.approx(float(r["lon_deg"]), abs=0.5e-7 + 1e-12)
