"""The live Foxglove view (``psns-hil run --realtime --foxglove``) against a client written from the Foxglove WebSocket
protocol specification (v1: subprotocol ``foxglove.websocket.v1``; JSON text ops ``serverInfo``, ``advertise``,
``subscribe``, ``status``; binary ``messageData`` = opcode 0x01, u32 subscription id, u64 log time ns, little-endian,
then the message): it receives every channel while the run goes, log times rising, the navigation values equal to
nav.csv, and its attempts to publish, call a service or read parameters are refused."""

from __future__ import annotations

import csv
import json
import re
import struct
import subprocess
import sys
import time
from collections import defaultdict

import pytest
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import connect

from emulator.recording.live import parse_host_port
from tests.conftest import ROOT, SCENARIOS

pytestmark = pytest.mark.realtime


def test_parse_host_port():
    assert parse_host_port("127.0.0.1:0") == ("127.0.0.1", 0)
    assert parse_host_port(":9000") == ("127.0.0.1", 9000)
    assert parse_host_port("localhost") == ("localhost", 8765)
    with pytest.raises(ValueError):
        parse_host_port("h:70000")


def test_a_spec_client_watches_a_realtime_run(tmp_path):
    out = tmp_path / "run"
    proc = subprocess.Popen([sys.executable, "-m", "emulator", "run", str(SCENARIOS / "quickstart.yaml"), "--set",
                             "duration_s=4", "--realtime", "--out", str(out), "--foxglove", "127.0.0.1:0",
                             "--no-report", "--no-tables", "--quiet"],
                            cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
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
        frames: dict[str, list[tuple[int, dict]]] = defaultdict(list)
        status: list[dict] = []
        with connect(url, subprotocols=["foxglove.websocket.v1"], open_timeout=10) as ws:
            assert ws.subprotocol == "foxglove.websocket.v1"
            info = json.loads(ws.recv(timeout=10))
            assert info["op"] == "serverInfo" and info["capabilities"] == []
            adv = json.loads(ws.recv(timeout=10))
            assert adv["op"] == "advertise"
            chans = {c["id"]: c for c in adv["channels"]}
            topics = {c["topic"] for c in chans.values()}
            assert {"/nav/solution", "/nav/location", "/nav/pose", "/tf", "/raw/uart1/in", "/raw/host/out"} <= topics
            assert all(c["encoding"] == "json" and c["schemaEncoding"] == "jsonschema" for c in chans.values())
            assert next(c for c in chans.values() if c["topic"] == "/nav/location")["schemaName"] == \
                "foxglove.LocationFix"
            ws.send(json.dumps({"op": "subscribe", "subscriptions": [{"id": 100 + cid, "channelId": cid}
                                                                    for cid in chans]}))
            # a client may not publish, call services or touch parameters
            ws.send(json.dumps({"op": "advertise", "channels": [{"id": 1, "topic": "/cmd", "encoding": "json",
                                                                 "schemaName": "x"}]}))
            ws.send(struct.pack("<BI", 0x01, 1) + b"{}")
            ws.send(json.dumps({"op": "setParameters", "parameters": [{"name": "x", "value": 1}]}))
            by_sub = {100 + cid: c["topic"] for cid, c in chans.items()}
            try:
                while True:
                    msg = ws.recv(timeout=30)
                    if isinstance(msg, str):
                        status.append(json.loads(msg))
                        continue
                    op, sub, log_ns = struct.unpack_from("<BIQ", msg)
                    assert op == 0x01
                    frames[by_sub[sub]].append((log_ns, json.loads(msg[13:])))
            except ConnectionClosed:
                pass
        assert proc.wait(timeout=60) in (0, 1)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert [s["op"] for s in status] == ["status"] * 3 and all(s["level"] == 2 for s in status)
    assert all("read-only" in s["message"] for s in status)
    for topic in ("/nav/solution", "/nav/location", "/nav/pose", "/raw/uart1/in", "/raw/gyro/in"):
        assert len(frames[topic]) >= 100, topic
        times = [t for t, _ in frames[topic]]
        assert times == sorted(times), topic
    with open(out / "nav.csv", newline="", encoding="utf-8") as f:
        nav = {float(r["time_s"]): r for r in csv.DictReader(f)}
    sols = frames["/nav/solution"]
    assert len(sols) >= 0.9 * len(nav)
    for log_ns, m in sols:
        r = nav[m["time_s"]]
        assert log_ns == round(m["time_s"] * 1e9)
        assert (m["lat_deg"], m["lon_deg"], m["heading_deg"]) == (float(r["lat_deg"]), float(r["lon_deg"]),
                                                                  float(r["heading_deg"]))
        assert m["arrival_s"] == float(r["arrival_s"])
