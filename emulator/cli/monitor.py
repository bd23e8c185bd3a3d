"""``psns-hil monitor ENDPOINT``: decode a port's traffic into a table of frames, live.

Endpoints:

* a capture file (``*.psnscap``): every record of every link (``--link`` to pick some), with its
  recorded time and direction;
* a serial device or a pseudo-terminal path (``/dev/ttyUSB0``, ``runs/x/ports/uart0``,
  ``serial:///dev/ttyUSB0``): opened with pyserial at ``--baud`` and decoded as bytes arrive --
  the same tool works on the real box's connectors; ``t_s`` counts from when the monitor opened it, except on a
  pty of a realtime run (``<run_dir>/ports/NAME``): there it is the scenario clock, from the run's ``clock.json``
  (:func:`run_clock_origin`; before the run has started, from the monitor's start until it has);
* a plain file of bytes (a dump of a port, ``cat /dev/ttyUSB0 > dump.bin``): decoded from start to end, ``t_s``
  the time of each chunk's first byte at ``--baud`` (10 bits a byte) from the file's start;
* ``zenoh://RUN/PORT`` (:mod:`emulator.links.zenoh`): what is published on ``psns/RUN/PORT/tx`` (bytes the
  port's owner transmits, shown as ``out``) and ``psns/RUN/PORT/rx`` (bytes it receives, ``in``), decoded as
  they arrive. The zenoh session connects to ``tcp/127.0.0.1:7447`` (where an emulator's zenoh port listens
  by default) unless the URL says ``connect=``, ``listen=``, ``session=``, ``config=`` or ``auth=`` as for a
  link; scouting is off. The emulator refuses sessions without its credentials: give the run's credentials
  file with ``auth=FILE`` (its path is in the run's ``ports.json``) or ``PSNS_HIL_ZENOH_AUTH=FILE``.

Decoders: ``--protocol`` names the frame families (``host``, ``imu``, ``stim210`` or
``stim210:FMT``, ``nmea``, ``psns``, ``ubx``, ``monitor``); ``auto`` (default) picks them from the port
name (the file name of a pty symlink such as ``uart0``, the capture's link name, or the PORT of a
zenoh key); a pty of a run (``runs/x/ports/NAME``) is looked up in the run's ``ports.json``, so a port named
freely in its URL (``pty://nmea`` for ``links.host_nmea``) is still told. On the MONITOR port every record is
unpacked and its
bytes are decoded with its channel's decoders, so one stream shows every channel.

Everything goes through :class:`protocols.stream.StreamDecoder`: bad bytes are counted, never
fatal. A frame holding a non-finite value (NaN, +-inf: an outside DSP may send them) is shown as it is (``nan``,
``inf`` in the table, ``null`` in JSON) and counted in its decoder's ``nonfinite_frames``. Lines are never cut.
The decoder statistics are printed at the end (Ctrl-C ends a live session cleanly).
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import math
import os
import queue
import select
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any, TextIO

from protocols.host import HostFormat
from protocols.imu_frame import FpgaFrameFormat
from protocols.monitor import MONITOR_CHANNELS, MonitorFormat
from protocols.nmea import NMEA_RX_MAX_LEN, NmeaFormat
from protocols.psns import PsnsFormat
from protocols.stim import Stim210Format
from protocols.stream import StreamDecoder
from protocols.ubx import UbxFormat

from ..errors import EmulatorError
from ..links import parse_link_url
from ..links.zenoh import DEFAULT_LISTEN, ZenohEndpointConfig, acquire_session, release_session, zenoh_key_prefix
from ..recording.capture import CAPTURE_MAGIC, iter_capture

__all__ = ["PROTOCOLS", "FrameRow", "Monitor", "describe_frame", "formats_for", "run_monitor"]


def _protocol_table() -> dict[str, Callable[[str], list[Any]]]:
    """Protocol name -> decoders given the name's argument (``stim210:FMT``)."""
    return {
        "host": lambda arg: [HostFormat()],
        "imu": lambda arg: [FpgaFrameFormat()],  # the IMU frame and the MAG frame that share the FPGA's UART
        "stim210": lambda arg: [Stim210Format(arg or "m")],
        "nmea": lambda arg: [NmeaFormat(NMEA_RX_MAX_LEN)],  # a receiving tool: real receivers' long sentences
        "psns": lambda arg: [PsnsFormat()],
        "ubx": lambda arg: [UbxFormat()],
        "monitor": lambda arg: [MonitorFormat()],
    }


