"""The DSP process of a split run: the firmware on a :class:`~emulator.dsp.host.VirtualDsp` whose UART ends are
the ``peer`` side of the FPGA process's zenoh keys (see :mod:`emulator.distributed.split`). Started by the FPGA
process as ``python -m emulator.cli.dsp_process ...`` (:func:`run_dsp_process`)."""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import time
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ...assembly.ports import UART_NUM
from ...assembly.session import Emulator
from ...clock import EmulatorLoop
from ...links import MemHub
from ...links.zenoh import ZenohEndpointConfig, ZenohLink
from ...scenario.loader import validate_scenario_data
from .control import READY_TIMEOUT_S, SplitControl, SplitError

__all__ = ["run_dsp_process"]


class _EventForwarder:
    """EventSink of the DSP process: every event goes to the FPGA process's recorder."""

    def __init__(self, ctl: SplitControl) -> None:
        self.ctl = ctl

    def emit(self, t: float, source: str, kind: str, /, **data: Any) -> None:
        self.ctl.send("event", t=t, source=source, kind=kind, data=data)


async def _dsp_main(spec_path: Path, key: str, connect: str, parent_pid: int | None) -> int:
    loop = asyncio.get_running_loop()
    assert isinstance(loop, EmulatorLoop)
    spec = json.loads(spec_path.read_text(encoding="utf-8"))
    base = Path(spec["base_dir"]) if spec.get("base_dir") else None
    scn = validate_scenario_data(spec["scenario"], {}, spec.get("source_file") or "<split>", base)
    endpoint = ZenohEndpointConfig(connect=(connect,))

    def on_start(msg: dict[str, Any]) -> None:
        # in the loop, before any data that followed it: from now on one scenario clock in both processes
        loop.speed = float(msg.get("speed", 1.0))
        loop._wall0 = float(msg["t0_monotonic"])  # one CLOCK_MONOTONIC per host  # one CLOCK_MONOTONIC per host

    ctl = SplitControl(endpoint, key, loop=loop, on_start=on_start)
    links: dict[int, ZenohLink] = {}
    try:
        emu = Emulator(scn, spec_path.parent, mode="realtime")  # for its construction helpers only
        emu.loop = loop
        uart_fpga, uart_dsp, rx_cfg = emu._build_uarts(MemHub(), loop, {})
        for uname, num in UART_NUM.items():
            if num not in uart_dsp:
                continue
            b = uart_dsp[num]
            z = ZenohLink(uname, f"zenoh://{key}/{uname}?role=peer&connect={connect}&pace=0&nav=off",
                          b.line, loop, target=f"{key}/{uname}")
            z.open_now()
            z.set_remote_line(uart_fpga[uname].line)
            links[num] = z
        dsp = emu.build_dsp(links, rx_cfg, _EventForwarder(ctl))  # type: ignore[arg-type]
        if not await _until(lambda: ctl.matched("ready"), READY_TIMEOUT_S):
            raise SplitError("the FPGA process's control channel did not answer")
        ctl.send("ready", pid=os.getpid())
        parent = parent_pid
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
    except Exception as exc:  # report to the FPGA process, then exit non-zero
        traceback.print_exc()
        with contextlib.suppress(Exception):  # the session may be gone too
            ctl.send("error", message=f"{type(exc).__name__}: {exc}")
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
    return os.getppid() == pid


def run_dsp_process(spec_path: Path, key: str, connect: str, parent_pid: int | None = None) -> int:
    """Run the DSP process of a split run until the FPGA process says stop (or goes away); the exit code.

    ``spec_path`` is the ``split-scenario.json`` the FPGA process wrote, ``key`` the run's zenoh key,
    ``connect`` the FPGA process's zenoh endpoint, ``parent_pid`` the FPGA process (its end ends this one).
    0: stopped normally; 1: no stop (the parent went away or the run overran); 2: failed (reported as ``error``).
    """
    loop = EmulatorLoop("realtime", 1.0)
    asyncio.set_event_loop(loop)
    try:
        return loop.run_until_complete(_dsp_main(Path(spec_path), key, connect, parent_pid))
    finally:
        asyncio.set_event_loop(None)
        loop.close()
