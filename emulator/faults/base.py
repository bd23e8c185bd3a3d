"""The injector base: one fault bound to its target, and the evidence it collects."""

from __future__ import annotations

import functools
import importlib
import pkgutil
from collections.abc import Callable
from typing import Any, TypeVar

import numpy as np

from ..errors import ScenarioError, ScenarioIssue
from .targets import FaultTargets

__all__ = ["AXES", "INJECTORS", "Injector", "bind_error", "injector_classes", "injects"]

AXES = {"x": 0, "y": 1, "z": 2}

#: the injector of every fault kind (the field name on :class:`emulator.scenario.faults_schema.Fault`), filled by
#: :func:`injects` when the modules of this package are imported (:func:`injector_classes` imports them all, once)
INJECTORS: dict[str, type[Injector]] = {}

_I = TypeVar("_I", bound="type[Injector]")


def injects(kind: str) -> Callable[[_I], _I]:
    """Register the decorated :class:`Injector` subclass as the injector of fault ``kind``: a new kind is its
    schema model (``emulator/scenario/faults_schema.py``) and one decorated class in a module of this package."""
    def register(cls: _I) -> _I:
        if kind in INJECTORS and INJECTORS[kind] is not cls:
            raise ValueError(f"fault kind {kind!r} already has an injector ({INJECTORS[kind].__name__})")
        INJECTORS[kind] = cls
        return cls
    return register


@functools.cache
def injector_classes() -> dict[str, type[Injector]]:
    """:data:`INJECTORS` after importing every module of this package (each registers its injectors)."""
    package = __name__.rpartition(".")[0]
    for info in pkgutil.iter_modules(importlib.import_module(package).__path__):
        importlib.import_module(f"{package}.{info.name}")
    return INJECTORS


class Injector:
    """One fault bound to its target. Subclasses implement :meth:`on`, :meth:`off` and :meth:`_counts`.

    ``_counts()`` returns cumulative counters of the target; the evidence is their change while the
    fault was active (overridden by injectors that count by themselves). ``effect_keys`` name the
    counts that prove the fault took effect.
    """

    effect_keys: tuple[str, ...] = ()

    def __init__(self, targets: FaultTargets, kind: str, spec: Any, index: int, rng: np.random.Generator) -> None:
        self.targets = targets
        self.kind = kind
        self.spec = spec
        self.index = index
        self.rng = rng
        self.active = False
        self.t_on: float | None = None
        self.t_off: float | None = None
        self._c0: dict[str, int] = {}
        self._acc: dict[str, int] = {}

    # -- described by subclasses ---------------------------------------------------------------
    @property
    def target(self) -> str:
        return ""

    def on(self, t: float) -> None:
        raise NotImplementedError

    def off(self, t: float) -> None:
        raise NotImplementedError

    def _counts(self) -> dict[str, int]:
        return {}

    # -- shared ------------------------------------------------------------------------------------
    def start(self, t: float) -> None:
        self._c0 = self._counts()
        self.on(t)
        self.active = True
        self.t_on = t

    def stop(self, t: float) -> None:
        if not self.active:
            return
        self.off(t)
        c1 = self._counts()
        for k, v in c1.items():
            self._acc[k] = self._acc.get(k, 0) + max(0, int(v) - int(self._c0.get(k, 0)))
        self.active = False
        self.t_off = t

    def evidence(self) -> dict[str, int]:
        return dict(self._acc)

    @property
    def fired(self) -> bool:
        ev = self.evidence()
        return any(ev.get(k, 0) > 0 for k in self.effect_keys)


def bind_error(kind: str, msg: str) -> ScenarioError:
    """A fault that cannot bind to its target (a missing device or link): a scenario error."""
    return ScenarioError(ScenarioIssue("<scenario>", None, None, f"faults.{kind}", f"{kind} {msg}"))
