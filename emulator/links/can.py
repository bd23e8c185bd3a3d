"""``can://virtual/CH`` and ``can://socketcan/IF``: the navigation solution on a CAN bus, per the DBC.

The CAN endpoint is an output sink for the host port: the bytes the box sends out of its HOST
port (the DSP's UART0 through the FPGA) are decoded with the one streaming decoder
(:class:`protocols.host.HostFormat`), and every NAV_SOLUTION frame becomes one CAN frame per
message of the DBC, sent at the navigation rate (or decimated to ``rate`` Hz of navigation time).
Nothing is received from the bus: a CAN host port carries no commands (the box's commands
arrive on RS422).

Buses (python-can 4.x, ``shared/reference/protocols.md`` section 3):

``can://virtual/CH``
    python-can's in-process ``virtual`` interface, channel ``CH`` (what the tests and CI use).
``can://socketcan/IF``
    Linux SocketCAN interface ``IF`` (``can0``, ``vcan0``); needs the kernel's CAN support.

URL options: ``dbc=FILE`` (default: ``protocols/psns_nav.dbc`` shipped with the package),
``rate=HZ`` (decimate; default every frame), ``bitrate=N`` (passed to the interface),
``fd=0|1`` (CAN FD frames), plus the common ``baud``/``mode``/``queue`` of the host line
that feeds the decoder.

Signals are filled by name from :func:`nav_signal_values` (the NavSolution fields, velocity and
sigma split per axis: ``vel_e_mps`` ... ``sig_pos_u_m``). A DBC signal with no such source is an
error at open, naming it. Values are saturated to what the signal can carry, except unsigned
unscaled integers (sequence counters, bit fields), which wrap modulo their width as a rolling
counter does. python-can and cantools exceptions are mapped to :class:`~emulator.errors.LinkError`
subclasses at this boundary.
"""

from __future__ import annotations

import asyncio
from pathlib import Path
from typing import Any

from protocols.host import HostFormat, NavSolution
from protocols.stream import StreamDecoder

from ..errors import LinkBrokenError, LinkConfigError
from .base import LineConfig, Link

__all__ = ["CanLink", "CAN_OPTIONS", "default_dbc_path", "nav_signal_values", "NavCanEncoder"]

CAN_OPTIONS = frozenset({"dbc", "rate", "bitrate", "fd"})
_USAGE = "can://virtual/CHANNEL or can://socketcan/IFACE[?dbc=FILE&rate=HZ&bitrate=N&fd=0|1]"
_INTERFACES = ("virtual", "socketcan")


def default_dbc_path() -> Path:
    """``protocols/psns_nav.dbc`` as installed with the package."""
    import protocols

    return Path(protocols.__file__).with_name("psns_nav.dbc")


def nav_signal_values(n: NavSolution) -> dict[str, float]:
    """NavSolution as flat signal values (names as in ``nav.csv``; units of :mod:`protocols.host`)."""
    s = n.sigma
    return {
        "seq": n.seq, "time_s": n.time_s, "lat_deg": n.lat_deg, "lon_deg": n.lon_deg, "height_m": n.height_m,
        "vel_e_mps": n.vel_enu_mps[0], "vel_n_mps": n.vel_enu_mps[1], "vel_u_mps": n.vel_enu_mps[2],
        "roll_deg": n.roll_deg, "pitch_deg": n.pitch_deg, "heading_deg": n.heading_deg,
        "sig_att_e_deg": s[0], "sig_att_n_deg": s[1], "sig_att_u_deg": s[2],
        "sig_vel_e_mps": s[3], "sig_vel_n_mps": s[4], "sig_vel_u_mps": s[5],
        "sig_pos_n_m": s[6], "sig_pos_e_m": s[7], "sig_pos_u_m": s[8],
        "mode": n.mode, "gnss_status": n.gnss_status, "psns_status": n.psns_status,
        "cpu_load_pct": n.cpu_load_pct, "deadline_misses": n.deadline_misses,
    }


class _SignalPlan:
    __slots__ = ("name", "lo", "hi", "wrap")

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
        if self.wrap:
            return int(v) % self.wrap
        return self.hi if v > self.hi else self.lo if v < self.lo else v


class NavCanEncoder:
    """DBC messages for one NavSolution: ``encode(n) -> [(frame_id, is_extended, data), ...]``.

    Parameters
    ----------
    dbc_path:
        The DBC file. Every signal of every message must have a source in :func:`nav_signal_values`.
    """

    def __init__(self, dbc_path: str | Path) -> None:
        import cantools

        try:
            self.db = cantools.database.load_file(str(dbc_path))
        except FileNotFoundError as exc:
            raise LinkConfigError(f"DBC file {dbc_path} not found; give can://...?dbc=FILE") from exc
        except Exception as exc:  # noqa: BLE001 - cantools raises ParseError and friends
            raise LinkConfigError(f"DBC file {dbc_path} could not be parsed: {exc}") from exc
        known = set(nav_signal_values(_ZERO_NAV))
        plans = []
        missing = []
        for m in self.db.messages:
            sigs = [_SignalPlan(s) for s in m.signals]
            missing += [f"{m.name}.{s.name}" for s in sigs if s.name not in known]
            plans.append((m, sigs))
        if missing:
            raise LinkConfigError(f"DBC {dbc_path}: signals with no NavSolution source: {', '.join(missing)}; "
                                  f"known: {', '.join(sorted(known))}")
        if not plans:
            raise LinkConfigError(f"DBC {dbc_path} defines no messages")
        self.plans = plans

    def encode(self, n: NavSolution) -> list[tuple[int, bool, bytes]]:
        vals = nav_signal_values(n)
        out = []
        for m, sigs in self.plans:
            data = {s.name: s.value(vals[s.name]) for s in sigs}
            out.append((m.frame_id, bool(m.is_extended_frame), m.encode(data, scaling=True, strict=False)))
        return out


_ZERO_NAV = NavSolution(0, 0.0, 0.0, 0.0, 0.0, (0.0, 0.0, 0.0), 0.0, 0.0, 0.0, (0.0,) * 9, 0, 0, 0, 0.0, 0)


class CanLink(Link):
    """Navigation output on CAN (see module docstring)."""

    scheme = "can"
    paces_input = False

    def __init__(self, name: str, url: str, line: LineConfig, loop: asyncio.AbstractEventLoop,
                 target: str = "", **_: Any) -> None:
        super().__init__(name, url, line, loop)
        from . import parse_link_url

        opts = parse_link_url(url).options
        iface, _, channel = target.partition("/")
        if iface not in _INTERFACES or not channel:
            raise LinkConfigError(f"{url!r}: expected {_USAGE}")
        self.interface, self.channel = iface, channel
        self.dbc_path = Path(opts["dbc"]) if "dbc" in opts else default_dbc_path()
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
        self.encoder = NavCanEncoder(self.dbc_path)
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

        for frame_id, ext, payload in enc.encode(n):
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
            try:
                bus.shutdown()
            except Exception:  # noqa: BLE001 - shutting down must not mask the run's result
                pass

    def describe(self) -> str:
        return f"CAN {self.interface}/{self.channel} (DBC {self.dbc_path.name})"