#: protocol names accepted by ``--protocol`` (besides ``auto``)
PROTOCOLS = ("host", "imu", "stim210", "nmea", "psns", "ubx", "monitor")

#: port name -> protocols decoded there (both directions)
_AUTO = {
    "host": ("host",), "uart0": ("host",), "gyro": ("stim210",), "uart1": ("imu",),
    "gnss": ("nmea", "ubx"), "uart3": ("nmea", "ubx"), "psns": ("psns",), "uart2": ("psns",),
    "monitor": ("monitor",), "host_nmea": ("nmea",), "nmea": ("nmea",), "ubx": ("ubx",),
    # the ports of an external DSP (docs/runtime.md: the firmware is started on <run_dir>/ports/dsp_uartN)
    "dsp_uart0": ("host",), "dsp_uart1": ("imu",), "dsp_uart2": ("psns",), "dsp_uart3": ("nmea", "ubx"),
}


def formats_for(port: str | None, protocol: str = "auto") -> list[Any]:
    """Frame formats for ``port`` under ``--protocol`` (comma-separated names or ``auto``)."""
    table = _protocol_table()
    if protocol == "auto":
        names = _AUTO.get((port or "").lower())
        if names is None:
            raise EmulatorError(f"cannot tell the protocol of {port!r} from its name; "
                                f"give --protocol ({', '.join(sorted(table))})")
    else:
        names = tuple(p.strip() for p in protocol.split(",") if p.strip())
    out: list[Any] = []
    for spec in names:
        name, _, arg = spec.partition(":")
        if name not in table:
            raise EmulatorError(f"unknown protocol {name!r}; known: {', '.join(sorted(table))}")
        out += table[name](arg)
    if not out:
        raise EmulatorError(f"no decoder available for {port!r}")
    return out


def _short(v: Any) -> str:
    if isinstance(v, float):
        return f"{v:.7g}"
    if isinstance(v, (tuple, list)):
        if len(v) > 6:
            return "(" + ", ".join(_short(x) for x in v[:6]) + f", ... {len(v)} items)"
        return "(" + ", ".join(_short(x) for x in v) + ")"
    if isinstance(v, (bytes, bytearray)):
        return v[:16].hex() + ("..." if len(v) > 16 else "")
    if dataclasses.is_dataclass(v) and not isinstance(v, type):
        return type(v).__name__
    return str(v)


def describe_frame(fr: Any) -> tuple[str, dict[str, Any]]:
    """``(type name, fields)`` of a decoded frame, fields JSON-friendly."""
    if dataclasses.is_dataclass(fr) and not isinstance(fr, type):
        fields = {f.name: getattr(fr, f.name) for f in dataclasses.fields(fr)}
    elif hasattr(fr, "_asdict"):
        fields = dict(fr._asdict())
    else:
        fields = {"value": fr}
    return type(fr).__name__, fields


