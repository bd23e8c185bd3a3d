"""The live Foxglove view (``psns-hil run --realtime --foxglove``) against a client written from the Foxglove WebSocket
protocol specification (v1: subprotocol ``foxglove.websocket.v1``; JSON text ops ``serverInfo``, ``advertise``,
``subscribe``, ``status``; binary ``messageData`` = opcode 0x01, u32 subscription id, u64 log time ns, little-endian,
then the message): it receives every channel of the run's MCAP (read back with the ``mcap`` reader) while the run
goes, each message equal to the MCAP's, log times rising, the navigation values equal to nav.csv, and its attempts to
publish, call a service or touch parameters are refused. The follower that feeds the server is also checked without
a socket: a run directory that grows in uneven slices (lines and capture records cut anywhere) yields exactly the
messages of its run.mcap."""

from __future__ import annotations

import csv
import json
import re
import shutil
import struct
import subprocess
import sys
import threading
import time
from collections import Counter, defaultdict
from pathlib import Path

import pytest
from mcap.reader import make_reader
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from emulator.assembly.session import run_scenario
from emulator.postrun.live import RunDirFollower, parse_host_port
from emulator.postrun.mcap_out import CSV_SOURCES, RunFeeds, encode_message, write_run_mcap
from emulator.scenario import load_scenario
from tests.conftest import ROOT, SCENARIOS


def _mcap(path: Path) -> tuple[dict[str, str], list[tuple[str, int, bytes]]]:
    """(topic -> schema name, [(topic, log time ns, message bytes)]) of an MCAP, by the mcap reader."""
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None
        schemas = {ch.topic: summary.schemas[ch.schema_id].name for ch in summary.channels.values()}
        msgs = [(ch.topic, m.log_time, m.data) for _s, ch, m in reader.iter_messages(log_time_order=False)]
    return schemas, msgs


def test_parse_host_port():
    assert parse_host_port("127.0.0.1:0") == ("127.0.0.1", 0)
    assert parse_host_port(":9000") == ("127.0.0.1", 9000)
    assert parse_host_port("localhost") == ("localhost", 8765)
    with pytest.raises(ValueError):
        parse_host_port("h:70000")


class _ListSink:
    def __init__(self) -> None:
        self.schemas: dict = {}
        self.msgs: list[tuple[str, int, bytes]] = []

    def add(self, topic, log_s, msg, publish_s=None):
        self.msgs.append((topic, max(0, round(log_s * 1e9)), encode_message(msg)))


def test_the_follower_of_a_growing_run_directory_gives_the_mcaps_messages(tmp_path):
    scn = load_scenario(SCENARIOS / "quickstart.yaml")
    scn.duration_s = 3.0
    src = tmp_path / "run"
    run_scenario(scn, src)
    write_run_mcap(src)
    _schemas, want = _mcap(src / "run.mcap")
    grow = tmp_path / "grow"
    grow.mkdir()
    names = [*CSV_SOURCES, "events.jsonl", "capture.psnscap"]
    data = {n: (src / n).read_bytes() for n in names if (src / n).exists()}
    sink = _ListSink()
    follower = RunDirFollower(grow, RunFeeds(sink))
    follower.poll()  # nothing written yet
    assert sink.msgs == []
    for k in range(1, 8):  # slices of uneven size: lines and records are cut anywhere
        for n, b in data.items():
            with open(grow / n, "ab") as f:
                f.write(b[len(b) * (k - 1) ** 2 // 49: len(b) * k ** 2 // 49])
        follower.poll()
        if k == 1:
            assert 0 < len(sink.msgs) < len(want) // 4
    shutil.copy(src / "summary.json", grow / "summary.json")
    follower.poll(final=True)
    assert Counter(sink.msgs) == Counter(want)
    # per channel the follower's order is the MCAP's (log time, then the order written)
    by_topic = defaultdict(list)
    for topic, log, _d in sink.msgs:
        by_topic[topic].append(log)
    assert all(v == sorted(v) for t, v in by_topic.items() if t != "/tf")


def _subscribe(ws, channels, chans, by_sub):
    subs = []
    for c in channels:
        chans[c["id"]] = c
        by_sub[1000 + c["id"]] = c["topic"]
        subs.append({"id": 1000 + c["id"], "channelId": c["id"]})
    ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))


