"""Split-process runs: the virtual DSP in its own OS process, joined to the virtual FPGA over zenoh.

``psns-hil run --split SCENARIO`` runs the scenario with the same assembly as a single-process run
(:class:`emulator.assembly.runner.Emulator`), cut at the FPGA-DSP UARTs:

* the **FPGA process** (this one) holds the world, the sensors, the external ports, the virtual FPGA
  and the recorder. Its ends of UART0-3 are :class:`~emulator.links.zenoh.ZenohLink` s
  (``zenoh://<run>/uartN``, role ``device``) instead of in-process ``mem://`` ends;
* the **DSP process** (``python -m emulator.distributed.split dsp ...``, started by this one) holds the
  firmware on a :class:`~emulator.dsp.host.VirtualDsp` whose UART ends are the ``peer`` side of
  the same keys.

Each end paces what it transmits with its own line model and delivers what it receives without
pacing again (``pace=0``), exactly as the two ends of a ``mem://`` pair do, so the only difference
from a single-process run is the transport latency between the two event loops (about 1 ms on
loopback: median 1.0 ms, p99 2 ms measured loop to loop; zenoh itself takes ~0.13 ms one way,
protocols.md section 4). The byte spacing of each chunk (which the DSP's UART FIFO model uses) travels with it
as the zenoh attachment. The run is realtime (the two processes share the wall clock).

Control messages (JSON) on ``psns/<run>/ctl/<kind>``:

``ready``   DSP -> FPGA: links and subscribers are up.
``start``   FPGA -> DSP: ``{"t0_monotonic", "speed"}``: scenario time 0 on the host's monotonic clock
            (``CLOCK_MONOTONIC`` is one clock for all processes of a host), so both processes
            share one scenario clock.
``event``   DSP -> FPGA: a device event (deadline miss, firmware event), written by the recorder.
``stop``    FPGA -> DSP: the run is over.
``summary`` DSP -> FPGA: the ``dsp`` and ``firmware`` sections of the summary.
``error``   DSP -> FPGA: the DSP process failed (message).

The FPGA's captures of UART0-3 are recorded with the DSP end's directions (``in`` = towards the
DSP), so that a split run's capture reads like a single-process one (and replays the same way).
"""

from __future__ import annotations

import argparse
import asyncio
import json
import os
import queue
import socket
import subprocess
import sys
import threading
import time
import uuid
from pathlib import Path
from typing import Any, Callable

from ..assembly.runner import UART_NUM, Emulator, run_emulator
from ..errors import EmulatorError
from ..links.zenoh import ZenohEndpointConfig, ZenohLink, acquire_session, release_session
from ..scenario.schema import Scenario

__all__ = ["SplitError", "SplitControl", "SplitFpgaEmulator", "run_split", "dsp_process_main", "free_tcp_port"]

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
    try:
        import numpy as np

        if isinstance(o, (np.floating, np.integer)):
            return o.item()
        if isinstance(o, np.ndarray):
            return o.tolist()
    except ImportError:  # pragma: no cover
        pass
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
        except Exception:  # noqa: BLE001 - never raise on a zenoh thread (nor for a closed loop)
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
        except Exception:  # noqa: BLE001
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
            try:
                ent.undeclare()
            except Exception:  # noqa: BLE001
                pass
        self._pubs.clear()
        release_session(self.endpoint)


class _DirectionSwap:
    """A link listener wrapper that reports ``out`` as ``in`` and vice versa (FPGA end seen as the DSP end)."""

    __slots__ = ("inner",)

    def __init__(self, inner: Any) -> None:
        self.inner = inner

    def on_link_bytes(self, link: Any, direction: str, t: float, data: bytes) -> None:
        self.inner.on_link_bytes(link, "in" if direction == "out" else "out", t, data)


class RemoteDsp:
    """Stands in for the :class:`~emulator.dsp.host.VirtualDsp` in the FPGA process (live status only):
    what the DSP process has reported so far."""

    fw = None

    def __init__(self, clock_hz: float) -> None:
        self.clock_hz = clock_hz
        self.deadline_misses = 0
        self.watchdog_trips = 0


def _wait_matched_sync(links: list[ZenohLink], timeout_s: float) -> list[str]:
    end = time.monotonic() + timeout_s
    while True:
        missing = [z.name for z in links if not z.peer_matched()]
        if not missing or time.monotonic() >= end:
            return missing
        time.sleep(0.002)