@dataclasses.dataclass
class FrameRow:
    """One decoded frame: when, where, what."""

    t_s: float
    port: str
    direction: str
    frame: Any

    def text(self, width: int | None = None) -> str:
        """The table line, whole (a NAV_SOLUTION's mode and counters are at its end), or cut at ``width``."""
        kind, fields = describe_frame(self.frame)
        body = " ".join(f"{k}={_short(v)}" for k, v in fields.items())
        line = f"{self.t_s:12.6f}  {self.port:<8} {self.direction:<3}  {kind:<18} {body}"
        return line if width is None or len(line) <= width else line[: width - 3] + "..."

    def as_json(self) -> str:
        kind, fields = describe_frame(self.frame)

        def conv(v: Any) -> Any:
            if isinstance(v, (bytes, bytearray)):
                return v.hex()
            if dataclasses.is_dataclass(v) and not isinstance(v, type):
                return {f.name: conv(getattr(v, f.name)) for f in dataclasses.fields(v)}
            if isinstance(v, (tuple, list)):
                return [conv(x) for x in v]
            if isinstance(v, dict):
                return {str(k): conv(x) for k, x in v.items()}
            if isinstance(v, float) and v - v != 0.0:
                return None  # NaN / infinity are not JSON
            if isinstance(v, (int, float, str, bool)) or v is None:
                return v
            return str(v)

        return json.dumps({"t_s": self.t_s, "port": self.port, "dir": self.direction, "type": kind,
                           "fields": conv(fields)})


class Monitor:
    """Decoders per (port, direction), with MONITOR-record demultiplexing."""

    def __init__(self, protocol: str = "auto") -> None:
        self.protocol = protocol
        self.decoders: dict[tuple[str, str], StreamDecoder] = {}
        self._channel_names: dict[int, str] | None = None
        #: frames holding a non-finite float, per decoder key (shown, counted, never raised)
        self.nonfinite: dict[tuple[str, str], int] = {}

    def _decoder(self, port: str, direction: str) -> StreamDecoder:
        key = (port, direction)
        dec = self.decoders.get(key)
        if dec is None:
            dec = self.decoders[key] = StreamDecoder(formats_for(port, self.protocol))
        return dec

    def feed(self, t: float, port: str, direction: str, data: bytes) -> list[FrameRow]:
        rows = []
        for fr in self._decoder(port, direction).feed(data):
            if type(fr).__name__ == "MonitorRecord" and self.protocol in ("auto", "monitor"):
                rows += self._demux(fr)
            else:
                self._count_nonfinite((port, direction), fr)
                rows.append(FrameRow(t, port, direction, fr))
        return rows

    def _count_nonfinite(self, key: tuple[str, str], fr: Any) -> None:
        if _has_nonfinite(fr):
            self.nonfinite[key] = self.nonfinite.get(key, 0) + 1

    def _demux(self, rec: Any) -> list[FrameRow]:
        if self._channel_names is None:
            self._channel_names = {v: k for k, v in MONITOR_CHANNELS.items()}
        ch = self._channel_names.get(rec.channel, f"ch{rec.channel}")
        d = "in" if rec.direction == 0 else "out"  # towards / away from the DSP
        t = rec.t_us / 1e6
        key = (f"monitor:{ch}", d)
        dec = self.decoders.get(key)
        if dec is None:
            try:
                fm = formats_for(ch, "auto")
            except EmulatorError:
                return [FrameRow(t, ch, d, rec)]
            dec = self.decoders[key] = StreamDecoder(fm)
        rows = [FrameRow(t, ch, d, fr) for fr in dec.feed(rec.data)]
        for r in rows:
            self._count_nonfinite(key, r.frame)
        return rows

    def stats(self) -> dict[str, dict[str, Any]]:
        # NMEA lines accepted with an LF-only end are counted apart (never as CRC errors)
        out = {}
        for (p, d), dec in self.decoders.items():
            st = dec.stats.as_dict()
            nmea = [f for f in dec.formats if isinstance(f, NmeaFormat)]
            if nmea:
                st["lf_only"] = sum(f.lf_only for f in nmea)
            st["nonfinite_frames"] = self.nonfinite.get((p, d), 0)
            out[f"{p}/{d}"] = st
        return out


def _has_nonfinite(fr: Any) -> bool:
    """True when a decoded frame holds a NaN or an infinity in a float field (or a tuple of floats)."""
    if not (dataclasses.is_dataclass(fr) and not isinstance(fr, type)):
        return False
    for f in dataclasses.fields(fr):
        v = getattr(fr, f.name)
        if isinstance(v, float):
            if v - v != 0.0:
                return True
        elif isinstance(v, tuple) and any(isinstance(x, float) and x - x != 0.0 for x in v):
            return True
    return False


