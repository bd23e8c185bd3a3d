"""``zenoh://RUN/PORT``: a port's bytes carried over eclipse-zenoh 1.x (another process or host).

Key expressions (``docs/reference/wire-formats.md`` section 4)::

    psns/<RUN>/<PORT>/tx     bytes transmitted by the port's owner (the box side: the FPGA, or the
                             emulator's external port), i.e. what a peer tool receives
    psns/<RUN>/<PORT>/rx     bytes received by the port's owner, i.e. what a peer tool sends
    psns/<RUN>/nav           the navigation solution, decoded, as one JSON object per frame

The link has a ``role``: ``device`` (default, the emulator's own port: publishes what its device
sends on ``tx`` and subscribes to ``rx``) or ``peer`` (the far end: publishes on ``rx`` and
subscribes to ``tx``); a split run (:mod:`emulator.distributed.split`) opens the DSP's UART ends as peers.
A KEY of a single segment (``zenoh://host``) belongs to run ``default``.

URL options (besides the common ``baud``, ``mode``, ``queue``)::

    role=device|peer          which direction this end publishes (above)
    listen=EP[,EP...]         zenoh endpoints to listen on, e.g. tcp/127.0.0.1:7447
    connect=EP[,EP...]        zenoh endpoints to connect to (other hosts: tcp/10.0.0.2:7447)
    session=peer|client       zenoh session mode (default peer)
    config=FILE               a zenoh JSON5 configuration file (then listen/connect/session
                              are applied on top of it)
    pace=1|0                  pace received bytes with the line model (default 1, as for a pty:
                              a peer tool writes at memory speed); 0 when the far end is another
                              emulator whose line model already paced them
    nav=tx|rx|off             publish decoded NAV_SOLUTION frames found on that stream as JSON
                              on psns/<RUN>/nav (default: tx for a port named ``host``, else off)
    auth=FILE                 the credentials file (one line ``USER:PASSWORD``, mode 0600) this end
                              authenticates with and accepts; default: the process's per-run
                              credentials (:func:`run_credentials`)

Authentication (decision D-9.6): every session is opened with zenoh's user/password
authentication (``transport/auth/usrpwd``): it presents ``USER:PASSWORD`` when it connects and
accepts only sessions that present a pair of its dictionary file (the same file). The credentials
are generated per run (a random 256-bit password in a fresh 0700 directory, file 0600) unless
``auth=FILE`` or the environment variable ``PSNS_HIL_ZENOH_AUTH`` names a file; a process started
by the run (the split DSP process) inherits them through that variable. A zenoh session without
them (an uninvited local process) is refused at the transport: it sees no key and publishes into
nothing. Applied on top of ``config=FILE`` as listen/connect are.

Default session configuration: peer mode on loopback, multicast AND gossip scouting off (the
default configuration would send UDP multicast and wait ~0.5 s at open, docs/reference/wire-formats.md section 0.4),
listening on ``tcp/127.0.0.1:7447`` unless ``listen`` or ``connect`` is given. Links of one
process that ask for the same session configuration share one zenoh session (reference-counted;
the last close closes it), so four UART links do not need four listening sockets.

Each chunk carries the sender's byte spacing on its line as the zenoh attachment (f64, s), so an
unpaced receiving end (``pace=0``) hands the device the same byte timing an in-process link would.

Threads: zenoh calls subscriber callbacks on its own (Rust) threads. The callback only copies the
payload and hands it to the event loop with ``loop.call_soon_threadsafe``; it never blocks and
never raises. Publishers use ``CongestionControl.BLOCK`` (a byte stream must not lose data).
On close the link undeclares its subscriber and publishers explicitly (callback subscribers
outlive their Python object otherwise) and releases the session.
"""

from __future__ import annotations

import asyncio
import atexit
import contextlib
import json
import os
import re
import secrets
import shutil
import stat
import struct
import tempfile
import threading
from collections.abc import Callable
from typing import Any

from protocols.host import NAV_MODE_VARIANT_MASK, HostFormat, NavMode, NavSolution
from protocols.stream import StreamDecoder

