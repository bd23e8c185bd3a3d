"""Test API for port traffic, Renode-style, and its pytest plugin: one package, imported as ``emulator.testing``.

The names below are its public API (``from emulator.testing import start_emulator, run, load_test_scenario``); they
are implemented in :mod:`emulator.testing.harness`. This module is also the pytest plugin (the ``pytest11`` entry
point ``psns_hil = "emulator.testing"`` in pyproject.toml), which registers the ``psns_emulator`` marker.

Start an emulator from a scenario inside a coroutine running on an
:class:`~emulator.clock.EmulatorLoop`, then wait for what its ports carry::

    import pytest
    from protocols.host import NavMode, NavSolution

    @pytest.mark.psns_emulator                      # this async test runs on a fresh fast-mode loop
    async def test_navigates(tmp_path):
        async with start_emulator("scenarios/quickstart.yaml", run_dir=tmp_path) as emu:
            nav = await emu.wait_for_frame("host", lambda f: isinstance(f, NavSolution)
                                           and f.mode & NavMode.NAVIGATING, timeout=10.0)
            await emu.assert_not_seen("host", lambda f: f.deadline_misses > 0, during=5.0)

Every timeout and duration counts in the **emulator's clock**: virtual seconds in ``fast`` mode
(a 60 s wait takes as long as simulating 60 s, usually a fraction of that in wall time),
wall seconds times ``speed`` in ``realtime`` mode. A timeout raises
:class:`~emulator.errors.LinkTimeoutError` (a ``TimeoutError``) saying what was seen.

Consumption follows Renode's terminal tester: every port direction is watched from the start;
``wait_for_bytes`` / ``wait_for_line`` consume the byte stream up to the end of their match,
``wait_for_frame`` consumes decoded frames up to and including the match. ``assert_not_seen``
looks only at traffic during its window and consumes nothing; it fails as soon as the pattern
shows up.

Ports are the emulator's link names (``host``, ``gyro``, ``gnss``, ``psns``, ``monitor``,
``uart0`` .. ``uart3``). The default direction is the one carrying the port's main traffic:
``out`` for ``host``, ``uart0`` and ``monitor`` (leaving the DSP / the box), ``in`` for the
others (towards the DSP). Frames are decoded with the port's formats
(:func:`emulator.assembly.ports.port_formats`).

Running the loop: the ``psns_emulator`` marker (this module is a pytest plugin, registered by
the ``pytest11`` entry point) runs an ``async def`` test on a fresh ``EmulatorLoop`` of its
own, independently of pytest-asyncio (``@pytest.mark.psns_emulator(mode="realtime",
speed=1.0)`` for real time). Emulators still running when the test returns are stopped.
Outside pytest, :func:`run` does the same for a coroutine function. An exception in any
event-loop callback (a device bug) fails the test after the coroutine ends.
"""

from __future__ import annotations

import inspect
from typing import Any

from .harness import (
    DEFAULT_DIRECTION,
    EmulatorHarness,
    PortWatcher,
    load_test_scenario,
    run,
    start_emulator,
)

__all__ = ["DEFAULT_DIRECTION", "EmulatorHarness", "PortWatcher", "load_test_scenario", "run", "start_emulator"]


# -- pytest plugin ------------------------------------------------------------------------------
def pytest_configure(config: Any) -> None:
    config.addinivalue_line(
        "markers",
        "psns_emulator(mode='fast', speed=1.0): run this async test on a fresh emulator.clock.EmulatorLoop "
        "(emulator.testing); timeouts count in the emulator's clock",
    )


try:
    import pytest as _pytest

    _tryfirst = _pytest.hookimpl(tryfirst=True)
except ImportError:  # pragma: no cover - pytest is a test dependency only
    def _tryfirst(f: Any) -> Any:
        return f


@_tryfirst
def pytest_pyfunc_call(pyfuncitem: Any) -> Any:
    marker = pyfuncitem.get_closest_marker("psns_emulator")
    if marker is None or not inspect.iscoroutinefunction(pyfuncitem.obj):
        return None
    if pyfuncitem.get_closest_marker("asyncio") is not None:
        raise RuntimeError(f"{pyfuncitem.nodeid}: use either @pytest.mark.psns_emulator or @pytest.mark.asyncio")
    mode = marker.kwargs.get("mode", marker.args[0] if marker.args else "fast")
    speed = float(marker.kwargs.get("speed", 1.0))
    names = pyfuncitem._fixtureinfo.argnames
    kwargs = {n: pyfuncitem.funcargs[n] for n in names}
    run(pyfuncitem.obj, mode=mode, speed=speed, **kwargs)
    return True
