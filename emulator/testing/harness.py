"""The test API for port traffic, Renode-style: start an emulator inside a coroutine and wait for what its
ports carry (:func:`start_emulator`, :class:`EmulatorHarness`, :func:`run`).

The test API is one package, ``emulator.testing``: import these names from there (``from emulator.testing import
start_emulator``); its docstring describes the API, and it is also the pytest plugin (the ``pytest11`` entry point).
"""

from __future__ import annotations

import asyncio
import re
from collections import deque
from collections.abc import Awaitable, Callable
from pathlib import Path
from re import Pattern
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from ..assembly.session import Emulator
    from ..scenario.schema import Scenario

__all__ = ["DEFAULT_DIRECTION", "EmulatorHarness", "PortWatcher", "load_test_scenario", "run", "start_emulator"]

#: Direction watched by default per port (see module docstring).
DEFAULT_DIRECTION = {"host": "out", "uart0": "out", "monitor": "out"}

_LOOP_HARNESSES = "_psns_harnesses"


def _direction(port: str, direction: str | None) -> str:
    if direction is not None:
        if direction not in ("in", "out"):
            raise ValueError(f"direction must be 'in' or 'out', got {direction!r}")
        return direction
    return DEFAULT_DIRECTION.get(port, "in")


class PortWatcher:
    """Everything one direction of one port carries since the emulator started (bounded).

    ``max_bytes`` of unconsumed bytes and ``max_frames`` unconsumed frames are kept; older ones
    are discarded and counted (``discarded_bytes``, ``discarded_frames``).
    """

    def __init__(self, port: str, direction: str, formats: list[Any], max_bytes: int = 1 << 20,
                 max_frames: int = 8192) -> None:
        from protocols.stream import StreamDecoder

        self.port = port
        self.direction = direction
        self.buf = bytearray()
        self.base = 0  # absolute stream offset of buf[0]
        self.total_bytes = 0
        self.frames: deque[tuple[float, Any]] = deque()
        self.total_frames = 0
        self.decoder = StreamDecoder(formats) if formats else None
        self.last_t: float | None = None
        self.max_bytes = max_bytes
        self.max_frames = max_frames
        self.discarded_bytes = 0
        self.discarded_frames = 0
        self._waiters: list[asyncio.Future[None]] = []

    # listener ------------------------------------------------------------------------------
    def on_link_bytes(self, link: Any, direction: str, t: float, data: bytes) -> None:
        if direction != self.direction:
            return
        self.buf += data
        self.total_bytes += len(data)
        over = len(self.buf) - self.max_bytes
        if over > 0:
            del self.buf[:over]
            self.base += over
            self.discarded_bytes += over
        if self.decoder is not None:
            for fr in self.decoder.feed(data):
                self.frames.append((t, fr))
                self.total_frames += 1
            while len(self.frames) > self.max_frames:
                self.frames.popleft()
                self.discarded_frames += 1
        self.last_t = t
        waiters, self._waiters = self._waiters, []
        for w in waiters:
            if not w.done():
                w.set_result(None)

    def changed(self) -> asyncio.Future[None]:
        """A future completed at the next chunk on this port direction."""
        fut = asyncio.get_running_loop().create_future()
        self._waiters.append(fut)
        return fut

    def describe(self) -> str:
        last = repr(self.frames[-1][1])[:160] if self.frames else "none"
        return (f"{self.total_bytes} bytes and {self.total_frames} frames seen on {self.port}/{self.direction} "
                f"so far; {len(self.buf)} bytes and {len(self.frames)} frames unconsumed; last frame: {last}")


def _compile_bytes(pattern: bytes | str | Pattern[bytes]) -> Pattern[bytes]:
    if isinstance(pattern, re.Pattern):
        if not isinstance(pattern.pattern, bytes):
            raise TypeError("a byte pattern must be bytes or a compiled bytes regex")
        return pattern
    if isinstance(pattern, str):
        pattern = pattern.encode("ascii")
    return re.compile(re.escape(pattern))


def _compile_text(pattern: str | Pattern[str]) -> Pattern[str]:
    if isinstance(pattern, re.Pattern):
        return pattern
    return re.compile(re.escape(pattern))