from ..errors import LinkBrokenError, LinkConfigError
from .base import Link
from .line import LineConfig

__all__ = [
    "AUTH_ENV",
    "DEFAULT_LISTEN",
    "ZENOH_OPTIONS",
    "NavJsonPublisher",
    "ZenohCredentials",
    "ZenohEndpointConfig",
    "ZenohLink",
    "acquire_session",
    "nav_to_json",
    "open_sessions",
    "release_session",
    "run_credentials",
    "zenoh_key_prefix",
]

#: URL options of zenoh:// beyond the common ones.
ZENOH_OPTIONS = frozenset({"role", "listen", "connect", "session", "config", "pace", "nav", "auth"})
#: Endpoint a link listens on when neither ``listen`` nor ``connect`` is given (zenoh's port).
DEFAULT_LISTEN = "tcp/127.0.0.1:7447"
_USAGE = ("zenoh://RUN/PORT[?role=device|peer&listen=tcp/127.0.0.1:7447&connect=tcp/HOST:PORT"
          "&session=peer|client&config=FILE&pace=1|0&nav=tx|rx|off&auth=FILE&baud=N&mode=8N1&queue=BYTES]")
_CHUNK = re.compile(r"^[A-Za-z0-9_.\-]+$")
#: zenoh attachment of every chunk: the sender's byte spacing on its line (s, f64 little-endian)
_PITCH = struct.Struct("<d")
#: environment variable naming the credentials file the process uses instead of generating its own
AUTH_ENV = "PSNS_HIL_ZENOH_AUTH"
#: a credentials file is one short line; anything longer is refused before it is read whole (bytes)
_AUTH_MAX_BYTES = 4096
_AUTH_TOKEN = re.compile(r"^[A-Za-z0-9_.\-]{1,256}$")


class ZenohCredentials:
    """One ``USER:PASSWORD`` pair in a file of zenoh's dictionary format (decision D-9.6).

    The file is both what this end presents (``user``, ``password``) and its dictionary of accepted peers
    (``dictionary_file``): the two ends of a run share one file.

    Parameters
    ----------
    user, password:
        Letters, digits, ``_ . -`` (1-256 characters each).
    file:
        Path of the file holding ``USER:PASSWORD``.
    """

    __slots__ = ("file", "password", "user")

    def __init__(self, user: str, password: str, file: str) -> None:
        self.user, self.password, self.file = user, password, file

    @classmethod
    def generate(cls, directory: str | None = None) -> ZenohCredentials:
        """New credentials: user ``psns-hil``, a random 256-bit password, in ``directory`` (default: a new
        0700 temporary directory) as ``credentials.txt`` created 0600 (never over an existing file)."""
        d = directory or tempfile.mkdtemp(prefix="psns-hil-zenoh-")  # mkdtemp: mode 0700
        path = os.path.join(d, "credentials.txt")
        user, password = "psns-hil", secrets.token_urlsafe(32)
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
        with os.fdopen(fd, "w", encoding="ascii") as f:
            f.write(f"{user}:{password}\n")
        return cls(user, password, path)

    @classmethod
    def load(cls, path: str) -> ZenohCredentials:
        """Read a credentials file; refused (LinkConfigError) when missing, readable by group or others, longer
        than 4 KB or not one ``USER:PASSWORD`` line. The message never quotes the file's content."""
        try:
            st = os.stat(path)
            if not stat.S_ISREG(st.st_mode):
                raise LinkConfigError(f"zenoh credentials {path}: not a regular file")
            if st.st_mode & 0o077:
                raise LinkConfigError(f"zenoh credentials {path}: readable by group or others "
                                      f"(mode {stat.S_IMODE(st.st_mode):o}); chmod 600 it")
            with open(path, "rb") as f:
                raw = f.read(_AUTH_MAX_BYTES + 1)
        except OSError as exc:
            raise LinkConfigError(f"zenoh credentials {path}: {exc.strerror or exc}") from exc
        lines = raw.decode("ascii", errors="replace").split()
        pair = lines[0].split(":", 1) if len(raw) <= _AUTH_MAX_BYTES and len(lines) == 1 else []
        if len(pair) != 2 or not all(_AUTH_TOKEN.match(x) for x in pair):
            raise LinkConfigError(f"zenoh credentials {path}: expected one line USER:PASSWORD "
                                  "(letters, digits, '_', '.', '-')")
        return cls(pair[0], pair[1], path)

    def apply(self, cfg: Any) -> None:
        """Put this pair and its dictionary into a ``zenoh.Config`` (``transport/auth/usrpwd``)."""
        cfg.insert_json5("transport/auth/usrpwd", json.dumps(
            {"user": self.user, "password": self.password, "dictionary_file": self.file}))

    def __repr__(self) -> str:  # never the password
        return f"ZenohCredentials(user={self.user!r}, file={self.file!r})"


