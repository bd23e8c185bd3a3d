"""The FPGA process of a split run: the whole box but the DSP, its UART ends on zenoh, the DSP process started
and collected (see :mod:`emulator.distributed.split`)."""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import subprocess
import sys
import time
import uuid
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ...assembly.session import Emulator, run_emulator
from ...links.zenoh import AUTH_ENV, ZenohEndpointConfig, ZenohLink
from ...scenario.schema import Scenario
from .control import READY_TIMEOUT_S, STOP_TIMEOUT_S, SplitControl, SplitError, free_tcp_port

__all__ = ["RemoteDsp", "SplitFpgaEmulator", "run_split"]


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

    Parameters are those of :class:`~emulator.assembly.session.Emulator`; ``python`` is the interpreter that runs
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
        cmd = [self.python, "-m", "emulator.cli.dsp_process", "--spec", str(spec), "--key", self.run_key,
               "--connect", f"tcp/127.0.0.1:{self.zenoh_port}", "--parent-pid", str(os.getpid())]
        # the run's zenoh credentials (D-9.6): the DSP process presents the file the FPGA's session accepts
        env = {**os.environ, AUTH_ENV: self.endpoint.credentials().file}
        with open(self.child_log, "wb") as log:  # the child has its own copy of the descriptor
            try:
                self.child = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                              cwd=os.getcwd(), env=env)
            except OSError as exc:
                raise SplitError(f"cannot start the DSP process ({cmd[0]}): {exc}") from exc

    def _child_exited(self) -> bool:
        return self.child is not None and self.child.poll() is not None

    def _child_failure(self, what: str) -> SplitError:
        tail = ""
        with contextlib.suppress(OSError):
            tail = self.child_log.read_text(errors="replace")[-2000:]
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
        with contextlib.suppress(RuntimeError):  # the loop is closed: the run is over
            loop.call_soon_threadsafe(self._record_event, msg)

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
            cut = self.uart_links.get(p["name"])
            if cut is not None:
                p["url"], p["path"] = cut.url, cut.describe()
        assert self.loop is not None
        self.ctl.send("start", t0_monotonic=self.loop._wall0, speed=self.loop.speed)

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
                with contextlib.suppress(Exception):  # closing must not lose the summary
                    await link.close()
            with contextlib.suppress(Exception):  # the session may be gone; the summary says so
                self.ctl.send("stop")
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
            with contextlib.suppress(Exception):  # the session may be gone
                self.ctl.send("stop")
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
    """Run ``scn`` split in two processes (realtime); returns the summary like
    :func:`~emulator.assembly.session.run_scenario`."""
    emu = SplitFpgaEmulator(scn, run_dir, seed=seed, progress=progress)
    return run_emulator(emu, speed if speed is not None else scn.speed, on_started)