class SplitFpgaEmulator(Emulator):
    """The FPGA side of a split run (see module docstring); a realtime :class:`Emulator`.

    Parameters are those of :class:`~emulator.assembly.runner.Emulator`; ``python`` is the interpreter that runs
    the DSP process (default this one).
    """

    def __init__(self, scn: Scenario, run_dir: Path, seed: int | None = None,
                 progress: Callable[[float, float], None] | None = None, python: str | None = None) -> None:
        super().__init__(scn, run_dir, mode="realtime", seed=seed, progress=progress)
        self.run_key = f"split-{os.getpid()}-{uuid.uuid4().hex[:8]}"
        self.zenoh_port = free_tcp_port()
        self.endpoint = ZenohEndpointConfig(listen=(f"tcp/127.0.0.1:{self.zenoh_port}",))
        self.python = python or sys.executable
        self.ctl: SplitControl | None = None
        self.child: subprocess.Popen[bytes] | None = None
        self.child_log: Path = self.run_dir / "dsp-process.log"
        self.remote: dict[str, Any] | None = None
        self.remote_error: str | None = None
        self.uart_links: dict[str, ZenohLink] = {}
        self.remote_events = 0

    # -- the DSP process ----------------------------------------------------------------------
    def _spawn(self) -> None:
        self.run_dir.mkdir(parents=True, exist_ok=True)
        spec = self.run_dir / "split-scenario.json"
        spec.write_text(json.dumps({"scenario": self.scn.model_dump(mode="json"),
                                    "source_file": self.scn.source_file, "base_dir": self.scn.base_dir},
                                   default=str), encoding="utf-8")
        cmd = [self.python, "-m", "emulator.distributed.split", "dsp", "--spec", str(spec), "--key", self.run_key,
               "--connect", f"tcp/127.0.0.1:{self.zenoh_port}", "--parent-pid", str(os.getpid())]
        log = open(self.child_log, "wb")
        try:
            self.child = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                          cwd=os.getcwd())
        except OSError as exc:
            raise SplitError(f"cannot start the DSP process ({cmd[0]}): {exc}") from exc
        finally:
            log.close()

    def _child_exited(self) -> bool:
        return self.child is not None and self.child.poll() is not None

    def _child_failure(self, what: str) -> SplitError:
        tail = ""
        try:
            tail = self.child_log.read_text(errors="replace")[-2000:]
        except OSError:
            pass
        err = self.ctl.get("error") if self.ctl is not None else None
        msg = f"DSP process {what}"
        if err:
            msg += f": {err.get('message')}"
        elif tail:
            msg += f"; its log ({self.child_log}) ends:\n{tail}"
        return SplitError(msg)

    def _on_remote_event(self, msg: dict[str, Any]) -> None:
        loop = self.loop
        if loop is None:
            return
        try:
            loop.call_soon_threadsafe(self._record_event, msg)
        except RuntimeError:
            pass

    def _record_event(self, msg: dict[str, Any]) -> None:
        if self.recorder is None or self._stopped:
            return
        self.remote_events += 1
        if isinstance(self.dsp, RemoteDsp) and msg.get("source") == "dsp":
            if msg.get("kind") == "deadline_miss":
                self.dsp.deadline_misses += 1
            elif msg.get("kind") == "watchdog":
                self.dsp.watchdog_trips += 1
        self.recorder.emit(float(msg["t"]), msg["source"], msg["kind"], **msg.get("data", {}))

    # -- assembly -------------------------------------------------------------------------------
    async def start(self) -> None:
        self.loop = asyncio.get_running_loop()  # type: ignore[assignment]
        self.ctl = SplitControl(self.endpoint, self.run_key, on_event=self._on_remote_event)
        self._spawn()
        ready = await self.ctl.await_("ready", READY_TIMEOUT_S, also=self._child_exited)
        if ready is None:
            raise self._child_failure("did not come up" if not self._child_exited() else "exited at start-up")
        await super().start()  # builds everything; _build_uarts below cuts the UARTs; restarts the clock
        for z in self.uart_links.values():  # record the UARTs from the DSP end's side, as a single run does
            z.listeners[:] = [_DirectionSwap(lst) for lst in z.listeners]
        for p in self.ports:
            z = self.uart_links.get(p["name"])
            if z is not None:
                p["url"], p["path"] = z.url, z.describe()
        assert self.loop is not None
        self.ctl.send("start", t0_monotonic=self.loop._wall0, speed=self.loop.speed)  # noqa: SLF001

    def _build_uarts(self, hub: Any, loop: Any, ext: dict[str, Any]) -> Any:
        uart_fpga, uart_dsp, rx_cfg = super()._build_uarts(hub, loop, ext)
        ep = self.endpoint.listen[0]
        for uname, a in list(uart_fpga.items()):
            d_line = self.links[uname].line
            z = ZenohLink(uname, f"zenoh://{self.run_key}/{uname}?listen={ep}&pace=0&nav=off", a.line, loop,
                          target=f"{self.run_key}/{uname}")
            z.open_now()
            z.set_remote_line(d_line)
            uart_fpga[uname] = z
            self.links[uname] = z
            self.uart_links[uname] = z
        missing = _wait_matched_sync(list(self.uart_links.values()), READY_TIMEOUT_S)
        if missing:
            raise self._child_failure(f"did not subscribe to {', '.join(missing)}")
        # the DSP ends built by the base class stay unconnected here (build_dsp below attaches nothing to them)
        return uart_fpga, uart_dsp, rx_cfg

    def build_dsp(self, uart_dsp: dict[int, Any], rx_cfg: dict[int, Any], events: Any) -> Any:
        return RemoteDsp(self.scn.dsp.clock_hz)

    def dsp_sections(self) -> dict[str, Any]:
        if self.remote is not None:
            return {"dsp": self.remote["dsp"], "firmware": self.remote["firmware"]}
        return {"dsp": {"error": self.remote_error, "deadline_misses": None},
                "firmware": {"error": self.remote_error}}

    # -- the end ----------------------------------------------------------------------------------
    async def stop(self, interrupted: bool = False) -> dict[str, Any]:
        if not self._stopped and self.ctl is not None:
            # the run ends now, as a single-process run does: close the ports (no byte after duration_s is
            # recorded), then collect the DSP process's results
            for link in list(self.links.values()) + list(self.device_ends.values()):
                try:
                    await link.close()
                except Exception:  # noqa: BLE001 - closing must not lose the summary
                    pass
            try:
                self.ctl.send("stop")
            except Exception:  # noqa: BLE001 - the session may be gone; the summary says so
                pass
            self.remote = await self.ctl.await_("summary", STOP_TIMEOUT_S, also=self._child_exited)
            if self.remote is None:
                err = self.ctl.get("error")
                self.remote_error = err.get("message") if err else (
                    "the DSP process exited without a summary" if self._child_exited()
                    else "no summary from the DSP process")
        try:
            return await super().stop(interrupted)
        finally:
            self._shutdown_child()

    async def _abort(self) -> None:
        """A failed start: tell the DSP process to go, close everything of ours, reap it."""
        if self.ctl is not None:
            try:
                self.ctl.send("stop")
            except Exception:  # noqa: BLE001
                pass
        try:
            await super()._abort()
        finally:
            self._shutdown_child(timeout_s=2.0)

    def _shutdown_child(self, timeout_s: float = STOP_TIMEOUT_S) -> None:
        if self.ctl is not None:
            self.ctl.close()
            self.ctl = None
        child = self.child
        if child is None:
            return
        try:
            child.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            child.terminate()
            try:
                child.wait(timeout=5.0)
            except subprocess.TimeoutExpired:
                child.kill()
                child.wait()

    def _summary(self, sim_t: float, wall: float, interrupted: bool) -> dict[str, Any]:
        s = super()._summary(sim_t, wall, interrupted)
        s["split"] = {
            "run_key": self.run_key,
            "endpoint": self.endpoint.listen[0],
            "dsp_pid": self.child.pid if self.child is not None else None,
            "dsp_log": str(self.child_log),
            "remote_events": self.remote_events,
            "dsp_link_stats": (self.remote or {}).get("link_stats"),
            "error": self.remote_error,
        }
        return s


