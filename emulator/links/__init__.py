"""Links addressed by URL, one transport module per scheme, imported lazily.

=============================================  =================================================
URL                                            transport
=============================================  =================================================
``mem://NAME``                                 in-process pair (:mod:`emulator.links.mem`)
``pty://NAME``                                 pseudo-terminal with a stable symlink
                                               ``<run_dir>/NAME`` (:mod:`emulator.links.pty`)
``serial:///dev/ttyUSB0``                      a real serial device (:mod:`emulator.links.serial`)
``zenoh://RUN/PORT``                           bytes over zenoh, another process or host
                                               (:mod:`emulator.links.zenoh`)
``can://virtual/CH``, ``can://socketcan/IF``   navigation solution out on CAN per the DBC
                                               (:mod:`emulator.links.can`)
=============================================  =================================================

Common options (query string): ``baud=N``, ``mode=8N1``, ``queue=BYTES`` (TX queue size).
``pty://`` also takes ``peer_baud=ignore|check`` (model a client set to another baud).
Unknown options are errors that show the accepted form. "Unknown scheme" and "the transport
module failed to import" are different errors, and the import failure keeps its cause.
"""

from __future__ import annotations

import asyncio
import importlib
from typing import Any
from urllib.parse import parse_qsl, urlsplit

from ..errors import LinkConfigError
from .base import ByteFault, Link, LinkListener, LinkStats
from .line import LineConfig, LineModel, parse_mode
from .mem import MemHub, MemLink

__all__ = [
    "LINK_SCHEMES",
    "ByteFault",
    "LineConfig",
    "LineModel",
    "Link",
    "LinkListener",
    "LinkStats",
    "LinkUrl",
    "MemHub",
    "MemLink",
    "open_link",
    "parse_link_url",
    "parse_mode",
]

#: scheme -> "module:Class"
LINK_SCHEMES: dict[str, str] = {
    "mem": "emulator.links.mem:MemLink",
    "pty": "emulator.links.pty:PtyLink",
    "serial": "emulator.links.serial:SerialLink",
    "zenoh": "emulator.links.zenoh:ZenohLink",
    "can": "emulator.links.can:CanLink",
}

_COMMON_OPTIONS = {"baud", "mode", "queue"}
#: options a scheme accepts beyond the common ones (kept here so that validation needs no import)
_SCHEME_OPTIONS: dict[str, frozenset[str]] = {
    "pty": frozenset({"peer_baud"}),
    "serial": frozenset({"pps"}),
    "zenoh": frozenset({"role", "listen", "connect", "session", "config", "pace", "nav"}),
    "can": frozenset({"dbc", "rate", "bitrate", "fd"}),
}
_USAGE = {
    "mem": "mem://NAME[?baud=N&mode=8N1&queue=BYTES]",
    "pty": "pty://NAME[?baud=N&mode=8N1&queue=BYTES&peer_baud=ignore|check]",
    "serial": "serial:///dev/ttyXXX[?baud=N&mode=8N1&queue=BYTES&pps=dcd|cts]",
    "zenoh": "zenoh://RUN/PORT[?role=device|peer&listen=tcp/127.0.0.1:7447&connect=tcp/HOST:PORT"
             "&session=peer|client&config=FILE&pace=1|0&nav=tx|rx|off&baud=N&mode=8N1&queue=BYTES]",
    "can": "can://virtual/CHANNEL or can://socketcan/IFACE[?dbc=FILE&rate=HZ&bitrate=N&fd=0|1]",
}


class LinkUrl:
    """A parsed link URL: scheme, target (name or device path) and options."""

    __slots__ = ("options", "scheme", "target", "url")

    def __init__(self, url: str, scheme: str, target: str, options: dict[str, str]) -> None:
        self.url = url
        self.scheme = scheme
        self.target = target
        self.options = options

    def line_config(self, default: LineConfig) -> LineConfig:
        """The line parameters, the URL's options overriding ``default``."""
        kw: dict[str, Any] = {
            "baud": default.baud,
            "data_bits": default.data_bits,
            "parity": default.parity,
            "stop_bits": default.stop_bits,
            "tx_queue_bytes": default.tx_queue_bytes,
        }
        try:
            if "baud" in self.options:
                kw["baud"] = int(self.options["baud"])
            if "mode" in self.options:
                kw["data_bits"], kw["parity"], kw["stop_bits"] = parse_mode(self.options["mode"])
            if "queue" in self.options:
                kw["tx_queue_bytes"] = int(self.options["queue"])
            return LineConfig(**kw)
        except ValueError as exc:
            usage = _USAGE.get(self.scheme, self.scheme + "://...")
            raise LinkConfigError(f"{self.url}: {exc}; expected {usage}") from exc


def parse_link_url(url: str, extra_options: frozenset[str] = frozenset()) -> LinkUrl:
    """Split and validate a link URL (scheme known, options known)."""
    parts = urlsplit(url)
    scheme = parts.scheme
    if scheme not in LINK_SCHEMES:
        raise LinkConfigError(
            f"unknown link scheme {scheme!r} in {url!r}; known schemes: {', '.join(sorted(LINK_SCHEMES))}"
        )
    target = parts.netloc + parts.path if scheme != "serial" else parts.path or parts.netloc
    if not target:
        raise LinkConfigError(f"{url!r} names no target; expected {_USAGE.get(scheme, scheme + '://NAME')}")
    options = dict(parse_qsl(parts.query, keep_blank_values=True))
    unknown = set(options) - _COMMON_OPTIONS - extra_options - _SCHEME_OPTIONS.get(scheme, frozenset())
    if unknown:
        raise LinkConfigError(
            f"{url!r}: unknown option(s) {', '.join(sorted(unknown))}; expected {_USAGE.get(scheme, scheme + '://...')}"
        )
    return LinkUrl(url, scheme, target, options)


def _transport_class(scheme: str) -> type[Link]:
    target = LINK_SCHEMES[scheme]
    mod_name, cls_name = target.split(":")
    try:
        mod = importlib.import_module(mod_name)
    except ImportError as exc:
        raise LinkConfigError(f"the {scheme}:// transport could not be loaded: {exc}") from exc
    return getattr(mod, cls_name)


#: The line of a link whose scenario entry gives none: 8N1 at the LineConfig defaults (immutable, so shared).
DEFAULT_LINE = LineConfig()


def open_link(
    url: str,
    name: str,
    loop: asyncio.AbstractEventLoop,
    default_line: LineConfig = DEFAULT_LINE,
    hub: MemHub | None = None,
    **transport_kw: Any,
) -> Link:
    """Create (not yet open) the link for port ``name`` at ``url``.

    ``hub`` pairs ``mem://`` ends; ``transport_kw`` goes to the transport (e.g. ``run_dir``
    for ptys).
    """
    u = parse_link_url(url)
    line = u.line_config(default_line)
    cls = _transport_class(u.scheme)
    if u.scheme == "mem":
        link = MemLink(name, url, line, loop)
        if hub is None:
            raise LinkConfigError(f"{url}: mem:// links need a MemHub to find their peer")
        hub.attach(u.target, link)
        return link
    return cls(name, url, line, loop, target=u.target, options=u.options, **transport_kw)  # type: ignore[call-arg]
