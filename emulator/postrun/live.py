"""A live view of a run over the Foxglove WebSocket protocol (``psns-hil run --foxglove [HOST:PORT]``).

The server speaks the Foxglove WebSocket protocol v1 (subprotocol ``foxglove.websocket.v1``): on connection a
``serverInfo`` with no capabilities and an ``advertise`` of the channels known so far (JSON messages, JSON Schema);
a channel that appears later is advertised when its first message comes. A client ``subscribe`` s and receives
binary ``messageData`` frames (opcode 0x01, u32 subscription id, u64 log time ns, all little-endian, then the JSON
message); on subscribing it first gets the channel's latest message, if there is one (a channel written once, such
as the expectations at the end, still reaches a client that subscribes after it). It is **read-only**, as every
local endpoint of the project: client publishing (``advertise``, ``unadvertise``, binary client messages),
services and parameters are refused with a ``status`` error and change nothing. It listens on 127.0.0.1 unless
told otherwise.

**The same channels as run.mcap, by the same code** (docs/decisions/emulator-runtime.md D-7.28): the server follows
the run directory as the recorder flushes it (:class:`RunDirFollower`: the complete lines of truth.csv, nav.csv,
psns.csv, timeline.csv, filter_state.csv and events.jsonl, the complete records of capture.psnscap, summary.json at
the end) and hands them to :class:`~emulator.postrun.mcap_out.RunFeeds`, the conversion ``run.mcap`` is written
with; the channel set is :data:`~emulator.postrun.mcap_out.TOPICS` (and ``/raw/<link>/<direction>``) for both.
So nothing here reaches into a device (the recorder is the listener on the links and devices), and every value is
the one nav.csv holds. Latency: the recorder's flush interval (1 s of wall time) plus :data:`POLL_S`. Log time is the
scenario clock. The server runs on its own thread and asyncio loop, so the emulator's loop (virtual or paced time)
never waits for a socket or a conversion: a client that falls behind (a fast-mode run, a slow network) loses the
oldest messages of its bounded queue, counted in :attr:`LiveServer.dropped`.
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import csv
import json
import struct
import threading
from pathlib import Path
from typing import Any

from ..recording.capture import _PITCH, _REC, CAPTURE_MAGIC, FLAG_PITCH, CaptureRecord
from .mcap_out import (
    CAPTURE_FILE,
    CSV_SOURCES,
    EVENTS_FILE,
    RunFeeds,
    channel_schema,
    encode_message,
    read_summary,
)

__all__ = ["LIVE_SUBPROTOCOL", "POLL_S", "LiveServer", "RunDirFollower", "parse_host_port"]

LIVE_SUBPROTOCOL = "foxglove.websocket.v1"
#: messages a client's queue holds before the oldest are dropped
CLIENT_QUEUE = 20000
#: how often the server looks for what the recorder has flushed (wall s)
POLL_S = 0.2
#: bytes read from one file per look (a fast-mode run far ahead of the server is caught up over several looks)
READ_CHUNK = 1 << 20
#: at the end of the run, how long a client may take to subscribe to channels advertised last (wall s)
FINAL_SUBSCRIBE_S = 1
_OP_MESSAGE_DATA = 0x01


def parse_host_port(text: str, default_port: int = 8765) -> tuple[str, int]:
    """``HOST:PORT``, ``HOST`` or ``:PORT`` (host 127.0.0.1); a bad port raises ``ValueError``."""
    host, _, port = text.rpartition(":") if ":" in text else (text, "", "")
    p = int(port) if port else default_port
    if not 0 <= p <= 65535:
        raise ValueError(f"port {p} out of range")
    return host or "127.0.0.1", p


class _Tail:
    """The new complete lines (or bytes) of a file that another writer appends to."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self.pos = 0
        self.buf = b""
        #: bytes read so far
        self.total = 0

    def read(self) -> bytes:
        try:
            with open(self.path, "rb") as f:
                f.seek(self.pos)
                data = f.read(READ_CHUNK)
        except OSError:  # not written yet
            return b""
        self.pos += len(data)
        self.total += len(data)
        return data

    def lines(self) -> list[str]:
        self.buf += self.read()
        end = self.buf.rfind(b"\n") + 1
        if not end:
            return []
        done, self.buf = self.buf[:end], self.buf[end:]
        return done.decode("utf-8", errors="replace").splitlines()