@pytest.mark.realtime
def test_a_spec_client_watches_a_realtime_run(tmp_path):
    out = tmp_path / "run"
    proc = subprocess.Popen([sys.executable, "-m", "emulator", "run", str(SCENARIOS / "quickstart.yaml"), "--set",
                             "duration_s=6", "--realtime", "--out", str(out), "--foxglove", "127.0.0.1:0", "--mcap",
                             "--no-report", "--no-tables", "--quiet"],
                            cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    frames: dict[str, list[tuple[int, bytes]]] = defaultdict(list)
    status: list[dict] = []
    chans: dict[int, dict] = {}
    by_sub: dict[int, str] = {}
    try:
        url = None
        deadline = time.monotonic() + 60.0
        while url is None and time.monotonic() < deadline:
            line = proc.stderr.readline()
            m = re.search(r"foxglove: (ws://\S+)", line)
            if m:
                url = m.group(1)
            elif not line and proc.poll() is not None:
                break
        assert url is not None, "the run never announced its live view"
        with connect(url, subprotocols=["foxglove.websocket.v1"], open_timeout=10, max_size=None) as ws:
            assert ws.subprotocol == "foxglove.websocket.v1"
            info = json.loads(ws.recv(timeout=10))
            assert info["op"] == "serverInfo" and info["capabilities"] == []
            adv = json.loads(ws.recv(timeout=10))
            assert adv["op"] == "advertise"
            _subscribe(ws, adv["channels"], chans, by_sub)
            # a client may not publish, call services or touch parameters
            ws.send(json.dumps({"op": "advertise", "channels": [{"id": 1, "topic": "/cmd", "encoding": "json",
                                                                 "schemaName": "x"}]}))
            ws.send(struct.pack("<BI", 0x01, 1) + b"{}")  # client message data on that channel
            ws.send(struct.pack("<BIII", 0x02, 1, 1, 4) + b"json" + b"{}")  # a service call request
            ws.send(json.dumps({"op": "setParameters", "parameters": [{"name": "x", "value": 1}]}))
            ws.send(json.dumps({"op": "getParameters", "parameterNames": []}))
            try:
                while True:
                    msg = ws.recv(timeout=30)
                    if isinstance(msg, str):
                        op = json.loads(msg)
                        if op["op"] == "advertise":  # channels that appear as the run goes
                            _subscribe(ws, op["channels"], chans, by_sub)
                        else:
                            status.append(op)
                        continue
                    code, sub, log_ns = struct.unpack_from("<BIQ", msg)
                    assert code == 0x01
                    frames[by_sub[sub]].append((log_ns, bytes(msg[13:])))
            except ConnectionClosed:
                pass
        assert proc.wait(timeout=60) in (0, 1)
        assert "stopped following" not in proc.stderr.read()
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert [s["op"] for s in status] == ["status"] * 5 and all(s["level"] == 2 for s in status)
    assert all("read-only" in s["message"] for s in status)
    assert "/cmd" not in {c["topic"] for c in chans.values()}
    assert all(c["encoding"] == "json" and c["schemaEncoding"] == "jsonschema" for c in chans.values())
    # every channel of the run's MCAP, with its schema, and nothing else
    schemas, mcap_msgs = _mcap(out / "run.mcap")
    assert {c["topic"]: c["schemaName"] for c in chans.values()} == schemas
    assert set(frames) == set(schemas)
    mcap_by_topic: dict[str, Counter] = defaultdict(Counter)
    for topic, log, data in mcap_msgs:
        mcap_by_topic[topic][(log, data)] += 1
    for topic, got in frames.items():
        want = mcap_by_topic[topic]
        n = sum(want.values())
        assert len(got) >= (n // 2 if n >= 10 else 1), (topic, len(got), n)  # a client misses only the start
        assert not Counter(got) - want, topic  # each message is one of the MCAP's, byte for byte
        times = [t for t, _ in got]
        assert times == sorted(times), topic
    assert len(frames["/nav/solution"]) >= 200 and len(frames["/imu"]) >= 400
    with open(out / "nav.csv", newline="", encoding="utf-8") as f:
        nav = {float(r["time_s"]): r for r in csv.DictReader(f)}
    for log_ns, data in frames["/nav/solution"]:
        m = json.loads(data)
        r = nav[m["time_s"]]
        assert log_ns == round(m["time_s"] * 1e9)
        for col in ("lat_deg", "lon_deg", "height_m", "heading_deg", "arrival_s", "sig_pos_e_m"):
            assert m[col] == float(r[col]), col


@pytest.mark.realtime
def test_the_server_refuses_a_hostile_client_and_serves_the_tail_of_the_run(tmp_path):
    """In process: a run directory written in two halves while a spec client watches. Malformed and forbidden
    messages get a status error each and change nothing; after subscribing, the client receives the channel's latest
    message and then every later one, equal to run.mcap's, to the end of the run (the expectations too)."""
    from emulator.postrun.live import LiveServer

    scn = load_scenario(SCENARIOS / "quickstart.yaml")
    scn.duration_s = 3.0
    src = tmp_path / "run"
    run_scenario(scn, src)
    write_run_mcap(src)
    _schemas, mcap_msgs = _mcap(src / "run.mcap")
    grow = tmp_path / "grow"
    grow.mkdir()
    data = {n: (src / n).read_bytes() for n in [*CSV_SOURCES, "events.jsonl", "capture.psnscap"]}

    def write(part):
        for n, b in data.items():
            with open(grow / n, "ab") as f:
                f.write(b[: len(b) // 2] if part == 0 else b[len(b) // 2:])

    server = LiveServer("127.0.0.1", 0)
    server.follow(grow)
    port = server.start()
    frames: dict[str, list[tuple[int, bytes]]] = defaultdict(list)
    chans: dict[int, dict] = {}
    by_sub: dict[int, str] = {}
    status: list[dict] = []
    try:
        with connect(f"ws://127.0.0.1:{port}", subprotocols=["foxglove.websocket.v1"], open_timeout=10,
                     max_size=None) as ws:
            assert json.loads(ws.recv(timeout=10))["op"] == "serverInfo"
            assert json.loads(ws.recv(timeout=10)) == {"op": "advertise", "channels": []}
            for bad in ("not json", "[1, 2]", '{"op": 3}', '{"op": "subscribe", "subscriptions": 5}',
                        '{"op": "unsubscribe", "subscriptionIds": "x"}', '{"op": "subscribeParameterUpdates"}'):
                ws.send(bad)
            while len(status) < 6:
                status.append(json.loads(ws.recv(timeout=10)))
            assert all(s["op"] == "status" and s["level"] == 2 and "read-only" in s["message"] for s in status)
            write(0)
            while "/nav/solution" not in by_sub.values():  # the first half is advertised as the server reads it
                op = json.loads(ws.recv(timeout=10))
                assert op["op"] == "advertise"
                _subscribe(ws, op["channels"], chans, by_sub)
            write(1)
            try:
                while True:
                    msg = ws.recv(timeout=2)  # silence: the server has read the second half (or close() will)
                    if isinstance(msg, str):
                        op = json.loads(msg)
                        assert op["op"] == "advertise"
                        _subscribe(ws, op["channels"], chans, by_sub)
                        continue
                    _code, sub, log_ns = struct.unpack_from("<BIQ", msg)
                    frames[by_sub[sub]].append((log_ns, bytes(msg[13:])))
            except TimeoutError:  # the run ends; close() reads what is left and waits for the client
                shutil.copy(src / "summary.json", grow / "summary.json")
                closer = threading.Thread(target=server.close)
                closer.start()
                for msg in ws:
                    if isinstance(msg, str):
                        _subscribe(ws, json.loads(msg)["channels"], chans, by_sub)
                        continue
                    _code, sub, log_ns = struct.unpack_from("<BIQ", msg)
                    frames[by_sub[sub]].append((log_ns, bytes(msg[13:])))
                closer.join(30)
    finally:
        server.close()
    want = [(log, d) for t, log, d in mcap_msgs if t == "/nav/solution"]
    got = frames["/nav/solution"]
    assert len(got) >= len(want) // 2 and got == want[len(want) - len(got):]  # a tail of the run, in order
    assert frames["/expectations"] and all((t, d) in {(lg, dd) for tt, lg, dd in mcap_msgs if tt == "/expectations"}
                                           for t, d in frames["/expectations"])
    assert server.refused == 6 and server.error is None
