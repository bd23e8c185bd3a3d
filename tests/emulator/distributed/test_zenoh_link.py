"""zenoh:// links: two sessions on 127.0.0.1 (scouting off), bytes both ways, pacing, nav JSON, cleanup."""

from __future__ import annotations

import json

import numpy as np
import pytest

from emulator.errors import LinkConfigError
from emulator.links import LineConfig, parse_link_url
from emulator.links.zenoh import ZenohEndpointConfig, open_sessions, zenoh_key_prefix
from protocols.host import NavMode, NavSolution, encode_nav_solution

from .conftest import DEFAULT_LINE, free_tcp_port, wait_until

pytestmark = pytest.mark.realtime  # sockets and processes on the wall clock



def _pair(zenoh_links, run: str, port: str = "uart1", a_opts: str = "", b_opts: str = "",
          line: LineConfig = DEFAULT_LINE):
    p = free_tcp_port()
    a = zenoh_links(f"zenoh://{run}/{port}?listen=tcp/127.0.0.1:{p}{a_opts}", "fpga_" + port, line)
    b = zenoh_links(f"zenoh://{run}/{port}?role=peer&connect=tcp/127.0.0.1:{p}{b_opts}", "dsp_" + port, line)
    return a, b


def test_bytes_cross_between_two_sessions_both_ways_in_order(zenoh_links, rt_loop):
    a, b = _pair(zenoh_links, "t1", line=LineConfig(baud=460800, tx_queue_bytes=1 << 16))
    assert a.session is not b.session
    assert (a.pub_key, a.sub_key) == ("psns/t1/uart1/tx", "psns/t1/uart1/rx")
    assert (b.pub_key, b.sub_key) == ("psns/t1/uart1/rx", "psns/t1/uart1/tx")
    got_b: list[bytes] = []
    got_a: list[bytes] = []
    b.on_receive = got_b.append
    a.on_receive = got_a.append
    rng = np.random.default_rng(9)
    chunks = [rng.integers(0, 256, int(n), dtype=np.uint8).tobytes() for n in rng.integers(1, 200, 50)]
    back = [bytes([k]) * 17 for k in range(20)]

    async def main():
        assert await a.wait_matched(5.0) and await b.wait_matched(5.0)
        for c in chunks:
            a.send(c)
        for c in back:
            b.send(c)
        ok = await wait_until(lambda: sum(map(len, got_b)) == sum(map(len, chunks))
                              and sum(map(len, got_a)) == sum(map(len, back)), 5.0)
        assert ok, (sum(map(len, got_b)), sum(map(len, got_a)))

    rt_loop.run_until_complete(main())
    assert b"".join(got_b) == b"".join(chunks)
    assert b"".join(got_a) == b"".join(back)
    assert a.stats.bytes_out == b.stats.bytes_in == sum(map(len, chunks))
    assert b.stats.bytes_out == a.stats.bytes_in == 20 * 17
    assert a.stats.dropped == b.stats.dropped == 0


def test_received_bytes_are_paced_by_the_line_model_unless_pace_0(zenoh_links, rt_loop):
    # 9600 baud 8N1: 480 bytes take 0.5 s on the receiving line when pace=1.
    line = LineConfig(baud=9600)
    a, b = _pair(zenoh_links, "t2", a_opts="", b_opts="", line=line)
    a2, b2 = _pair(zenoh_links, "t2b", b_opts="&pace=0", line=LineConfig(baud=9600, tx_queue_bytes=4096))
    assert b.paces_input and not b2.paces_input
    t_b: list[float] = []
    t_b2: list[float] = []
    b.on_receive = lambda d: t_b.append(rt_loop.time())
    b2.on_receive = lambda d: t_b2.append(rt_loop.time())

    async def main():
        assert await a.wait_matched(5.0) and await a2.wait_matched(5.0)
        # inject straight into the far end's transport: bytes "from outside", unpaced at the source
        t0 = rt_loop.time()
        a._write_raw(b"x" * 480)
        a2._write_raw(b"y" * 480)
        assert await wait_until(lambda: bool(t_b) and bool(t_b2), 5.0)
        return t0

    t0 = rt_loop.run_until_complete(main())
    assert t_b[0] - t0 == pytest.approx(480 * 10 / 9600, abs=0.05)  # 0.5 s of wire time
    assert t_b2[0] - t0 < 0.1  # delivered on arrival


