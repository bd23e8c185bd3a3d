"""The DSP outside the emulator (``dsp.external``): a real C6747 board or a foreign firmware process behind the
virtual FPGA.

The FPGA-DSP UARTs named in the scenario are cut: the FPGA end of each becomes a real port (``pty://``,
``serial://``, ``zenoh://``), so the FPGA's frames (IMU/MAG on UART1, GNSS on UART3, PSNS on UART2, host commands
on UART0) reach the outside DSP at the FPGA's own timing and baud, and what the outside DSP writes on UART0 goes
through the FPGA's routing to the host port, where the recorder decodes it and compares it with truth as it does
for the virtual DSP. Nothing of the firmware model runs.

The outside DSP is hostile input (docs/hostile-input.md): what it writes on UART0 is decoded here as well (the
host frame format of docs/icd.md section 7) so that garbage, CRC errors and bad lengths are counted under their
cause, bytes it writes on a UART that only carries input to it (UART1-3) are counted as unexpected, and a DSP
that says nothing for ``silence_s`` after it was sent its first IMU frame is counted as silent. All of it lands
in ``summary.json`` (section ``external_dsp``); none of it ends the run.
"""

from __future__ import annotations

import asyncio
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from protocols.host import HostFormat, NavSolution
from protocols.stream import StreamDecoder

from ..devices.base import EventSink, NullEvents
from ..links import LineConfig, Link, LinkUrl, MemHub, open_link

__all__ = ["DirectionSwap", "ExternalDsp", "UartWatch", "cut_dsp_uarts"]

#: how often the silence watch looks, s of scenario time
SILENCE_POLL_S = 0.25


def cut_dsp_uarts(external: Mapping[Any, str | LinkUrl], uart_fpga: dict[str, Link], loop: asyncio.AbstractEventLoop,
                  hub: MemHub, run_dir: Path) -> dict[str, Link]:
    """Replace the FPGA end of each UART in ``external`` (name -> URL, or its parsed :class:`LinkUrl`) by a link to
    that URL, with the FPGA end's line; ``uart_fpga`` is changed in place. Returns the new links by UART name (not
    yet open)."""
    cut: dict[str, Link] = {}
    for uname, url in external.items():
        old = uart_fpga[uname]
        line: LineConfig = old.line
        link = open_link(url, uname, loop, default_line=line, hub=hub, run_dir=run_dir)
        uart_fpga[uname] = link
        cut[uname] = link
    return cut


class DirectionSwap:
    """A link listener wrapper that reports ``out`` as ``in`` and vice versa: a cut UART's FPGA end recorded as
    the DSP end is in a run with the virtual DSP (``in`` = what the DSP received)."""

    __slots__ = ("inner",)

    def __init__(self, inner: Any) -> None:
        self.inner = inner

    def on_link_bytes(self, link: Link, direction: str, t: float, data: bytes) -> None:
        self.inner.on_link_bytes(link, "in" if direction == "out" else "out", t, data)


class UartWatch:
    """Link listener of one cut UART (directions named from the FPGA's end: ``out`` to the DSP, ``in`` from it)."""

    __slots__ = ("dsp", "uart")

    def __init__(self, dsp: ExternalDsp, uart: str) -> None:
        self.dsp = dsp
        self.uart = uart

    def on_link_bytes(self, link: Link, direction: str, t: float, data: bytes) -> None:
        self.dsp._on_bytes(self.uart, direction, t, data)


