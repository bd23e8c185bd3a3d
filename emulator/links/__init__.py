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

More schemes come from packages installed next to psns-hil, through the ``psns_hil.links`` entry points
(:mod:`emulator.plugins`, docs/plugins.md): the entry point's name is the scheme, its value a
:class:`~emulator.links.base.Link` subclass taking ``(name, url, line, loop, target=, options=, run_dir=)``,
which may declare ``url_options`` (a frozenset of the query options it accepts beyond the common ones) and
``url_usage`` (the accepted form, shown in errors). They join :func:`link_schemes` at first use; a built-in
scheme is never replaced.
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
    "link_schemes",
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


def link_schemes() -> dict[str, str]:
    """Scheme -> ``module:Class``: the built-in transports and the ``psns_hil.links`` entry points."""
    from ..plugins import PLUGIN_ERRORS, entry_points_of

    out = dict(LINK_SCHEMES)
    for ep in entry_points_of("psns_hil.links"):
        if ep.name in LINK_SCHEMES:
            PLUGIN_ERRORS.setdefault(("psns_hil.links", ep.name), f"{ep.value}: the scheme {ep.name!r} is built in; "
                                     "not replaced")
            continue
        out[ep.name] = ep.value
    return out


def _plugin_class(scheme: str) -> type[Link] | None:
    """The transport class of a plugin scheme (imported at first use), None for a built-in one."""
    if scheme in LINK_SCHEMES:
        return None
    from ..plugins import PLUGIN_ERRORS, plugin

    cls = plugin("psns_hil.links", scheme)
    if cls is None:
        why = PLUGIN_ERRORS.get(("psns_hil.links", scheme), "no such entry point")
        raise LinkConfigError(f"the {scheme}:// transport (a psns_hil.links plugin) could not be loaded: {why}")
    if not (isinstance(cls, type) and issubclass(cls, Link)):
        raise LinkConfigError(f"the {scheme}:// transport (a psns_hil.links plugin) is not a Link subclass: {cls!r}")
    return cls


def _usage(scheme: str) -> str:
    """The URL syntax the transport of ``scheme`` declares (:attr:`Link.url_usage`; a class entered under another
    scheme than its own, e.g. by a plugin, does not speak for it)."""
    cls = _transport_class(scheme)
    usage = str(getattr(cls, "url_usage", "") or "")
    return usage if usage and getattr(cls, "scheme", "") in ("", scheme) else scheme + "://..."


def _options(scheme: str) -> frozenset[str]:
    """The query options the transport of ``scheme`` accepts beyond the common ones (:attr:`Link.url_options`)."""
    return frozenset(getattr(_transport_class(scheme), "url_options", frozenset()))


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
            usage = _usage(self.scheme)
            raise LinkConfigError(f"{self.url}: {exc}; expected {usage}") from exc


def parse_link_url(url: str, extra_options: frozenset[str] = frozenset()) -> LinkUrl:
    """Split and validate a link URL: the one parser of every scheme. The scheme must be known, the options those
    common to every link or declared by the transport (:attr:`Link.url_options`), and the target one the transport
    accepts (:meth:`Link.check_target`); every error shows the transport's :attr:`Link.url_usage`. The transport's
    module is imported to read these (transport modules import their I/O libraries only when a link opens)."""
    parts = urlsplit(url)
    scheme = parts.scheme
    schemes = LINK_SCHEMES if scheme in LINK_SCHEMES else link_schemes()
    if scheme not in schemes:
        import difflib

        close = difflib.get_close_matches(scheme, list(schemes), n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise LinkConfigError(
            f"unknown link scheme {scheme!r} in {url!r}{hint}; known schemes: {', '.join(sorted(schemes))}"
        )
    target = parts.netloc + parts.path if scheme != "serial" else parts.path or parts.netloc
    if not target:
        raise LinkConfigError(f"{url!r} names no target; expected {_usage(scheme)}")
    options = dict(parse_qsl(parts.query, keep_blank_values=True))
    unknown = set(options) - _COMMON_OPTIONS - extra_options - _options(scheme)
    if unknown:
        raise LinkConfigError(
            f"{url!r}: unknown option(s) {', '.join(sorted(unknown))}; expected {_usage(scheme)}"
        )
    check = getattr(_transport_class(scheme), "check_target", None)
    if callable(check):
        check(url, target)
    return LinkUrl(url, scheme, target, options)


def _transport_class(scheme: str) -> type[Link]:
    plugin_cls = _plugin_class(scheme)
    if plugin_cls is not None:
        return plugin_cls
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
    url: str | LinkUrl,
    name: str,
    loop: asyncio.AbstractEventLoop,
    default_line: LineConfig = DEFAULT_LINE,
    hub: MemHub | None = None,
    **transport_kw: Any,
) -> Link:
    """Create (not yet open) the link for port ``name`` at ``url``.

    ``url``: the URL's text, or the :class:`LinkUrl` it was parsed into (a resolved scenario's port,
    :mod:`emulator.scenario.resolved`: parsed once, not again here). ``hub`` pairs ``mem://`` ends;
    ``transport_kw`` goes to the transport (e.g. ``run_dir`` for ptys).
    """
    u = url if isinstance(url, LinkUrl) else parse_link_url(url)
    url = u.url
    line = u.line_config(default_line)
    cls = _transport_class(u.scheme)
    if u.scheme == "mem":
        link = MemLink(name, url, line, loop)
        if hub is None:
            raise LinkConfigError(f"{url}: mem:// links need a MemHub to find their peer")
        hub.attach(u.target, link)
        return link
    return cls(name, url, line, loop, target=u.target, options=u.options, **transport_kw)  # type: ignore[call-arg]