class RunDirFollower:
    """Follows a run directory as the recorder writes it and feeds :class:`~emulator.postrun.mcap_out.RunFeeds`
    with what is complete: CSV lines (nav.csv and truth.csv in step, row for row, as the recorder writes them, so the
    poses have their ENU origin and ``/tf`` stays time-ordered), events.jsonl lines and capture records.
    :meth:`poll` takes what is new; ``final=True`` (the run is over) takes everything and summary.json."""

    def __init__(self, run_dir: Path, feeds: RunFeeds) -> None:
        self.run_dir = Path(run_dir)
        self.feeds = feeds
        self._csv = {name: _Tail(self.run_dir / name) for name in CSV_SOURCES}
        self._rows: dict[str, collections.deque[list[str]]] = {name: collections.deque() for name in CSV_SOURCES}
        self._headed: set[str] = set()
        self._events = _Tail(self.run_dir / EVENTS_FILE)
        self._cap = _Tail(self.run_dir / CAPTURE_FILE)
        self._cap_links: list[str] | None = None
        self.summary_done = False

    def poll(self, final: bool = False) -> int:
        """Feed what is new; returns the bytes read."""
        feeds = self.feeds
        before = self._bytes_read()
        for name, tail in self._csv.items():
            lines = tail.lines()
            if not lines:
                continue
            rows = list(csv.reader(lines))
            if name not in self._headed:
                feeds.csv_header(name, rows.pop(0))
                self._headed.add(name)
            self._rows[name].extend(rows)
        nav, truth = self._rows["nav.csv"], self._rows["truth.csv"]
        paired = max(len(nav), len(truth)) if final else min(len(nav), len(truth))
        for name, q in self._rows.items():
            n = paired if name in ("nav.csv", "truth.csv") else len(q)
            for _ in range(min(n, len(q))):
                feeds.csv_row(name, q.popleft())
        self._poll_capture()
        for line in self._events.lines():
            feeds.event_line(line)
        if final and not self.summary_done:
            summary = read_summary(self.run_dir)
            if summary is not None:
                feeds.summary(summary)
                self.summary_done = True
        return self._bytes_read() - before

    def _bytes_read(self) -> int:
        return sum(t.total for t in (*self._csv.values(), self._events, self._cap))

    def _poll_capture(self) -> None:
        tail = self._cap
        buf = tail.buf + tail.read()
        pos = 0
        if self._cap_links is None:
            end = buf.find(b"\n", len(CAPTURE_MAGIC))
            if end < 0 or not buf.startswith(CAPTURE_MAGIC):
                tail.buf = buf
                return
            try:
                header = json.loads(buf[len(CAPTURE_MAGIC):end])
            except json.JSONDecodeError:
                header = {}
            header = header if isinstance(header, dict) else {}
            self._cap_links = [str(x) for x in header.get("links", [])]
            self.feeds.capture_header(header)
            pos = end + 1
        links, size = self._cap_links, _REC.size
        while len(buf) - pos >= size:
            t, idx, d, flags, n = _REC.unpack_from(buf, pos)
            extra = _PITCH.size if flags & FLAG_PITCH else 0
            if len(buf) - pos < size + extra + n:
                break
            pitch = _PITCH.unpack_from(buf, pos + size)[0] if extra else None
            data = buf[pos + size + extra: pos + size + extra + n]
            pos += size + extra + n
            name = links[idx] if idx < len(links) else f"link{idx}"
            self.feeds.capture_record(CaptureRecord(t, name, "out" if d == 0 else "in", data, pitch))
        tail.buf = buf[pos:]


class _Client:
    def __init__(self, ws: Any) -> None:
        self.ws = ws
        self.subs: dict[int, int] = {}  # channel id -> subscription id
        self.queue: collections.deque[bytes | str] = collections.deque(maxlen=CLIENT_QUEUE)
        self.wake = asyncio.Event()