def run_split(scn: Scenario, run_dir: Path, speed: float | None = None, seed: int | None = None,
              progress: Callable[[float, float], None] | None = None,
              on_started: Callable[[Emulator], None] | None = None) -> dict[str, Any]:
    """Run ``scn`` split in two processes (realtime); returns the summary like :func:`~emulator.assembly.runner.run_scenario`."""
    emu = SplitFpgaEmulator(scn, run_dir, seed=seed, progress=progress)
    return run_emulator(emu, speed if speed is not None else scn.speed, on_started)


# -- the DSP process ------------------------------------------------------------------------------------
class _EventForwarder:
    """EventSink of the DSP process: every event goes to the FPGA process's recorder."""

    def __init__(self, ctl: SplitControl) -> None:
        self.ctl = ctl

    def emit(self, t: float, source: str, kind: str, /, **data: Any) -> None:
        self.ctl.send("event", t=t, source=source, kind=kind, data=data)


async def _dsp_main(args: argparse.Namespace) -> int:
    from ..clock import EmulatorLoop
    from ..links import MemHub
    from ..scenario.loader import validate_scenario_data

    loop = asyncio.get_running_loop()
    assert isinstance(loop, EmulatorLoop)
    spec = json.loads(Path(args.spec).read_text(encoding="utf-8"))
    base = Path(spec["base_dir"]) if spec.get("base_dir") else None
    scn = validate_scenario_data(spec["scenario"], {}, spec.get("source_file") or "<split>", base)
    endpoint = ZenohEndpointConfig(connect=(args.connect,))

    def on_start(msg: dict[str, Any]) -> None:
        # in the loop, before any data that followed it: from now on one scenario clock in both processes
        loop.speed = float(msg.get("speed", 1.0))  # type: ignore[attr-defined]
        loop._wall0 = float(msg["t0_monotonic"])  # type: ignore[attr-defined]  # noqa: SLF001 - one CLOCK_MONOTONIC per host

    ctl = SplitControl(endpoint, args.key, loop=loop, on_start=on_start)
    links: dict[int, ZenohLink] = {}
    try:
        emu = Emulator(scn, Path(args.spec).parent, mode="realtime")  # for its construction helpers only
        emu.loop = loop
        uart_fpga, uart_dsp, rx_cfg = emu._build_uarts(MemHub(), loop, {})  # noqa: SLF001
        for uname, num in UART_NUM.items():
            if num not in uart_dsp:
                continue
            b = uart_dsp[num]
            z = ZenohLink(uname, f"zenoh://{args.key}/{uname}?role=peer&connect={args.connect}&pace=0&nav=off",
                          b.line, loop, target=f"{args.key}/{uname}")
            z.open_now()
            z.set_remote_line(uart_fpga[uname].line)
            links[num] = z
        dsp = emu.build_dsp(links, rx_cfg, _EventForwarder(ctl))  # type: ignore[arg-type]
        if not await _until(lambda: ctl.matched("ready"), READY_TIMEOUT_S):
            raise SplitError("the FPGA process's control channel did not answer")
        ctl.send("ready", pid=os.getpid())
        parent = args.parent_pid
        start = await ctl.await_("start", READY_TIMEOUT_S, also=lambda: "stop" in ctl.seen or not _alive(parent))
        if start is None:
            raise SplitError("no start from the FPGA process")
        # the FPGA declared its UART subscribers before it sent start; make sure we see them before any output
        if not await _until(lambda: all(z.peer_matched() for z in links.values()), 5.0):
            raise SplitError("the FPGA process did not subscribe to the DSP's UART output")
        deadline = time.monotonic() + scn.duration_s / loop.speed + 60.0
        stop = await ctl.await_("stop", max(0.0, deadline - time.monotonic()), also=lambda: not _alive(parent))
        emu.dsp = dsp
        sections = emu.dsp_sections()
        ctl.send("summary", dsp=sections["dsp"], firmware=sections["firmware"], stopped=stop is not None,
                 link_stats={z.name: z.stats.as_dict() for z in links.values()})
        return 0 if stop is not None else 1
    except Exception as exc:  # noqa: BLE001 - report to the FPGA process, then exit non-zero
        import traceback

        traceback.print_exc()
        try:
            ctl.send("error", message=f"{type(exc).__name__}: {exc}")
        except Exception:  # noqa: BLE001
            pass
        return 2
    finally:
        for z in links.values():
            await z.close()
        ctl.close()