def _capture_rows(path: Path, mon: Monitor, links: set[str] | None,
                  info: dict[str, Any] | None = None) -> Iterator[FrameRow]:
    """The frames of a capture (``links``: only these; an unknown one is an error, raised here at once).
    ``info`` receives the capture's header dict, whose time-stamp counters fill as the records are read."""
    header, recs = iter_capture(path)
    if info is not None:
        info["header"] = header
    known = [str(x) for x in header.get("links", [])]
    unknown = sorted((links or set()) - set(known))
    if unknown:
        close = getattr(recs, "close", None)
        if close is not None:
            close()
        raise EmulatorError(f"{path}: no link {', '.join(map(repr, unknown))} in this capture; its links: "
                            f"{', '.join(known)}")
    return _capture_iter(recs, mon, links)


def _capture_iter(recs: Iterator[Any], mon: Monitor, links: set[str] | None) -> Iterator[FrameRow]:
    for r in recs:
        if links is not None and r.link not in links:
            continue
        try:
            yield from mon.feed(r.t_s, r.link, r.direction, r.data)
        except EmulatorError:
            if links is not None:
                raise
            continue  # a link with no decoder (e.g. an unknown port) in an all-links listing


def _is_capture(endpoint: str) -> bool:
    p = Path(endpoint)
    if p.suffix == ".psnscap":
        return True
    try:
        with open(p, "rb") as f:
            return f.read(len(CAPTURE_MAGIC)) == CAPTURE_MAGIC
    except OSError:
        return False


#: bytes read at a time from a byte dump
_DUMP_CHUNK = 4096


def _is_byte_dump(endpoint: str) -> bool:
    """A regular file (not a device, a fifo or a pty): a dump of a port's bytes, read from start to end."""
    try:
        return Path(endpoint).is_file()
    except OSError:
        return False


def _dump_rows(path: str, port: str, mon: Monitor, baud: int) -> Iterator[FrameRow]:
    """The frames of a byte dump; ``t_s`` is the time of each chunk's first byte at ``baud`` (10 bits a byte)."""
    try:
        f = open(path, "rb")  # noqa: SIM115 (closed in the generator's finally)
    except OSError as exc:
        raise EmulatorError(f"cannot read {path}: {exc.strerror or exc}") from exc
    try:
        offset = 0
        while chunk := f.read(_DUMP_CHUNK):
            yield from mon.feed(offset * 10.0 / baud, port, "in", chunk)
            offset += len(chunk)
    except OSError as exc:
        raise EmulatorError(f"{path}: {exc.strerror or exc}") from exc
    finally:
        f.close()


#: largest ports.json read to name a run's pty (a run writes a few KB)
_PORTS_JSON_MAX = 1 << 20


def port_of_run_pty(endpoint: str) -> str | None:
    """The port name of a run's pty ``<run_dir>/ports/NAME`` from ``<run_dir>/ports.json`` (the link whose URL is
    ``pty://NAME``), or None when it is not one; a malformed or oversized ports.json is ignored."""
    p = Path(endpoint)
    pj = p.parent.parent / "ports.json"
    if p.parent.name != "ports" or not pj.is_file():
        return None
    try:
        with open(pj, "rb") as f:
            raw = f.read(_PORTS_JSON_MAX + 1)
        if len(raw) > _PORTS_JSON_MAX:
            return None
        entries = json.loads(raw)
    except (OSError, ValueError, RecursionError):
        return None
    if not isinstance(entries, list):
        return None
    for e in entries:
        if isinstance(e, dict) and isinstance(e.get("url"), str) and isinstance(e.get("name"), str) \
                and e["url"].split("?", 1)[0] == f"pty://{p.name}":
            return str(e["name"])
    return None


#: largest clock.json read (a run writes about 100 bytes)
_CLOCK_JSON_MAX = 4096