class LiveServer:
    """The live Foxglove WebSocket server (see module docstring): :meth:`follow` names the run directory,
    :meth:`start` binds and returns the port, :meth:`close` (after the run) sends the rest and stops.

    It is also the :class:`~emulator.postrun.mcap_out.MessageSink` of its feeds: :meth:`add` runs on the server's
    thread, inside a poll."""

    def __init__(self, host: str = "127.0.0.1", port: int = 8765) -> None:
        self.host, self.port = host, port
        #: topic -> channel id, in the order the channels appeared
        self.channels: dict[str, int] = {}
        self.schemas: dict[str, dict[str, Any]] = {}
        self._adverts: list[dict[str, Any]] = []
        #: each channel's latest message (log time ns, message: encoded once a client wants it)
        self._latest: dict[int, tuple[int, dict[str, Any] | bytes]] = {}
        self._batch: list[tuple[int, int, int, bytes]] = []
        self._new: list[dict[str, Any]] = []
        self._clients: set[_Client] = set()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._thread: threading.Thread | None = None
        self._stop: asyncio.Event | None = None
        self._follower: RunDirFollower | None = None
        self.dropped = 0
        self.published = 0
        self.refused = 0
        #: an error of the follower (the run goes on; the view stops following)
        self.error: str | None = None

    def follow(self, run_dir: Path) -> None:
        """Serve the run being written into ``run_dir`` (before :meth:`start`)."""
        self._follower = RunDirFollower(run_dir, RunFeeds(self))

    # -- the sink of the feeds (the server's thread) -----------------------------------------------
    def add(self, topic: str, log_s: float, msg: dict[str, Any], publish_s: float | None = None) -> None:
        """One message of the feeds: queued for the end of the poll (then time-ordered and sent)."""
        cid = self.channels.get(topic)
        if cid is None:
            schema = channel_schema(topic)
            cid = self.channels[topic] = len(self.channels) + 1
            advert = {"id": cid, "topic": topic, "encoding": "json", "schemaName": schema,
                      "schema": json.dumps(self.schemas[schema], sort_keys=True), "schemaEncoding": "jsonschema"}
            self._adverts.append(advert)
            self._new.append(advert)
        log_ns = max(0, round(log_s * 1e9))
        if not any(cid in c.subs for c in self._clients):  # nobody watching: the latest message, not encoded
            self._latest[cid] = (log_ns, msg)
            return
        self._batch.append((log_ns, len(self._batch), cid, encode_message(msg)))

    def _publish_batch(self) -> None:
        if self._new:
            text = json.dumps({"op": "advertise", "channels": self._new})
            for c in self._clients:
                c.queue.append(text)
                c.wake.set()
            self._new = []
        batch, self._batch = self._batch, []
        batch.sort()
        for log_ns, _i, cid, payload in batch:
            self._latest[cid] = (log_ns, payload)
            self.published += 1
            for c in self._clients:
                sub = c.subs.get(cid)
                if sub is None:
                    continue
                if len(c.queue) == c.queue.maxlen:
                    self.dropped += 1
                c.queue.append(struct.pack("<BIQ", _OP_MESSAGE_DATA, sub, log_ns) + payload)
                c.wake.set()

    def _poll(self, final: bool = False) -> int:
        """One look at the run directory; the bytes read."""
        if self._follower is None or self.error is not None:
            return 0
        n = 0
        try:
            n = self._follower.poll(final)
        except Exception as exc:  # a file the view cannot read: the run goes on without the view
            self.error = f"{type(exc).__name__}: {exc}"
        self._publish_batch()
        return n

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
            while not self._stop.is_set():
                self._poll()
                with contextlib.suppress(TimeoutError):
                    await asyncio.wait_for(self._stop.wait(), POLL_S)
            known = set(self.channels.values())
            while self._poll(final=True):  # the run is over: everything it wrote (a fast run may be far ahead)
                await asyncio.sleep(0)
            late = set(self.channels.values()) - known  # advertised at the end (the expectations): a client
            for _ in range(FINAL_SUBSCRIBE_S * 100):  # that subscribes in time gets their latest message
                if all(late <= set(c.subs) for c in self._clients):
                    break
                await asyncio.sleep(0.01)
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
        await ws.send(json.dumps({"op": "advertise", "channels": list(self._adverts)}))
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
        except ValueError:
            msg = None
        if not isinstance(msg, dict) or not isinstance(msg.get("op"), str):
            self._refuse(client, "malformed message")
            return
        op = msg["op"]
        subs, ids = msg.get("subscriptions"), msg.get("subscriptionIds")
        if op == "subscribe" and isinstance(subs, list):
            known = set(self.channels.values())
            for s in subs:
                if isinstance(s, dict) and isinstance(s.get("id"), int) and s.get("channelId") in known:
                    cid = s["channelId"]
                    client.subs[cid] = s["id"]
                    latest = self._latest.get(cid)
                    if latest is not None:  # the channel's latest message, at once
                        log_ns, m = latest
                        payload = m if isinstance(m, bytes) else encode_message(m)
                        self._latest[cid] = (log_ns, payload)
                        client.queue.append(struct.pack("<BIQ", _OP_MESSAGE_DATA, s["id"], log_ns) + payload)
                        client.wake.set()
        elif op == "unsubscribe" and isinstance(ids, list):
            gone = {i for i in ids if isinstance(i, int)}
            client.subs = {c: s for c, s in client.subs.items() if s not in gone}
        elif op in ("subscribe", "unsubscribe"):
            self._refuse(client, f"malformed {op}")
        else:  # advertise, unadvertise, getParameters, setParameters, subscribeParameterUpdates, ...
            self._refuse(client, str(op))

    async def _sender(self, client: _Client) -> None:
        while True:
            await client.wake.wait()
            client.wake.clear()
            while client.queue:
                await client.ws.send(client.queue.popleft())

    def close(self) -> None:
        """The run is over: send what it wrote since the last look and what is queued, close the connections and
        stop the thread."""
        loop, stop = self._loop, self._stop
        if loop is not None and stop is not None and not loop.is_closed():
            loop.call_soon_threadsafe(stop.set)
        if self._thread is not None:
            self._thread.join(30.0)