class EmulatorHarness:
    """A running emulator with Renode-style waits on its ports (see module docstring)."""

    def __init__(self, emulator: Emulator) -> None:
        self.emulator = emulator
        self.watchers: dict[tuple[str, str], PortWatcher] = {}
        self.summary: dict[str, Any] | None = None
        self._loop: asyncio.AbstractEventLoop | None = None

    # -- lifecycle ---------------------------------------------------------------------------
    async def start(self) -> EmulatorHarness:
        from ..assembly.ports import port_formats
        from ..clock import EmulatorLoop
        from ..errors import EmulatorError

        loop = asyncio.get_running_loop()
        if not isinstance(loop, EmulatorLoop):
            raise EmulatorError("start_emulator() needs a running emulator.clock.EmulatorLoop: mark the test "
                                "@pytest.mark.psns_emulator or use emulator.testing.run()")
        if loop.mode != self.emulator.mode:
            raise EmulatorError(f"the scenario runs in {self.emulator.mode} mode but the loop is in {loop.mode} "
                                f"mode; use @pytest.mark.psns_emulator(mode={self.emulator.mode!r})")
        running = getattr(loop, _LOOP_HARNESSES, None)
        if running is None:
            running = []
            setattr(loop, _LOOP_HARNESSES, running)
        if running:
            raise EmulatorError("one emulator per test: the emulator restarts the scenario clock at 0, so it "
                                "needs a fresh EmulatorLoop (one per psns_emulator test or emulator.testing.run)")
        running.append(self)
        self._loop = loop
        emu = self.emulator
        await emu.start()
        for name, link in emu.links.items():
            fm = port_formats(name)
            for d in ("in", "out"):
                formats = fm.get(d, [])
                if name == "gyro" and d == "in":
                    from protocols.stim import gyro_port_format

                    imu = emu.scn.sensors.imu
                    formats = [gyro_port_format(imu.device, imu.format, int(imu.stim300_datagram, 16))]
                w = PortWatcher(name, d, formats)
                self.watchers[(name, d)] = w
            link.listeners.append(_Both(self.watchers[(name, "in")], self.watchers[(name, "out")]))
        return self

    async def stop(self) -> dict[str, Any]:
        """Stop the emulator (closes links, writes the run directory); returns the summary."""
        if self.summary is None:
            self.summary = await self.emulator.stop()
            fpga = self.emulator.fpga
            if fpga is not None:
                fpga.stop()
        return self.summary

    async def __aenter__(self) -> EmulatorHarness:
        return self

    async def __aexit__(self, *exc: Any) -> None:
        await self.stop()

    # -- properties --------------------------------------------------------------------------
    @property
    def loop(self) -> asyncio.AbstractEventLoop:
        assert self._loop is not None
        return self._loop

    @property
    def time(self) -> float:
        """Scenario time, s (the emulator's clock)."""
        return self.loop.time()

    @property
    def ports(self) -> list[str]:
        return list(self.emulator.links)

    def watcher(self, port: str, direction: str | None = None) -> PortWatcher:
        d = _direction(port, direction)
        try:
            return self.watchers[(port, d)]
        except KeyError:
            raise KeyError(f"no port {port!r}; ports: {', '.join(self.ports)}") from None

    # -- waiting primitives --------------------------------------------------------------------
    async def _wait(self, w: PortWatcher, check: Callable[[], Any], timeout: float, what: str) -> Any:
        from ..errors import LinkTimeoutError

        loop = self.loop
        deadline = loop.time() + timeout
        while True:
            got = check()
            if got is not None:
                return got
            left = deadline - loop.time()
            if left <= 0:
                raise LinkTimeoutError(f"{what} within {timeout:g} s (emulator clock, now t = {loop.time():.6f} s); "
                                       f"{w.describe()}")
            fut = w.changed()
            timer = loop.call_at(deadline, _wake, fut)
            try:
                await fut
            finally:
                timer.cancel()

    async def wait_for_frame(self, port: str, predicate: Callable[[Any], bool] | None = None, timeout: float = 1.0,
                             direction: str | None = None) -> Any:
        """The first unconsumed decoded frame on ``port`` for which ``predicate`` holds.

        Frames before it are consumed too. Returns the frame (its arrival time is
        :attr:`last_match_time`).
        """
        w = self.watcher(port, direction)
        if w.decoder is None:
            raise ValueError(f"no frame decoder for {port}/{w.direction}; use wait_for_bytes")

        def check() -> Any:
            while w.frames:
                t, fr = w.frames.popleft()
                if predicate is None or predicate(fr):
                    self.last_match_time = t
                    return (fr,)
            return None

        return (await self._wait(w, check, timeout, f"no frame matching {_name(predicate)} on {port}/{w.direction}"))[0]

    async def wait_for_bytes(self, port: str, pattern: bytes | str | Pattern[bytes], timeout: float = 1.0,
                             direction: str | None = None) -> bytes:
        """Wait until ``pattern`` (bytes, or a compiled bytes regex) appears in the unconsumed
        byte stream; consume through the end of the match and return the matched bytes."""
        w = self.watcher(port, direction)
        rx = _compile_bytes(pattern)

        def check() -> Any:
            m = rx.search(w.buf)
            if m is None:
                return None
            self.last_match_time = w.last_t
            got = bytes(m.group(0))
            del w.buf[:m.end()]
            w.base += m.end()
            return got

        got: bytes = await self._wait(w, check, timeout, f"no bytes matching {rx.pattern!r} on {port}/{w.direction}")
        return got

    async def wait_for_line(self, port: str, pattern: str | Pattern[str], timeout: float = 1.0,
                            direction: str | None = None) -> str:
        """Wait for a whole line (``\\n``-terminated, ``\\r`` stripped, ASCII) containing
        ``pattern`` (a string, or a compiled regex searched in the line); lines before it are
        consumed. Returns the line."""
        w = self.watcher(port, direction)
        rx = _compile_text(pattern)

        def check() -> Any:
            while True:
                nl = w.buf.find(b"\n")
                if nl < 0:
                    return None
                line = bytes(w.buf[:nl]).rstrip(b"\r").decode("ascii", errors="replace")
                del w.buf[:nl + 1]
                w.base += nl + 1
                if rx.search(line):
                    self.last_match_time = w.last_t
                    return line

        found: str = await self._wait(w, check, timeout, f"no line matching {rx.pattern!r} on {port}/{w.direction}")
        return found

    async def assert_not_seen(self, port: str, pattern: bytes | str | Pattern[bytes] | Callable[[Any], bool],
                              during: float, direction: str | None = None) -> None:
        """Fail (AssertionError) if, within the next ``during`` s of the emulator's clock,
        ``port`` carries ``pattern``: bytes / a bytes regex on the raw stream, or a predicate on
        decoded frames. Consumes nothing; fails as soon as the pattern appears."""
        w = self.watcher(port, direction)
        loop = self.loop
        end = loop.time() + during
        byte_start = w.base + len(w.buf)
        frame_start = w.total_frames
        is_frame = callable(pattern) and not isinstance(pattern, (bytes, str, re.Pattern))
        rx = None if is_frame else _compile_bytes(pattern)  # type: ignore[arg-type]
        while True:
            if is_frame:
                new = w.total_frames - frame_start
                recent = list(w.frames)[-new:] if new > 0 else []
                for t, fr in recent:
                    if pattern(fr):  # type: ignore[operator]
                        raise AssertionError(f"{port}/{w.direction}: frame matching {_name(pattern)} seen at "
                                             f"t = {t:.6f} s: {fr!r}"[:600])
            else:
                off = max(0, byte_start - w.base - 64)  # a match may straddle the window start
                m = rx.search(w.buf, off) if rx is not None else None
                if m is not None and w.base + m.end() > byte_start:
                    raise AssertionError(f"{port}/{w.direction}: {bytes(m.group(0))!r} seen by t = {w.last_t:.6f} s "
                                         f"(window {end - during:.6f}..{end:.6f} s)")
            if loop.time() >= end:
                return
            fut = w.changed()
            timer = loop.call_at(end, _wake, fut)
            try:
                await fut
            finally:
                timer.cancel()

    async def wait_idle(self, port: str, quiet_time: float, timeout: float = 10.0, direction: str | None = None
                        ) -> float:
        """Wait until ``port`` has carried nothing for ``quiet_time`` s; returns the time the
        quiet period began (the last chunk's time, or the call's time if nothing came since)."""
        from ..errors import LinkTimeoutError

        w = self.watcher(port, direction)
        loop = self.loop
        t_call = loop.time()
        deadline = t_call + timeout
        while True:
            last = w.last_t if w.last_t is not None and w.last_t > t_call else t_call
            quiet_until = last + quiet_time
            now = loop.time()
            if now >= quiet_until:
                return last
            if quiet_until > deadline:
                if now >= deadline:
                    raise LinkTimeoutError(f"{port}/{w.direction} never stayed quiet for {quiet_time:g} s within "
                                           f"{timeout:g} s (emulator clock); last chunk at t = {w.last_t}")
                wake_at = deadline
            else:
                wake_at = quiet_until
            fut = w.changed()
            timer = loop.call_at(wake_at, _wake, fut)
            try:
                await fut
            finally:
                timer.cancel()

    async def wait_until(self, predicate: Callable[[], bool], timeout: float, poll_s: float = 0.005,
                         what: str = "") -> float:
        """Wait until ``predicate()`` holds (polled every ``poll_s`` of the emulator's clock);
        returns the time it first held. For state such as firmware counters."""
        from ..errors import LinkTimeoutError

        loop = self.loop
        deadline = loop.time() + timeout
        while not predicate():
            if loop.time() >= deadline:
                raise LinkTimeoutError(f"{what or _name(predicate)} did not hold within {timeout:g} s "
                                       f"(emulator clock, now t = {loop.time():.6f} s)")
            await asyncio.sleep(min(poll_s, max(deadline - loop.time(), 0.0)))
        return loop.time()

    async def run_for(self, duration: float) -> None:
        """Let the emulator run ``duration`` s of its clock."""
        await asyncio.sleep(duration)

    # -- injecting ------------------------------------------------------------------------------
    def send(self, port: str, data: bytes) -> int:
        """Put ``data`` on ``port`` from the device side (the external peer), paced by its line.

        Only ports wired in-process (``mem://``); for a pty, write to its path.
        """
        end = self.emulator.device_ends.get(port)
        if end is None:
            raise KeyError(f"{port!r} has no in-process device end (not a mem:// port); write to its endpoint")
        return end.send(data)

    # -- results --------------------------------------------------------------------------------
    @property
    def fw(self) -> Any:
        return self.emulator.fw

    def link_stats(self, port: str) -> dict[str, Any]:
        return self.emulator.links[port].stats.as_dict()

    last_match_time: float | None = None