async def _until(pred: Callable[[], bool], timeout_s: float) -> bool:
    end = time.monotonic() + timeout_s
    while not pred():
        if time.monotonic() >= end:
            return False
        await asyncio.sleep(0.002)
    return True


def _alive(pid: int | None) -> bool:
    if not pid:
        return True
    if os.getppid() != pid:
        return False
    return True


def dsp_process_main(argv: list[str] | None = None) -> int:
    """Entry point of the DSP process (``python -m emulator.distributed.split dsp ...``)."""
    from ..clock import EmulatorLoop

    p = argparse.ArgumentParser(prog="python -m emulator.distributed.split")
    sub = p.add_subparsers(dest="cmd", required=True)
    d = sub.add_parser("dsp", help="run the virtual DSP of a split run (started by psns-hil run --split)")
    d.add_argument("--spec", required=True, help="split-scenario.json written by the FPGA process")
    d.add_argument("--key", required=True, help="zenoh run key")
    d.add_argument("--connect", required=True, help="zenoh endpoint of the FPGA process")
    d.add_argument("--parent-pid", type=int, default=None)
    args = p.parse_args(argv)
    loop = EmulatorLoop("realtime", 1.0)
    asyncio.set_event_loop(loop)
    try:
        return loop.run_until_complete(_dsp_main(args))
    finally:
        asyncio.set_event_loop(None)
        loop.close()


if __name__ == "__main__":  # pragma: no cover - the DSP process
    sys.exit(dsp_process_main())