_run_credentials: ZenohCredentials | None = None
_cred_lock = threading.Lock()


def run_credentials() -> ZenohCredentials:
    """The process's zenoh credentials: the file named by ``PSNS_HIL_ZENOH_AUTH`` if set, else generated once
    (and that variable set, so that processes this one starts share them; the directory is removed at exit)."""
    global _run_credentials
    with _cred_lock:
        if _run_credentials is None:
            named = os.environ.get(AUTH_ENV)
            if named:
                _run_credentials = ZenohCredentials.load(named)
            else:
                _run_credentials = ZenohCredentials.generate()
                os.environ[AUTH_ENV] = _run_credentials.file
                atexit.register(shutil.rmtree, os.path.dirname(_run_credentials.file), True)
        return _run_credentials


def _zenoh() -> Any:
    try:
        import zenoh
    except ImportError as exc:  # pragma: no cover - zenoh is a runtime dependency
        raise LinkConfigError(f"zenoh:// needs the eclipse-zenoh package: {exc}") from exc
    return zenoh


def zenoh_key_prefix(target: str) -> tuple[str, str, str]:
    """Split a zenoh:// target into ``(run, port, "psns/<run>/<port>")``.

    ``target`` is ``RUN/PORT`` (RUN may itself have several segments) or ``PORT`` (run
    ``default``). Every segment is a plain zenoh key chunk: letters, digits, ``_ . -``.
    """
    parts = target.strip("/").split("/") if target else []
    if not parts or not all(_CHUNK.match(p) for p in parts):
        raise LinkConfigError(
            f"zenoh://{target}: the key must be RUN/PORT made of letters, digits, '_', '.', '-' "
            f"(no wildcards or empty segments); expected {_USAGE}")
    if len(parts) == 1:
        run, port = "default", parts[0]
    else:
        run, port = "/".join(parts[:-1]), parts[-1]
    return run, port, f"psns/{run}/{port}"


