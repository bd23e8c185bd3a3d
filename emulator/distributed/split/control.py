"""The control channel of a split run: JSON messages on ``psns/<run>/ctl/<kind>`` between the two processes
(see :mod:`emulator.distributed.split`), and what both sides share (timeouts, the error, a free port)."""

from __future__ import annotations

import asyncio
import contextlib
import json
import queue
import socket
import time
from collections.abc import Callable
from typing import Any

import numpy as np

from ...errors import EmulatorError
from ...links.zenoh import ZenohEndpointConfig, acquire_session, release_session

__all__ = ["READY_TIMEOUT_S", "STOP_TIMEOUT_S", "SplitControl", "SplitError", "free_tcp_port"]

#: How long the FPGA process waits for the DSP process to come up (wall s; it imports numpy and the firmware).
READY_TIMEOUT_S = 60.0
#: How long it waits for the DSP's summary and exit at the end (wall s).
STOP_TIMEOUT_S = 15.0


class SplitError(EmulatorError):
    """The DSP process could not be started, did not answer, or failed."""


def free_tcp_port() -> int:
    """A TCP port on 127.0.0.1 that the OS reports free."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def _jsonable(o: Any) -> Any:
    if isinstance(o, (np.floating, np.integer)):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    return str(o)


class SplitControl:
    """The control channel of a split run (see module docstring) on one side.

    Parameters
    ----------
    endpoint:
        The zenoh session configuration (shared with the side's UART links).
    run_key:
        ``<run>`` of ``psns/<run>/ctl/...``.
    on_event:
        Called on the zenoh thread for every ``event`` message (hand it to a loop yourself).
    """

    KINDS = ("ready", "start", "event", "stop", "summary", "error")

    def __init__(self, endpoint: ZenohEndpointConfig, run_key: str,
                 on_event: Callable[[dict[str, Any]], None] | None = None,
                 loop: asyncio.AbstractEventLoop | None = None,
                 on_start: Callable[[dict[str, Any]], None] | None = None) -> None:
        self.endpoint = endpoint
        #: with a loop, messages reach the queues through it, in order with the data links' callbacks
        self._loop = loop
        self._on_start = on_start
        self.prefix = f"psns/{run_key}/ctl"
        self.session = acquire_session(endpoint)
        self._queues: dict[str, queue.Queue[dict[str, Any]]] = {k: queue.Queue() for k in self.KINDS}
        self._on_event = on_event
        self._pubs: dict[str, Any] = {}
        #: kinds of message received so far
        self.seen: set[str] = set()
        self._sub = self.session.declare_subscriber(f"{self.prefix}/*", self._on_sample)
        self._closed = False

    def _on_sample(self, sample: Any) -> None:
        try:
            kind = str(sample.key_expr).rsplit("/", 1)[-1]
            msg = json.loads(sample.payload.to_bytes())
            if kind == "event" and self._on_event is not None:
                self._on_event(msg)
            elif kind in self._queues:
                if self._loop is not None:
                    self._loop.call_soon_threadsafe(self._arrived, kind, msg)
                else:
                    self.seen.add(kind)
                    self._queues[kind].put(msg)
        except Exception:  # never raise on a zenoh thread (nor for a closed loop)
            pass

    def _arrived(self, kind: str, msg: dict[str, Any]) -> None:
        if kind == "start" and self._on_start is not None:
            self._on_start(msg)
        self.seen.add(kind)
        self._queues[kind].put(msg)

    def _pub(self, kind: str) -> Any:
        pub = self._pubs.get(kind)
        if pub is None:
            import zenoh

            pub = self._pubs[kind] = self.session.declare_publisher(
                f"{self.prefix}/{kind}", congestion_control=zenoh.CongestionControl.BLOCK)
        return pub

    def send(self, kind: str, /, **payload: Any) -> None:
        self._pub(kind).put(json.dumps(payload, default=_jsonable).encode())

    def matched(self, kind: str) -> bool:
        try:
            return bool(self._pub(kind).matching_status.matching)
        except Exception:
            return False

    def get(self, kind: str) -> dict[str, Any] | None:
        """The next ``kind`` message if one arrived, else None (no waiting)."""
        try:
            return self._queues[kind].get_nowait()
        except queue.Empty:
            return None

    def wait(self, kind: str, timeout_s: float) -> dict[str, Any] | None:
        """Block the calling thread (wall clock) for the next ``kind`` message; None on timeout."""
        try:
            return self._queues[kind].get(timeout=timeout_s)
        except queue.Empty:
            return None

    async def await_(self, kind: str, timeout_s: float, also: Callable[[], bool] | None = None,
                     poll_s: float = 0.005) -> dict[str, Any] | None:
        """Wait in the event loop (wall clock) for the next ``kind`` message; None on timeout or when
        ``also()`` becomes true (e.g. the peer process exited)."""
        end = time.monotonic() + timeout_s
        while True:
            msg = self.get(kind)
            if msg is not None:
                return msg
            if time.monotonic() >= end or (also is not None and also()):
                return None
            await asyncio.sleep(poll_s)

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        for ent in [self._sub, *self._pubs.values()]:
            with contextlib.suppress(Exception):  # already undeclared with its session
                ent.undeclare()
        self._pubs.clear()
        release_session(self.endpoint)