def _nav(seq: int) -> NavSolution:
    return NavSolution(seq=seq, time_s=0.01 * seq, lat_deg=39.979 + 1e-6 * seq, lon_deg=116.339, height_m=50.5,
                       vel_enu_mps=(0.01, -0.02, 0.0), roll_deg=0.1, pitch_deg=-0.2, heading_deg=30.25,
                       sigma=tuple(0.1 * k for k in range(9)),
                       mode=int(NavMode.NAVIGATING | NavMode.GNSS_AIDED), gnss_status=1, psns_status=0,
                       cpu_load_pct=0.17, deadline_misses=0)


def test_host_port_publishes_decoded_nav_json(zenoh_links, rt_loop):
    import zenoh

    p = free_tcp_port()
    host = zenoh_links(f"zenoh://t3/host?listen=tcp/127.0.0.1:{p}", "host")
    assert host.nav_direction == "out" and host.nav_key == "psns/t3/nav"
    cfg = ZenohEndpointConfig(connect=(f"tcp/127.0.0.1:{p}",)).build()
    got: list[dict] = []
    raw: list[bytes] = []
    with zenoh.open(cfg) as s:
        sub = s.declare_subscriber("psns/t3/nav", lambda smp: got.append(json.loads(smp.payload.to_bytes())))
        sub_raw = s.declare_subscriber("psns/t3/host/tx", lambda smp: raw.append(smp.payload.to_bytes()))
        try:
            frames = [encode_nav_solution(_nav(k)) for k in range(10)]

            async def main():
                assert await wait_until(lambda: host._nav_pub.matching_status.matching
                                        and host.peer_matched(), 5.0)
                blob = b"".join(frames)
                host.send(blob[:37])  # arbitrary chunking: the decoder is a stream decoder
                host.send(blob[37:])
                # two publishers: the last frame's JSON is put (by the link's listener) before the raw bytes that
                # carry it, and their deliveries are not ordered across publishers -- wait for both
                assert await wait_until(lambda: len(got) == 10 and sum(map(len, raw)) >= len(blob), 5.0)

            rt_loop.run_until_complete(main())
        finally:
            sub.undeclare()
            sub_raw.undeclare()
    assert b"".join(raw) == b"".join(frames)
    for k, d in enumerate(got):
        n = _nav(k)
        assert d["seq"] == k
        assert d["lat_deg"] == n.lat_deg  # f64 on the wire: exact
        assert d["heading_deg"] == pytest.approx(30.25)
        assert d["vel_enu_mps"] == pytest.approx(list(n.vel_enu_mps), abs=1e-7)
        assert d["mode_flags"] == ["NAVIGATING", "GNSS_AIDED"]
        assert d["t_s"] >= 0
    assert host.nav_publisher.published == 10


def test_links_with_the_same_config_share_one_session_and_release_it(zenoh_links, rt_loop):
    p = free_tcp_port()
    a = zenoh_links(f"zenoh://t4/uart1?listen=tcp/127.0.0.1:{p}", "uart1")
    b = zenoh_links(f"zenoh://t4/uart3?listen=tcp/127.0.0.1:{p}", "uart3")
    assert a.session is b.session
    assert open_sessions() == 1
    rt_loop.run_until_complete(a.close())
    assert open_sessions() == 1 and not b.session.is_closed()
    rt_loop.run_until_complete(b.close())
    assert open_sessions() == 0


def test_same_session_loopback_delivers_locally(zenoh_links, rt_loop):
    # a device end and a peer end in one process on one session (the in-process conformance setting)
    p = free_tcp_port()
    a = zenoh_links(f"zenoh://t5/gnss?listen=tcp/127.0.0.1:{p}", "gnss")
    b = zenoh_links(f"zenoh://t5/gnss?role=peer&listen=tcp/127.0.0.1:{p}&pace=0", "tool")
    got: list[bytes] = []
    b.on_receive = got.append

    async def main():
        assert await a.wait_matched(2.0)
        a.send(b"$GPGGA,hello*00\r\n")
        assert await wait_until(lambda: b"".join(got) == b"$GPGGA,hello*00\r\n", 2.0)

    rt_loop.run_until_complete(main())


def test_callback_after_close_is_counted_not_raised(zenoh_links, rt_loop):
    _a, b = _pair(zenoh_links, "t6")

    class _Sample:
        class payload:
            @staticmethod
            def to_bytes() -> bytes:
                return b"late"

    rt_loop.run_until_complete(b.close())
    b._call = lambda *a_: (_ for _ in ()).throw(RuntimeError("Event loop is closed"))
    b._on_sample(_Sample())  # what a zenoh thread would do after the run ended
    assert b.received_after_close == 1