class _Both:
    __slots__ = ("w_in", "w_out")

    def __init__(self, w_in: PortWatcher, w_out: PortWatcher) -> None:
        self.w_in = w_in
        self.w_out = w_out

    def on_link_bytes(self, link: Any, direction: str, t: float, data: bytes) -> None:
        (self.w_in if direction == "in" else self.w_out).on_link_bytes(link, direction, t, data)


def _wake(fut: asyncio.Future[None]) -> None:
    if not fut.done():
        fut.set_result(None)


def _name(f: Any) -> str:
    if f is None:
        return "(any)"
    return getattr(f, "__name__", None) or repr(f)


def _set_path(data: dict[str, Any], dotted: str, value: Any) -> None:
    keys = dotted.split(".")
    d = data
    for k in keys[:-1]:
        if not isinstance(d.get(k), dict):
            d[k] = {}
        d = d[k]
    d[keys[-1]] = value


def load_test_scenario(scenario: str | Path | Scenario | dict[str, Any],
                       overrides: dict[str, Any] | None = None) -> Scenario:
    """A validated scenario from a path, a mapping or a Scenario, with dotted-path overrides
    (``{"duration_s": 70, "links.host.url": "pty://uart0"}``) applied before validation."""
    import yaml

    from ..scenario.loader import load_yaml_with_marks, validate_scenario_data
    from ..scenario.schema import Scenario

    base_dir = None
    file = "<test scenario>"
    if isinstance(scenario, Scenario):
        data = scenario.model_dump(mode="json", exclude_unset=True)
        marks: dict[Any, Any] = {}
    elif isinstance(scenario, dict):
        data = yaml.safe_load(yaml.safe_dump(scenario))
        marks = {}
    else:
        p = Path(scenario)
        file = str(p)
        base_dir = p.resolve().parent
        data, marks = load_yaml_with_marks(p.read_text(encoding="utf-8"), file)
    for k, v in (overrides or {}).items():
        _set_path(data, k, v)
    return validate_scenario_data(data, marks, file, base_dir=base_dir)