class ZenohEndpointConfig:
    """The zenoh session configuration a link asks for (hashable: equal configs share a session).

    Parameters
    ----------
    listen, connect:
        zenoh endpoint strings (``tcp/127.0.0.1:7447``). With neither, :data:`DEFAULT_LISTEN`.
    session_mode:
        ``peer`` or ``client``.
    config_file:
        Optional zenoh JSON5 configuration file applied first.
    auth_file:
        Credentials file (:class:`ZenohCredentials`); None: the process's :func:`run_credentials`.
    """

    __slots__ = ("auth_file", "config_file", "connect", "listen", "session_mode")

    def __init__(self, listen: tuple[str, ...] = (), connect: tuple[str, ...] = (), session_mode: str = "peer",
                 config_file: str | None = None, auth_file: str | None = None) -> None:
        if session_mode not in ("peer", "client"):
            raise LinkConfigError(f"zenoh session mode must be peer or client, got {session_mode!r}")
        if not listen and not connect and config_file is None:
            listen = (DEFAULT_LISTEN,)
        for ep in listen + connect:
            if "/" not in ep or ep.startswith("/"):
                raise LinkConfigError(f"bad zenoh endpoint {ep!r}; expected e.g. tcp/127.0.0.1:7447")
        self.listen = tuple(listen)
        self.connect = tuple(connect)
        self.session_mode = session_mode
        self.config_file = config_file
        self.auth_file = auth_file

    @property
    def key(self) -> str:
        return json.dumps([self.listen, self.connect, self.session_mode, self.config_file, self.auth_file])

    def credentials(self) -> ZenohCredentials:
        """The credentials this session presents and accepts (``auth_file`` or the run's)."""
        return ZenohCredentials.load(self.auth_file) if self.auth_file is not None else run_credentials()

    def build(self) -> Any:
        """The ``zenoh.Config``: loopback-safe (scouting off unless a config file says otherwise) and
        authenticated (:meth:`credentials`, on top of a config file too)."""
        zenoh = _zenoh()
        creds = self.credentials()
        try:
            if self.config_file is not None:
                cfg = zenoh.Config.from_file(self.config_file)
            else:
                cfg = zenoh.Config()
                cfg.insert_json5("scouting/multicast/enabled", "false")
                cfg.insert_json5("scouting/gossip/enabled", "false")
            cfg.insert_json5("mode", json.dumps(self.session_mode))
            if self.listen or self.config_file is None:
                cfg.insert_json5("listen/endpoints", json.dumps(list(self.listen)))
            if self.connect or self.config_file is None:
                cfg.insert_json5("connect/endpoints", json.dumps(list(self.connect)))
            creds.apply(cfg)
        except zenoh.ZError as exc:
            raise LinkConfigError(f"zenoh configuration rejected: {exc}") from exc
        return cfg

    def __repr__(self) -> str:
        return (f"ZenohEndpointConfig(listen={self.listen}, connect={self.connect}, "
                f"session_mode={self.session_mode!r}, config_file={self.config_file!r}, auth_file={self.auth_file!r})")


# -- the per-process session pool -----------------------------------------------------------------
_pool_lock = threading.Lock()
_pool: dict[str, list[Any]] = {}  # key -> [session, refcount]


def acquire_session(cfg: ZenohEndpointConfig) -> Any:
    """Open (or share) the zenoh session for ``cfg``; pair every call with :func:`release_session`."""
    zenoh = _zenoh()
    with _pool_lock:
        entry = _pool.get(cfg.key)
        if entry is not None and not entry[0].is_closed():
            entry[1] += 1
            return entry[0]
        try:
            session = zenoh.open(cfg.build())
        except zenoh.ZError as exc:
            raise LinkBrokenError(f"cannot open a zenoh session with {cfg}: {exc}") from exc
        _pool[cfg.key] = [session, 1]
        return session


def release_session(cfg: ZenohEndpointConfig) -> None:
    """Drop one reference to ``cfg``'s session; the last one closes it."""
    with _pool_lock:
        entry = _pool.get(cfg.key)
        if entry is None:
            return
        entry[1] -= 1
        if entry[1] > 0:
            return
        del _pool[cfg.key]
        session = entry[0]
    with contextlib.suppress(Exception):
        session.close()


def open_sessions() -> int:
    """Number of zenoh sessions this process holds open through links (tests check it is 0)."""
    with _pool_lock:
        return sum(1 for s, _n in _pool.values() if not s.is_closed())


# -- navigation solution as JSON --------------------------------------------------------------------
def nav_to_json(n: NavSolution, t_s: float | None = None) -> bytes:
    """One NAV_SOLUTION as a JSON object (field names and units of :class:`protocols.host.NavSolution`).

    ``t_s`` is the scenario time at which the frame was seen (s); ``mode_flags`` names the set
    :class:`~protocols.host.NavMode` bits.
    """
    d: dict[str, Any] = {
        "seq": n.seq, "time_s": n.time_s, "lat_deg": n.lat_deg, "lon_deg": n.lon_deg,
        "height_m": n.height_m, "vel_enu_mps": list(n.vel_enu_mps), "roll_deg": n.roll_deg,
        "pitch_deg": n.pitch_deg, "heading_deg": n.heading_deg, "sigma": list(n.sigma), "mode": n.mode,
        "mode_flags": [f.name for f in NavMode if n.mode & f and not f & NAV_MODE_VARIANT_MASK],
        "gnss_status": n.gnss_status, "psns_status": n.psns_status, "cpu_load_pct": n.cpu_load_pct,
        "deadline_misses": n.deadline_misses,
    }
    if t_s is not None:
        d["t_s"] = t_s
    return json.dumps(d, separators=(",", ":")).encode()