class ExternalDsp:
    """Stands in for the :class:`~emulator.dsp.host.VirtualDsp` when the DSP is outside (see module docstring).

    Parameters
    ----------
    loop : the emulator's loop (scenario time).
    links : the cut UARTs by name (``uart0`` .. ``uart3``), FPGA side.
    silence_s : no byte from the DSP for this long, s, once it has been sent an IMU frame, is a silence.
    events : where ``external_dsp_silent`` / ``external_dsp_resumed`` events go (the recorder).
    """

    #: no firmware runs here: the session and the summary ask for none
    fw = None
    clock_hz = None

    def __init__(self, loop: asyncio.AbstractEventLoop, links: dict[str, Link], silence_s: float = 2.0,
                 events: EventSink | None = None) -> None:
        self.loop = loop
        self.links = links
        self.silence_s = silence_s
        self.events = events or NullEvents()
        self.deadline_misses = 0  # not observable from outside; kept for the live status and timeline
        self.watchdog_trips = 0
        self.host_decoder = StreamDecoder([HostFormat()])
        self.frames_by_kind: dict[str, int] = {}
        self.bytes_from_dsp: dict[str, int] = {u: 0 for u in links}
        self.bytes_to_dsp: dict[str, int] = {u: 0 for u in links}
        self.unexpected_bytes: dict[str, int] = {u: 0 for u in links if u != "uart0"}
        self.first_imu_t: float | None = None
        self.first_rx_t: float | None = None
        self.last_rx_t: float | None = None
        self.silences = 0
        self.silent_s = 0.0
        self._silent_since: float | None = None
        self.last_nav_time_s: float | None = None
        for uname, link in links.items():
            link.listeners.append(UartWatch(self, uname))

    def start(self) -> None:
        """Start the silence watch (scenario time)."""
        self.loop.call_later(SILENCE_POLL_S, self._watch)

    def _on_bytes(self, uart: str, direction: str, t: float, data: bytes) -> None:
        if direction == "out":
            self.bytes_to_dsp[uart] += len(data)
            if uart == "uart1" and self.first_imu_t is None:
                self.first_imu_t = t
            return
        self.bytes_from_dsp[uart] += len(data)
        if self.first_rx_t is None:
            self.first_rx_t = t
        self.last_rx_t = t
        if self._silent_since is not None:
            self.silent_s += t - self._silent_since
            self._silent_since = None
            self.events.emit(t, "external_dsp", "external_dsp_resumed", uart=uart)
        if uart != "uart0":
            self.unexpected_bytes[uart] += len(data)
            return
        for fr in self.host_decoder.feed(data):
            kind = type(fr).__name__
            self.frames_by_kind[kind] = self.frames_by_kind.get(kind, 0) + 1
            if isinstance(fr, NavSolution):
                self.last_nav_time_s = fr.time_s

    def _watch(self) -> None:
        now = self.loop.time()
        if self.first_imu_t is not None and self._silent_since is None:
            since = self.last_rx_t if self.last_rx_t is not None and self.last_rx_t > self.first_imu_t \
                else self.first_imu_t
            if now - since >= self.silence_s:
                self._silent_since = since
                self.silences += 1
                self.events.emit(now, "external_dsp", "external_dsp_silent", since_s=since)
        self.loop.call_later(SILENCE_POLL_S, self._watch)

    def section(self, end_t: float | None = None) -> dict[str, Any]:
        """The ``external_dsp`` section of ``summary.json``."""
        silent_s = self.silent_s
        if self._silent_since is not None and end_t is not None:
            silent_s += max(0.0, end_t - self._silent_since)
        st = self.host_decoder.stats.as_dict()
        return {
            "uarts": {u: {"url": lk.url, "path": lk.describe(), "bytes_to_dsp": self.bytes_to_dsp[u],
                          "unheard_bytes": lk.stats.no_peer_out, "bytes_from_dsp": self.bytes_from_dsp[u]}
                      for u, lk in self.links.items()},
            "host_frames": dict(self.frames_by_kind),
            "nav_frames": self.frames_by_kind.get("NavSolution", 0),
            "host_decoder": st,
            "garbage_bytes": st["garbage_bytes"],
            "crc_errors": st["crc_errors"],
            "length_errors": st["length_errors"],
            "unexpected_bytes": dict(self.unexpected_bytes),
            "first_imu_sent_s": self.first_imu_t,
            "first_byte_s": self.first_rx_t,
            "last_byte_s": self.last_rx_t,
            "silent": self.first_rx_t is None,
            "silences": self.silences,
            "silent_s": silent_s,
            "silence_s": self.silence_s,
        }

    def sections(self, end_t: float | None = None) -> dict[str, Any]:
        """The ``dsp`` and ``firmware`` sections of the summary when the DSP is outside."""
        return {"dsp": {"external": True, "clock_hz": None, "deadline_misses": None, "ticks": None},
                "firmware": {"external": True, "filter": None},
                "external_dsp": self.section(end_t)}
