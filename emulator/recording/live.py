"""A live view of a run over the Foxglove WebSocket protocol (``psns-hil run --foxglove [HOST:PORT]``).

The server speaks the Foxglove WebSocket protocol v1 (subprotocol ``foxglove.websocket.v1``): on connection a
``serverInfo`` with no capabilities and an ``advertise`` of its channels (JSON messages, JSON Schema, the same
topics and schemas as ``run.mcap``: :mod:`emulator.recording.mcap_out`); a client ``subscribe`` s and receives
binary ``messageData`` frames (opcode 0x01, u32 subscription id, u64 log time ns, all little-endian, then the JSON
message). It is **read-only**, as every local endpoint of the project: client publishing (``advertise``,
``unadvertise``, binary client messages), services and parameters are refused with a ``status`` error and change
nothing. It listens on 127.0.0.1 unless told otherwise.

The data come from listeners, never from inside a device: the recorder's navigation listener
(:attr:`~emulator.recording.recorder.Recorder.nav_listeners`: ``/nav/solution``, ``/nav/location``, ``/nav/pose``,
``/tf``) and a :class:`~emulator.links.base.LinkListener` on every tapped link (``/raw/<link>/<direction>``). Log
time is the scenario clock (a navigation frame at its time of validity). The server runs on its own thread and
asyncio loop, so the emulator's loop (virtual or paced time) never waits for a socket: messages cross through a
bounded queue per client, and a client that falls behind (a fast-mode run, a slow network) loses the oldest ones,
counted in :attr:`LiveServer.dropped`.
"""

from __future__ import annotations

import asyncio
import base64
import collections
import json
import struct
import threading
from collections.abc import Callable
from typing import Any

from protocols.host import NavSolution

from .mcap_out import _RAW_SCHEMA_DEF, FOXGLOVE_SCHEMAS, RAW_SCHEMA, _location, _stamp, attitude_quaternion

__all__ = ["LIVE_SUBPROTOCOL", "LiveServer", "nav_solution_message", "parse_host_port"]

LIVE_SUBPROTOCOL = "foxglove.websocket.v1"
#: messages a client's queue holds before the oldest are dropped
CLIENT_QUEUE = 20000
_OP_MESSAGE_DATA = 0x01
_NAV_FIELDS = ("seq", "time_s", "lat_deg", "lon_deg", "height_m", "roll_deg", "pitch_deg", "heading_deg", "mode",
               "gnss_status", "psns_status", "cpu_load_pct", "deadline_misses")
_NAV_SCHEMA = {"title": "psns_hil.NavSolution", "type": "object",
               "description": "One NAV_SOLUTION as the host received it (deg, m, m/s; sigma: the filter's 1-sigma)",
               "properties": {**{f: {"type": "number"} for f in _NAV_FIELDS},
                              "vel_enu_mps": {"type": "array", "items": {"type": "number"}},
                              "sigma": {"type": "array", "items": {"type": "number"}},
                              "arrival_s": {"type": "number"}}}


def parse_host_port(text: str, default_port: int = 8765) -> tuple[str, int]:
    """``HOST:PORT``, ``HOST`` or ``:PORT`` (host 127.0.0.1); a bad port raises ``ValueError``."""
    host, _, port = text.rpartition(":") if ":" in text else (text, "", "")
    p = int(port) if port else default_port
    if not 0 <= p <= 65535:
        raise ValueError(f"port {p} out of range")
    return host or "127.0.0.1", p


def nav_solution_message(t_arrival: float, n: NavSolution) -> dict[str, Any]:
    """The ``/nav/solution`` message of a live frame: its fields as decoded, and its arrival time (s)."""
    msg: dict[str, Any] = {f: getattr(n, f) for f in _NAV_FIELDS}
    msg["vel_enu_mps"] = list(n.vel_enu_mps)
    msg["sigma"] = list(n.sigma)
    msg["arrival_s"] = t_arrival
    return msg


class _Client:
    def __init__(self, ws: Any) -> None:
        self.ws = ws
        self.subs: dict[int, int] = {}  # channel id -> subscription id
        self.queue: collections.deque[bytes | str] = collections.deque(maxlen=CLIENT_QUEUE)
        self.wake = asyncio.Event()