@pytest.mark.parametrize("url, msg", [
    ("zenoh://a/*/b", "no wildcards"),
    ("zenoh://run//x", "the key must be"),
    ("zenoh://r/p?role=master", "role='master'"),
    ("zenoh://r/p?session=router", "peer or client"),
    ("zenoh://r/p?listen=7447", "bad zenoh endpoint"),
    ("zenoh://r/p?pace=maybe", "pace='maybe'"),
    ("zenoh://r/p?nav=both", "nav='both'"),
])
def test_bad_urls_are_config_errors_with_the_accepted_form(rt_loop, url, msg):
    from emulator.links import open_link

    with pytest.raises(LinkConfigError, match="zenoh://") as ei:
        open_link(url, "p", rt_loop)
    assert msg.split("'")[0] in str(ei.value)


def test_unknown_option_is_rejected_at_parse_time():
    with pytest.raises(LinkConfigError, match="unknown option"):
        parse_link_url("zenoh://r/p?colour=red")
    assert parse_link_url("zenoh://r/p?listen=tcp/127.0.0.1:1&role=peer").options["role"] == "peer"


def test_key_prefix_rules():
    assert zenoh_key_prefix("bench/host") == ("bench", "host", "psns/bench/host")
    assert zenoh_key_prefix("host") == ("default", "host", "psns/default/host")
    assert zenoh_key_prefix("lab.2/rig-a/uart0") == ("lab.2/rig-a", "uart0", "psns/lab.2/rig-a/uart0")


def test_default_config_is_loopback_peer_without_scouting():
    import zenoh  # noqa: F401

    c = ZenohEndpointConfig()
    assert c.listen == ("tcp/127.0.0.1:7447",) and c.connect == ()
    cfg = c.build()
    assert json.loads(cfg.get_json("scouting/multicast/enabled")) is False
    assert json.loads(cfg.get_json("scouting/gossip/enabled")) is False
    assert json.loads(cfg.get_json("mode")) == "peer"
    assert json.loads(cfg.get_json("listen/endpoints")) == ["tcp/127.0.0.1:7447"]
    assert open_sessions() == 0


def test_a_realtime_run_publishes_host_bytes_and_nav_json_over_zenoh(tmp_path):
    """The whole box with its HOST port on zenoh: a separate session sees the raw frames and the JSON."""
    import csv

    import zenoh

    from emulator.assembly.session import run_scenario
    from emulator.scenario import load_scenario
    from protocols.host import HostFormat
    from protocols.stream import StreamDecoder

    from .conftest import write_short_scenario

    p = free_tcp_port()
    path = write_short_scenario(tmp_path / "z.yaml", 2.0, name="zrun", mode="realtime", expectations=[],
                                links={"host": {"url": f"zenoh://zrun/host?connect=tcp/127.0.0.1:{p}",
                                                "baud": 460800}})
    raw: list[bytes] = []
    nav: list[dict] = []
    # the tool listens and the emulator connects at start, so the subscriptions are known before the first frame
    cfg = ZenohEndpointConfig(listen=(f"tcp/127.0.0.1:{p}",)).build()
    with zenoh.open(cfg) as s:
        subs = [s.declare_subscriber("psns/zrun/host/tx", lambda smp: raw.append(smp.payload.to_bytes())),
                s.declare_subscriber("psns/zrun/nav", lambda smp: nav.append(json.loads(smp.payload.to_bytes())))]
        try:
            summary = run_scenario(load_scenario(path), tmp_path / "run")
        finally:
            for sub in subs:
                sub.undeclare()
    assert open_sessions() == 0
    frames = [f for f in StreamDecoder([HostFormat()]).feed(b"".join(raw)) if isinstance(f, NavSolution)]
    with open(tmp_path / "run" / "nav.csv", newline="") as f:
        rows = {round(float(r["time_s"]), 6) for r in csv.DictReader(f)}
    # 2 s of 100 Hz solutions; the subscription reaches the emulator while it starts (at worst a few frames late)
    assert len(frames) > 190 and len(nav) > 190
    assert [round(f.time_s, 6) for f in frames] == [round(d["time_s"], 6) for d in nav]
    assert {round(f.time_s, 6) for f in frames} <= rows
    assert summary["link_stats"]["host"]["dropped_out"] == 0
    seqs = [d["seq"] for d in nav]
    assert seqs == list(range(seqs[0], seqs[0] + len(seqs)))  # none lost after the first