class NavJsonPublisher:
    """A link listener that decodes host frames in one direction and publishes them as JSON.

    Parameters
    ----------
    publisher:
        Anything with ``put(bytes)`` (a zenoh publisher on ``psns/<run>/nav``).
    direction:
        ``"out"`` or ``"in"``: which direction of the link carries the navigation frames.
    """

    def __init__(self, publisher: Any, direction: str) -> None:
        self.publisher = publisher
        self.direction = direction
        self.decoder = StreamDecoder([HostFormat()])
        self.published = 0

    def on_link_bytes(self, link: Link, direction: str, t: float, data: bytes) -> None:
        if direction != self.direction:
            return
        for fr in self.decoder.feed(data):
            if isinstance(fr, NavSolution):
                self.publisher.put(nav_to_json(fr, t))
                self.published += 1


def _flag(url: str, name: str, value: str) -> bool:
    if value in ("1", "true", "yes", "on"):
        return True
    if value in ("0", "false", "no", "off"):
        return False
    raise LinkConfigError(f"{url!r}: {name}={value!r} must be 1 or 0; expected {_USAGE}")


class ZenohLink(Link):
    """A link end whose far side is reached through zenoh (see module docstring)."""

    scheme = "zenoh"
    url_usage = _USAGE
    url_options = ZENOH_OPTIONS
    paces_input = True

    @classmethod
    def check_target(cls, url: str, target: str) -> None:
        zenoh_key_prefix(target)

    def __init__(self, name: str, url: str, line: LineConfig, loop: asyncio.AbstractEventLoop,
                 target: str = "", options: dict[str, str] | None = None, **_: Any) -> None:
        super().__init__(name, url, line, loop)
        if options is None:  # built from a URL alone (the split run's UARTs): its options through the one parser
            from . import parse_link_url

            options = parse_link_url(url).options
        opts = options
        self.run, self.port, self.key_prefix = zenoh_key_prefix(target)
        self.role = opts.get("role", "device")
        if self.role not in ("device", "peer"):
            raise LinkConfigError(f"{url!r}: role={self.role!r} must be device or peer; expected {_USAGE}")
        tx, rx = f"{self.key_prefix}/tx", f"{self.key_prefix}/rx"
        self.pub_key, self.sub_key = (tx, rx) if self.role == "device" else (rx, tx)
        self.nav_key = f"psns/{self.run}/nav"
        nav = opts.get("nav", "tx" if (name == "host" and self.role == "device") else "off")
        if nav not in ("tx", "rx", "off"):
            raise LinkConfigError(f"{url!r}: nav={nav!r} must be tx, rx or off; expected {_USAGE}")
        # which of this end's directions carries the nav stream: tx is published by the device end
        self.nav_direction: str | None = None
        if nav != "off":
            self.nav_direction = "out" if (nav == "tx") == (self.role == "device") else "in"
        if "pace" in opts:
            self.paces_input = _flag(url, "pace", opts["pace"])  # type: ignore[misc]

        def _eps(v: str | None) -> tuple[str, ...]:
            return tuple(e.strip() for e in v.split(",") if e.strip()) if v else ()

        try:
            self.endpoint = ZenohEndpointConfig(_eps(opts.get("listen")), _eps(opts.get("connect")),
                                                opts.get("session", "peer"), opts.get("config"), opts.get("auth"))
        except LinkConfigError as exc:
            raise LinkConfigError(f"{url!r}: {exc}; expected {_USAGE}") from exc
        self.session: Any = None
        self._pub: Any = None
        self._sub: Any = None
        self._nav_pub: Any = None
        self.nav_publisher: NavJsonPublisher | None = None
        self._call: Callable[..., Any] = loop.call_soon_threadsafe
        self.received_after_close = 0

    # -- lifecycle ------------------------------------------------------------------------------
    async def open(self) -> None:
        self.open_now()

    def open_now(self) -> None:
        """Open synchronously (zenoh's API is synchronous; :meth:`open` is this for the async callers)."""
        zenoh = _zenoh()
        self.session = acquire_session(self.endpoint)
        try:
            block = zenoh.CongestionControl.BLOCK
            self._pub = self.session.declare_publisher(self.pub_key, congestion_control=block)
            self._sub = self.session.declare_subscriber(self.sub_key, self._on_sample)
            if self.nav_direction is not None:
                self._nav_pub = self.session.declare_publisher(self.nav_key, congestion_control=block)
                self.nav_publisher = NavJsonPublisher(self._nav_pub, self.nav_direction)
                self.listeners.append(self.nav_publisher)
        except zenoh.ZError as exc:
            self._release()
            raise LinkBrokenError(f"{self.name}: cannot declare zenoh entities on {self.key_prefix}: {exc}") from exc

    def _on_sample(self, sample: Any) -> None:
        """zenoh thread: copy the payload and hand it to the loop; never block, never raise."""
        try:
            data = sample.payload.to_bytes()
            att = sample.attachment
            self._call(self._input_from_peer, data, att.to_bytes() if att is not None else None)
        except RuntimeError:  # the loop is closed: the run is over
            self.received_after_close += 1
        except Exception:
            self.received_after_close += 1

    def _input_from_peer(self, data: bytes, attachment: bytes | None) -> None:
        """Loop thread: bytes from zenoh. Unpaced links keep the sender's byte spacing (the attachment)."""
        if self.paces_input or attachment is None or len(attachment) != _PITCH.size or self.closed or not data:
            self._input(data)
            return
        pitch = _PITCH.unpack(attachment)[0]
        if not (0.0 < pitch < 1.0):
            self._input(data)
            return
        bt = self.in_line.cfg.byte_time
        self._arrive(data, self.loop.time() - (len(data) - 1) * pitch - bt, pitch, self.in_line)

    def peer_matched(self) -> bool:
        """True when some subscriber (local or remote) listens to what this end publishes."""
        if self._pub is None:
            return False
        try:
            return bool(self._pub.matching_status.matching)
        except Exception:
            return False

    async def wait_matched(self, timeout_s: float = 5.0, poll_s: float = 0.002) -> bool:
        """Wait (wall clock) until :meth:`peer_matched`; False on timeout.

        Data published before the far end's subscriber is known is lost (pub/sub semantics),
        so a run that needs every byte waits for this first.
        """
        import time

        end = time.monotonic() + timeout_s
        while not self.peer_matched():
            if time.monotonic() >= end:
                return False
            await asyncio.sleep(poll_s)
        return True

    def _write_raw(self, data: bytes) -> None:
        pub = self._pub
        if pub is None:
            self.stats.dropped_out += len(data)
            return
        try:
            pub.put(data, attachment=_PITCH.pack(self._tx_pitch))
        except Exception as exc:
            self.stats.dropped_out += len(data)
            if not self.closed:
                raise LinkBrokenError(f"{self.name}: zenoh put on {self.pub_key} failed: {exc}") from exc

    async def close(self) -> None:
        await super().close()
        self._release()

    def _release(self) -> None:
        self.closed = True
        for attr in ("_sub", "_pub", "_nav_pub"):
            ent = getattr(self, attr)
            setattr(self, attr, None)
            if ent is not None:
                with contextlib.suppress(Exception):
                    ent.undeclare()
        if self.nav_publisher is not None and self.nav_publisher in self.listeners:
            self.listeners.remove(self.nav_publisher)
        if self.session is not None:
            self.session = None
            release_session(self.endpoint)

    def describe(self) -> str:
        eps = [f"listen {e}" for e in self.endpoint.listen] + [f"connect {e}" for e in self.endpoint.connect]
        try:  # the file's path, never its content (the same pair the session uses; made now if not yet)
            creds = self.endpoint.credentials().file
        except LinkConfigError:
            creds = self.endpoint.auth_file or "per run"
        return (f"zenoh {self.key_prefix}/{{tx,rx}} ({self.role}; {', '.join(eps) or 'config file'}; "
                f"credentials {creds})")
