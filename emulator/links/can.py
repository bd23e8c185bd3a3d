"""``can://virtual/CH`` and ``can://socketcan/IF``: the navigation solution on a CAN bus, per the DBC.

The CAN endpoint is an output sink for the host port: the bytes the box sends out of its HOST
port (the DSP's UART0 through the FPGA) are decoded with the one streaming decoder
(:class:`protocols.host.HostFormat`), and every NAV_SOLUTION frame becomes the CAN frames of the
messages that are due, in identifier order. Nothing is received from the bus: a CAN host port
carries no commands (the box's commands arrive on RS422).

Messages and rates: by default those of ``protocols/psns_nav.dbc`` (:mod:`protocols.can_nav`,
CAN 2.0B, 29-bit ids, D-3.4): TIME, POSITION, HEIGHT_MODE, VELOCITY and ATTITUDE every 10 ms,
the three SIGMA frames and DSP health every 100 ms, encoded by the protocols layer's struct codec
(cantools decodes them identically; no cantools in the per-frame path). A message is due when its
cycle time has passed in *navigation* time (``time_s`` of the solutions), so the output is
reproducible and follows the navigation rate (a 50 Hz solution sends the 10 ms messages at 50 Hz).
``rate=HZ`` caps the whole set further.

Buses (python-can 4.x, ``docs/reference/wire-formats.md`` section 3):

``can://virtual/CH``
    python-can's in-process ``virtual`` interface, channel ``CH`` (what the tests and CI use).
``can://socketcan/IF``
    Linux SocketCAN interface ``IF`` (``can0``, ``vcan0``); needs the kernel's CAN support.

URL options: ``dbc=FILE`` (another DBC: encoded with cantools, every signal filled by name from
:func:`nav_signal_values`, cycle times from its ``GenMsgCycleTime``; a signal with no source is an
error at open), ``rate=HZ``, ``bitrate=N`` (passed to the interface), ``fd=0|1`` (CAN FD frames),
plus the common ``baud``/``mode``/``queue`` of the host line that feeds the decoder.
python-can and cantools exceptions are mapped to :class:`~emulator.errors.LinkError` subclasses.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
from pathlib import Path
from typing import Any

from protocols.can_nav import CAN_MESSAGES, encode_can_frames
from protocols.host import HostFormat, NavSolution
from protocols.stream import StreamDecoder

from ..errors import LinkBrokenError, LinkConfigError
from .base import Link
from .line import LineConfig

__all__ = [
    "CAN_OPTIONS",
    "CanLink",
    "DbcNavCanEncoder",
    "DefaultNavCanEncoder",
    "NavCanEncoder",
    "default_dbc_path",
    "nav_signal_values",
]

CAN_OPTIONS = frozenset({"dbc", "rate", "bitrate", "fd"})
_USAGE = "can://virtual/CHANNEL or can://socketcan/IFACE[?dbc=FILE&rate=HZ&bitrate=N&fd=0|1]"
_INTERFACES = ("virtual", "socketcan")
#: tolerance when comparing navigation times against a cycle (s)
_CYCLE_EPS = 1e-6


def default_dbc_path() -> Path:
    """``protocols/psns_nav.dbc`` as installed with the package."""
    import protocols

    return Path(protocols.__file__).with_name("psns_nav.dbc")


def nav_signal_values(n: NavSolution) -> dict[str, float]:
    """NavSolution as flat signal values, named as the signals of ``protocols/psns_nav.dbc``."""
    s = n.sigma
    return {
        "seq": n.seq, "seq8": n.seq & 0xFF, "time_s": n.time_s, "lat_deg": n.lat_deg, "lon_deg": n.lon_deg,
        "height_m": n.height_m, "vel_e_mps": n.vel_enu_mps[0], "vel_n_mps": n.vel_enu_mps[1],
        "vel_u_mps": n.vel_enu_mps[2], "roll_deg": n.roll_deg, "pitch_deg": n.pitch_deg,
        "heading_deg": n.heading_deg % 360.0,
        "sigma_att_e_deg": s[0], "sigma_att_n_deg": s[1], "sigma_att_u_deg": s[2],
        "sigma_vel_e_mps": s[3], "sigma_vel_n_mps": s[4], "sigma_vel_u_mps": s[5],
        "sigma_pos_n_m": s[6], "sigma_pos_e_m": s[7], "sigma_pos_u_m": s[8],
        "mode": n.mode, "gnss_status": n.gnss_status, "psns_status": n.psns_status,
        "cpu_load_pct": n.cpu_load_pct, "deadline_misses": n.deadline_misses,
    }


class NavCanEncoder:
    """Which messages are due for a solution and their frames: ``frames(n) -> [(id, extended, data)]``."""

    #: (name, cycle s or 0 for every solution) per message, in identifier order
    schedule: list[tuple[str, float]]

    def __init__(self) -> None:
        self._last: dict[str, float] = {}

    def due(self, n: NavSolution) -> list[str]:
        out = []
        for name, cycle in self.schedule:
            last = self._last.get(name)
            if last is None or cycle <= 0 or n.time_s - last >= cycle - _CYCLE_EPS or n.time_s < last:
                self._last[name] = n.time_s
                out.append(name)
        return out

    def frames(self, n: NavSolution) -> list[tuple[int, bool, bytes]]:
        raise NotImplementedError


class DefaultNavCanEncoder(NavCanEncoder):
    """``protocols/psns_nav.dbc`` through :func:`protocols.can_nav.encode_can_frames` (29-bit ids)."""

    def __init__(self) -> None:
        super().__init__()
        self.path = default_dbc_path()
        self.schedule = [(m.name, m.cycle_ms / 1000.0) for m in sorted(CAN_MESSAGES, key=lambda m: m.frame_id)]

    def frames(self, n: NavSolution) -> list[tuple[int, bool, bytes]]:
        names = self.due(n)
        if not names:
            return []
        return [(fid, True, data) for fid, data in encode_can_frames(n, names)]


class _SignalPlan:
    __slots__ = ("hi", "lo", "name", "wrap")

    def __init__(self, sig: Any) -> None:
        self.name = sig.name
        bits = sig.length
        if sig.is_float:
            raw_lo, raw_hi = float("-inf"), float("inf")
        elif sig.is_signed:
            raw_lo, raw_hi = -(1 << (bits - 1)), (1 << (bits - 1)) - 1
        else:
            raw_lo, raw_hi = 0, (1 << bits) - 1
        scale, offset = float(sig.scale), float(sig.offset)
        a, b = offset + scale * raw_lo, offset + scale * raw_hi
        lo, hi = min(a, b), max(a, b)
        if sig.minimum is not None:
            lo = max(lo, float(sig.minimum))
        if sig.maximum is not None:
            hi = min(hi, float(sig.maximum))
        self.lo, self.hi = lo, hi
        self.wrap = (1 << bits) if (not sig.is_float and not sig.is_signed and scale == 1 and offset == 0) else 0

    def value(self, v: float) -> float:
        if isinstance(v, float) and not math.isfinite(v):
            v = 0.0
        if self.wrap:
            return int(v) % self.wrap
        return self.hi if v > self.hi else self.lo if v < self.lo else v


class DbcNavCanEncoder(NavCanEncoder):
    """Any DBC through cantools: signals filled by name from :func:`nav_signal_values` (see module docstring).

    Values beyond a signal's range saturate; unsigned unscaled integers (counters, bit fields) wrap.
    """

    def __init__(self, dbc_path: str | Path) -> None:
        super().__init__()
        import cantools

        self.path = Path(dbc_path)
        try:
            db = cantools.database.load_file(str(dbc_path))
        except FileNotFoundError as exc:
            raise LinkConfigError(f"DBC file {dbc_path} not found; give can://...?dbc=FILE") from exc
        except Exception as exc:
            raise LinkConfigError(f"DBC file {dbc_path} could not be parsed: {exc}") from exc
        if not isinstance(db, cantools.database.can.Database):
            raise LinkConfigError(f"DBC file {dbc_path} is not a CAN database ({type(db).__name__})")
        self.db = db
        known = set(nav_signal_values(_ZERO_NAV))
        plans: dict[str, tuple[Any, list[_SignalPlan]]] = {}
        missing = []
        for m in sorted(self.db.messages, key=lambda m: m.frame_id):
            sigs = [_SignalPlan(s) for s in m.signals]
            missing += [f"{m.name}.{s.name}" for s in sigs if s.name not in known]
            plans[m.name] = (m, sigs)
        if missing:
            raise LinkConfigError(f"DBC {dbc_path}: signals with no NavSolution source: {', '.join(missing)}; "
                                  f"known: {', '.join(sorted(known))}")
        if not plans:
            raise LinkConfigError(f"DBC {dbc_path} defines no messages")
        self.plans = plans
        self.schedule = [(name, (m.cycle_time or 0) / 1000.0) for name, (m, _s) in plans.items()]

    def frames(self, n: NavSolution) -> list[tuple[int, bool, bytes]]:
        names = self.due(n)
        if not names:
            return []
        vals = nav_signal_values(n)
        out = []
        for name in names:
            m, sigs = self.plans[name]
            data = {s.name: s.value(vals[s.name]) for s in sigs}
            out.append((m.frame_id, bool(m.is_extended_frame), m.encode(data, scaling=True, strict=False)))
        return out


_ZERO_NAV = NavSolution(0, 0.0, 0.0, 0.0, 0.0, (0.0, 0.0, 0.0), 0.0, 0.0, 0.0, (0.0,) * 9, 0, 0, 0, 0.0, 0)


class CanLink(Link):
    """Navigation output on CAN (see module docstring)."""

    scheme = "can"
    url_usage = _USAGE
    url_options = frozenset({"dbc", "rate", "bitrate", "fd"})
    paces_input = False

    @classmethod
    def check_target(cls, url: str, target: str) -> None:
        iface, _sep, channel = target.partition("/")
        if iface not in _INTERFACES or not channel:
            raise LinkConfigError(f"{url!r}: expected {_USAGE}")

    def __init__(self, name: str, url: str, line: LineConfig, loop: asyncio.AbstractEventLoop,
                 target: str = "", options: dict[str, str] | None = None, **_: Any) -> None:
        super().__init__(name, url, line, loop)
        opts = options or {}
        self.check_target(url, target)
        iface, _sep, channel = target.partition("/")
        self.interface, self.channel = iface, channel
        self.dbc_path = Path(opts["dbc"]) if "dbc" in opts else None
        try:
            self.min_interval_s = 1.0 / float(opts["rate"]) if "rate" in opts else 0.0
            self.bitrate = int(opts["bitrate"]) if "bitrate" in opts else None
        except (ValueError, ZeroDivisionError) as exc:
            raise LinkConfigError(f"{url!r}: {exc}; expected {_USAGE}") from exc
        if self.min_interval_s < 0:
            raise LinkConfigError(f"{url!r}: rate must be > 0; expected {_USAGE}")
        self.fd = opts.get("fd", "0") in ("1", "true", "yes")
        self.encoder: NavCanEncoder | None = None
        self.bus: Any = None
        self._decoder = StreamDecoder([HostFormat()])
        self._last_sent_t: float | None = None
        self.nav_frames = 0
        self.can_frames_sent = 0
        self.can_send_errors = 0
        self.last_error: str | None = None

    async def open(self) -> None:
        self.encoder = DbcNavCanEncoder(self.dbc_path) if self.dbc_path is not None else DefaultNavCanEncoder()
        import can

        kw: dict[str, Any] = {"interface": self.interface, "channel": self.channel}
        if self.bitrate is not None:
            kw["bitrate"] = self.bitrate
        if self.fd:
            kw["fd"] = True
        try:
            self.bus = can.Bus(**kw)
        except (can.CanError, OSError, ValueError) as exc:
            raise LinkBrokenError(f"{self.name}: cannot open CAN bus {self.interface}/{self.channel}: {exc}") from exc

    def _write_raw(self, data: bytes) -> None:
        for fr in self._decoder.feed(data):
            if isinstance(fr, NavSolution):
                self._send_nav(fr)

    def _send_nav(self, n: NavSolution) -> None:
        self.nav_frames += 1
        if self.min_interval_s and self._last_sent_t is not None \
                and n.time_s - self._last_sent_t < self.min_interval_s - 1e-6:
            return
        self._last_sent_t = n.time_s
        bus, enc = self.bus, self.encoder
        if bus is None or enc is None:
            return
        import can

        for frame_id, ext, payload in enc.frames(n):
            msg = can.Message(arbitration_id=frame_id, is_extended_id=ext, data=payload, is_fd=self.fd,
                              timestamp=self.loop.time())
            try:
                bus.send(msg, timeout=0)
                self.can_frames_sent += 1
            except can.CanError as exc:  # a full TX buffer on a real bus: count it, keep going
                self.can_send_errors += 1
                self.stats.dropped_out += len(payload)
                self.last_error = str(exc)

    @property
    def decoder_stats(self) -> dict[str, Any]:
        return self._decoder.stats.as_dict()

    async def close(self) -> None:
        await super().close()
        bus, self.bus = self.bus, None
        if bus is not None:
            with contextlib.suppress(Exception):
                bus.shutdown()

    def describe(self) -> str:
        dbc = self.dbc_path.name if self.dbc_path is not None else "psns_nav.dbc"
        return f"CAN {self.interface}/{self.channel} (DBC {dbc})"