def run_clock_origin(endpoint: str) -> tuple[float, float] | None:
    """``(t0_monotonic_s, speed)`` of the realtime run whose pty ``<run_dir>/ports/NAME`` is ``endpoint``, from
    ``<run_dir>/clock.json`` (written by the run when its scenario clock starts): the scenario time of a byte read
    at ``time.monotonic() = m`` is ``(m - t0) * speed``. None when it is not a run's pty, the run has not started,
    it runs in fast mode (its clock is not the wall's), or the file is malformed or oversized."""
    p = Path(endpoint)
    if p.parent.name != "ports":
        return None
    try:
        with open(p.parent.parent / "clock.json", "rb") as f:
            raw = f.read(_CLOCK_JSON_MAX + 1)
        doc = json.loads(raw) if len(raw) <= _CLOCK_JSON_MAX else None
    except (OSError, ValueError, RecursionError):
        return None
    if not isinstance(doc, dict) or doc.get("mode") != "realtime":
        return None
    t0, speed = doc.get("t0_monotonic_s"), doc.get("speed")
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) for v in (t0, speed)) \
            or not speed > 0 or not 0 <= t0 <= time.monotonic():  # type: ignore[operator]
        return None
    return float(t0), float(speed)  # type: ignore[arg-type]


def _live_rows(device: str, port: str, mon: Monitor, baud: int, stop: Callable[[], bool]) -> Iterator[FrameRow]:
    import serial

    try:
        ser = serial.Serial(device, baud, timeout=0)
    except (serial.SerialException, OSError, ValueError) as exc:
        raise EmulatorError(f"cannot open {device}: {exc}") from exc
    t0 = time.monotonic()
    speed = 1.0
    origin = run_clock_origin(device)
    looked = t0
    try:
        fd = ser.fileno()
        while not stop():
            if origin is None and time.monotonic() - looked >= 0.2:  # the run may start after the monitor
                looked = time.monotonic()
                origin = run_clock_origin(device)
            if origin is not None:
                t0, speed = origin
            r, _w, _x = select.select([fd], [], [], 0.1)
            if not r:
                continue
            try:
                data = os.read(fd, 4096)
            except BlockingIOError:
                continue
            except OSError as exc:
                raise EmulatorError(f"{device}: {exc} (the other end went away?)") from exc
            if not data:
                raise EmulatorError(f"{device}: end of file (the other end went away)")
            yield from mon.feed((time.monotonic() - t0) * speed, port, "in", data)
    finally:
        ser.close()


#: URL options of ``zenoh://`` that choose the monitor's zenoh session (the other link options do not apply)
_ZENOH_SESSION_OPTIONS = ("listen", "connect", "session", "config", "auth")


def _zenoh_source(endpoint: str) -> tuple[ZenohEndpointConfig, str, str]:
    """``(session configuration, port name, key prefix psns/RUN/PORT)`` of a ``zenoh://RUN/PORT`` endpoint."""
    url = parse_link_url(endpoint)
    extra = sorted(set(url.options) - set(_ZENOH_SESSION_OPTIONS) - {"baud", "mode", "queue"})
    if extra:
        raise EmulatorError(f"{endpoint}: option(s) {', '.join(extra)} do not apply to monitor; it takes "
                            f"{', '.join(_ZENOH_SESSION_OPTIONS)}")
    _run, port, prefix = zenoh_key_prefix(url.target)

    def eps(name: str) -> tuple[str, ...]:
        v = url.options.get(name)
        return tuple(e.strip() for e in v.split(",") if e.strip()) if v else ()

    listen, connect, config = eps("listen"), eps("connect"), url.options.get("config")
    if not listen and not connect and config is None:
        connect = (DEFAULT_LISTEN,)  # where an emulator's zenoh port listens by default
    return (ZenohEndpointConfig(listen, connect, url.options.get("session", "peer"), config, url.options.get("auth")),
            port, prefix)