def start_emulator(scenario: str | Path | Scenario | dict[str, Any], run_dir: str | Path | None = None,
                   mode: str | None = None, seed: int | None = None,
                   overrides: dict[str, Any] | None = None) -> _Starter:
    """Start an emulator for ``scenario`` on the running EmulatorLoop.

    Use as ``async with start_emulator(...) as emu`` (stopped at the end of the block) or
    ``emu = await start_emulator(...)`` (stopped by the ``psns_emulator`` runner at the end of
    the test, or by ``await emu.stop()``). ``mode`` defaults to the running loop's mode.
    """
    return _Starter(scenario, run_dir, mode, seed, overrides)


class _Starter:
    def __init__(self, scenario: Any, run_dir: Any, mode: str | None, seed: int | None,
                 overrides: dict[str, Any] | None) -> None:
        self.args = (scenario, run_dir, mode, seed, overrides)
        self.harness: EmulatorHarness | None = None

    async def _start(self) -> EmulatorHarness:
        import tempfile

        from ..assembly.session import Emulator

        scenario, run_dir, mode, seed, overrides = self.args
        scn = load_test_scenario(scenario, overrides)
        loop = asyncio.get_running_loop()
        mode = mode or getattr(loop, "mode", None)
        if run_dir is None:
            run_dir = Path(tempfile.mkdtemp(prefix="psns-hil-test-"))
        emu = Emulator(scn, Path(run_dir), mode=mode, seed=seed)
        self.harness = EmulatorHarness(emu)
        return await self.harness.start()

    def __await__(self) -> Any:
        return self._start().__await__()

    async def __aenter__(self) -> EmulatorHarness:
        return await self._start()

    async def __aexit__(self, *exc: Any) -> None:
        if self.harness is not None:
            await self.harness.stop()