class LiveServer:
    """The live Foxglove WebSocket server (see module docstring). :meth:`start` binds and returns the port;
    :meth:`publish` is called from the emulator's thread; :meth:`close` stops it."""

    def __init__(self, host: str = "127.0.0.1", port: int = 8765) -> None:
        self.host, self.port = host, port
        self.channels: dict[str, int] = {}
        self._adverts: list[dict[str, Any]] = []
        self._clients: set[_Client] = set()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._stop: asyncio.Event | None = None
        self.dropped = 0
        self.published = 0
        self.refused = 0
        for topic, schema in (("/nav/solution", "psns_hil.NavSolution"), ("/nav/location", "foxglove.LocationFix"),
                              ("/nav/pose", "foxglove.PoseInFrame"), ("/tf", "foxglove.FrameTransform")):
            self._channel(topic, schema, _NAV_SCHEMA if schema == "psns_hil.NavSolution" else FOXGLOVE_SCHEMAS[schema])

    def _channel(self, topic: str, schema: str, definition: dict[str, Any]) -> int:
        cid = len(self.channels) + 1
        self.channels[topic] = cid
        self._adverts.append({"id": cid, "topic": topic, "encoding": "json", "schemaName": schema,
                              "schema": json.dumps(definition), "schemaEncoding": "jsonschema"})
        return cid

    def add_raw_channel(self, link: str, direction: str) -> None:
        """Advertise ``/raw/<link>/<direction>`` (before :meth:`start`)."""
        self._channel(f"/raw/{link}/{direction}", RAW_SCHEMA, _RAW_SCHEMA_DEF)

    # -- the server thread -----------------------------------------------------------------------
    def start(self) -> int:
        """Bind and serve on a thread of its own; returns the bound port (``port`` 0: one the OS chose)."""
        ready = threading.Event()
        err: list[BaseException] = []

        def run() -> None:
            loop = asyncio.new_event_loop()
            self._loop = loop
            try:
                loop.run_until_complete(self._serve(ready))
            except BaseException as exc:  # bind failure: reported to start()
                err.append(exc)
                ready.set()
            finally:
                loop.close()

        self._thread = threading.Thread(target=run, name="psns-hil-foxglove", daemon=True)
        self._thread.start()
        ready.wait(10.0)
        if err:
            raise err[0]
        return self.port

    async def _serve(self, ready: threading.Event) -> None:
        from websockets.asyncio.server import serve

        self._stop = asyncio.Event()
        async with serve(self._handle, self.host, self.port, subprotocols=[LIVE_SUBPROTOCOL],  # type: ignore[list-item]
                         max_size=1 << 16) as server:
            self.port = next(iter(server.sockets)).getsockname()[1]
            ready.set()
            await self._stop.wait()
            for _ in range(500):  # let every client receive what is queued (up to 5 s), then close
                if not any(c.queue for c in self._clients):
                    break
                for c in self._clients:
                    c.wake.set()
                await asyncio.sleep(0.01)

    async def _handle(self, ws: Any) -> None:
        client = _Client(ws)
        await ws.send(json.dumps({"op": "serverInfo", "name": "psns-hil", "capabilities": [],
                                  "supportedEncodings": [], "metadata": {}}))
        await ws.send(json.dumps({"op": "advertise", "channels": self._adverts}))
        self._clients.add(client)
        sender = asyncio.ensure_future(self._sender(client))
        try:
            async for raw in ws:
                self._on_client_message(client, raw)
        except Exception:
            pass
        finally:
            self._clients.discard(client)
            sender.cancel()

    def _refuse(self, client: _Client, what: str) -> None:
        self.refused += 1
        msg = {"op": "status", "level": 2, "message": f"psns-hil's live view is read-only: {what} refused",
               "id": "read-only"}
        client.queue.append(json.dumps(msg))  # a text frame, after what is queued before it
        client.wake.set()

    def _on_client_message(self, client: _Client, raw: str | bytes) -> None:
        if isinstance(raw, bytes):  # binary client messages: client publishing or service calls
            self._refuse(client, "binary client message")
            return
        try:
            msg = json.loads(raw)
            op = msg["op"] if isinstance(msg, dict) else None
        except (ValueError, KeyError):
            self._refuse(client, "malformed message")
            return
        if op == "subscribe":
            for s in msg.get("subscriptions", []):
                if isinstance(s, dict) and isinstance(s.get("id"), int) and s.get("channelId") in \
                        self.channels.values():
                    client.subs[s["channelId"]] = s["id"]
        elif op == "unsubscribe":
            ids = set(msg.get("subscriptionIds", []))
            client.subs = {c: s for c, s in client.subs.items() if s not in ids}
        else:  # advertise, unadvertise, getParameters, setParameters, subscribeParameterUpdates, ...
            self._refuse(client, str(op))

    async def _sender(self, client: _Client) -> None:
        while True:
            await client.wake.wait()
            client.wake.clear()
            while client.queue:
                await client.ws.send(client.queue.popleft())

    def _deliver(self, cid: int, log_ns: int, payload: bytes) -> None:
        for c in self._clients:
            sub = c.subs.get(cid)
            if sub is None:
                continue
            if len(c.queue) == c.queue.maxlen:
                self.dropped += 1
            c.queue.append(struct.pack("<BIQ", _OP_MESSAGE_DATA, sub, log_ns) + payload)
            c.wake.set()

    # -- the emulator's side ---------------------------------------------------------------------
    def publish(self, topic: str, t_s: float, msg: dict[str, Any]) -> None:
        """Send ``msg`` on ``topic`` at scenario time ``t_s`` to its subscribers (thread-safe)."""
        loop = self._loop
        cid = self.channels.get(topic)
        if loop is None or cid is None or not self._clients:
            return
        self.published += 1
        payload = json.dumps(msg, separators=(",", ":")).encode()
        loop.call_soon_threadsafe(self._deliver, cid, max(0, round(t_s * 1e9)), payload)

    def on_nav(self, t_arrival: float, n: NavSolution) -> None:
        """A recorder navigation listener: the frame on ``/nav/*`` and ``/tf``."""
        if not self._clients:
            return
        t = n.time_s
        self.publish("/nav/solution", t, nav_solution_message(t_arrival, n))
        sig = (n.sigma[7], n.sigma[6], n.sigma[8]) if len(n.sigma) >= 9 else None  # sigma: pos N, E, U
        self.publish("/nav/location", t, _location(t, n.lat_deg, n.lon_deg, n.height_m, sig, "body", n.heading_deg,
                                                   tuple(n.vel_enu_mps)))  # type: ignore[arg-type]
        x, y, z, w = attitude_quaternion(n.roll_deg, n.pitch_deg, n.heading_deg)
        q = {"x": x, "y": y, "z": z, "w": w}
        zero = {"x": 0.0, "y": 0.0, "z": 0.0}
        self.publish("/nav/pose", t, {"timestamp": _stamp(t), "frame_id": "enu",
                                      "pose": {"position": zero, "orientation": q}})
        self.publish("/tf", t, {"timestamp": _stamp(t), "parent_frame_id": "enu", "child_frame_id": "body",
                                "translation": zero, "rotation": q})

    def link_listener(self, name: str) -> Callable[..., None]:
        """An ``on_link_bytes`` for link ``name``: its chunks on ``/raw/<name>/<direction>``."""
        def on_link_bytes(link: Any, direction: str, t: float, data: bytes) -> None:
            if self._clients:
                self.publish(f"/raw/{name}/{direction}", t, {"link": name, "direction": direction, "pitch_s": None,
                                                             "data": base64.b64encode(data).decode("ascii")})
        return on_link_bytes

    def close(self) -> None:
        """Send what is queued, close the connections and stop the thread."""
        loop, stop = self._loop, self._stop
        if loop is not None and stop is not None and not loop.is_closed():
            loop.call_soon_threadsafe(stop.set)
        if self._thread is not None:
            self._thread.join(5.0)


class _LinkTap:
    """A :class:`~emulator.links.base.LinkListener` that hands every chunk to a callable."""

    __slots__ = ("on_link_bytes",)

    def __init__(self, fn: Callable[..., None]) -> None:
        self.on_link_bytes = fn


def attach(server: LiveServer, emu: Any) -> None:
    """Listen on ``emu``'s recorder and tapped links (called once the run has started)."""
    rec = emu.recorder
    rec.nav_listeners.append(server.on_nav)
    for name, link in emu.links.items():
        link.listeners.append(_LinkTap(server.link_listener(name)))
