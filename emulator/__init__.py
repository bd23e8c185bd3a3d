"""The asyncio world around the firmware: clock, links, devices, world/truth, scenarios,
recorder, reports and the ``psns-hil`` CLI. Depends on :mod:`firmware_model` and
:mod:`protocols`, never the other way round."""

from __future__ import annotations

from protocols import __version__

from .errors import EmulatorError, LinkError, ScenarioError

__all__ = ["EmulatorError", "LinkError", "ScenarioError", "__version__"]