async def _stop_all(loop: asyncio.AbstractEventLoop) -> None:
    for h in getattr(loop, _LOOP_HARNESSES, []):
        if h.summary is None:
            await h.stop()


def run(main: Callable[..., Awaitable[Any]], *args: Any, mode: str = "fast", speed: float = 1.0, **kwargs: Any
        ) -> Any:
    """Run ``main(*args, **kwargs)`` on a fresh EmulatorLoop; stop every emulator it left running."""
    from ..clock import EmulatorLoop

    loop = EmulatorLoop(mode, speed)
    errors: list[dict[str, Any]] = []
    loop.set_exception_handler(lambda lp, ctx: errors.append(ctx))
    try:
        asyncio.set_event_loop(loop)

        async def wrapper() -> Any:
            try:
                return await main(*args, **kwargs)
            finally:
                await _stop_all(loop)

        result = loop.run_until_complete(wrapper())
        if errors:  # a device callback raised: the emulated system is broken, say so
            ctx = errors[0]
            raise AssertionError(f"{len(errors)} error(s) in event-loop callbacks; first: "
                                 f"{ctx.get('message')}: {ctx.get('exception')!r}") from ctx.get("exception")
        return result
    finally:
        try:
            pending = [t for t in asyncio.all_tasks(loop) if not t.done()]
            for t in pending:
                t.cancel()
            if pending:
                loop.run_until_complete(asyncio.gather(*pending, return_exceptions=True))
            loop.run_until_complete(loop.shutdown_asyncgens())
        finally:
            asyncio.set_event_loop(None)
            loop.close()