def _zenoh_rows(cfg: ZenohEndpointConfig, port: str, prefix: str, mon: Monitor,
                stop: Callable[[], bool]) -> Iterator[FrameRow]:
    """Decode what is published on ``prefix/tx`` (``out``) and ``prefix/rx`` (``in``) until ``stop()``.

    zenoh calls the subscribers on its own threads; they only queue the payload, decoding happens here.
    """
    arrived: queue.SimpleQueue[tuple[float, str, bytes]] = queue.SimpleQueue()
    t0 = time.monotonic()

    def subscriber(direction: str) -> Callable[[Any], None]:
        def on_sample(sample: Any) -> None:
            arrived.put((time.monotonic() - t0, direction, sample.payload.to_bytes()))
        return on_sample

    session = acquire_session(cfg)
    subs: list[Any] = []
    try:
        for suffix, direction in (("tx", "out"), ("rx", "in")):
            subs.append(session.declare_subscriber(f"{prefix}/{suffix}", subscriber(direction)))
        while not stop():
            try:
                t, direction, data = arrived.get(timeout=0.1)
            except queue.Empty:
                continue
            yield from mon.feed(t, port, direction, data)
    finally:
        for sub in subs:
            with contextlib.suppress(Exception):  # undeclared already with a closed session
                sub.undeclare()
        release_session(cfg)


def run_monitor(endpoint: str, protocol: str = "auto", baud: int = 460800, links: list[str] | None = None,
                count: int | None = None, duration_s: float | None = None, as_json: bool = False,
                out: TextIO | None = None, port_name: str | None = None) -> dict[str, Any]:
    """Decode ``endpoint`` and print one line (or JSON object) per frame; returns the statistics."""
    out = out or sys.stdout
    if protocol != "auto":
        formats_for(None, protocol)  # an unknown name is an error (exit 2) listing the known ones
    mon = Monitor(protocol)
    if endpoint.startswith("serial://"):
        endpoint = parse_link_url(endpoint).target
    t_start = time.monotonic()

    def stop() -> bool:
        return duration_s is not None and time.monotonic() - t_start >= duration_s

    rows: Iterator[FrameRow]
    capture_info: dict[str, Any] = {}
    if endpoint.startswith("zenoh://"):
        cfg, key_port, prefix = _zenoh_source(endpoint)
        name = port_name or key_port
        if protocol == "auto":
            formats_for(name, "auto")  # fail early with the hint
        rows = _zenoh_rows(cfg, name, prefix, mon, stop)
    elif _is_capture(endpoint):
        rows = _capture_rows(Path(endpoint), mon, set(links) if links else None, capture_info)
    elif _is_byte_dump(endpoint):
        name = port_name or Path(endpoint).stem
        if protocol == "auto":
            formats_for(name, "auto")  # fail early with the hint
        rows = _dump_rows(endpoint, name, mon, baud)
    elif os.path.exists(endpoint):
        name = port_name or port_of_run_pty(endpoint) or Path(endpoint).name
        if protocol == "auto":
            formats_for(name, "auto")  # fail early with the hint
        rows = _live_rows(endpoint, name, mon, baud, stop)
    else:
        raise EmulatorError(f"{endpoint}: no such file or device")
    n = 0
    if not as_json:
        print(f"{'t_s':>12}  {'port':<8} {'dir':<3}  {'frame':<18} fields", file=out)
    try:
        for row in rows:
            print(row.as_json() if as_json else row.text(), file=out, flush=True)
            n += 1
            if count is not None and n >= count:
                break
    except KeyboardInterrupt:
        pass
    finally:
        close = getattr(rows, "close", None)
        if close is not None:
            close()
    out_stats: dict[str, Any] = {"frames": n, "decoders": mon.stats()}
    if "header" in capture_info:  # a capture: its damaged time stamps are reported, never silently used
        h = capture_info["header"]
        out_stats["capture"] = {k: h.get(k, 0) for k in ("bad_time_records", "backward_time_records")}
        out_stats["capture"]["truncated_record"] = bool(h.get("truncated_record"))
    return out_stats
