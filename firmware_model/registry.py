"""What the emulator may use of a firmware (:class:`FirmwareProtocol`, :class:`FirmwareSnapshot`) and the build's
registries: filter variants with their parameter models, and firmware implementations.

The registries are plain tables; the emulator fills them from the ``psns_hil.filters`` and ``psns_hil.firmware``
entry points at start-up (:mod:`emulator.plugins`, docs/plugins.md), so a package installed next to psns-hil adds
a filter or a whole firmware without editing this one. Nothing here does I/O.

* A **filter** is a :class:`firmware_model.filters.interface.NavFilter` subclass. It declares its parameter model as the
  class attribute ``params_model`` (a dataclass whose fields have defaults); the scenario's ``firmware.params``
  is validated against it, and the filter reads its instance with :func:`filter_params`.
* A **firmware implementation** is a callable ``(FirmwareConfig) -> FirmwareProtocol``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field, fields, is_dataclass
from typing import Any, Protocol, get_type_hints, runtime_checkable

from .config import FILTER_VARIANTS, FirmwareConfig
from .tasks.state import SolarSolve, TickResult
from .variants import params as _params
from .variants.params import VariantParams

__all__ = [
    "BUILTIN_FILTER_PARAMS",
    "FIRMWARE_IMPLEMENTATIONS",
    "FirmwareProtocol",
    "FirmwareSnapshot",
    "SolarSolve",
    "TickResult",
    "filter_params",
    "filter_params_model",
    "register_firmware",
]


@dataclass(frozen=True)
class FirmwareSnapshot:
    """What the recorder and the report read of a firmware, at one instant (units in the names).

    ``covariance_diag``: the diagonal of the filter's error-state covariance (layout: :mod:`firmware_model.kf`;
    rad^2, (m/s)^2, rad^2 / m^2, (rad/s)^2, (m/s^2)^2), None for a firmware without one; ``gyro_bias_rad_s`` and
    ``accel_bias_mps2``: the bias estimates compensating the IMU (body axes), None without; ``cycles``: the cycle
    meter's table (docs/reference/c674x-cycles.md section 5) and ``tick_budget_cycles`` (None: not metered).
    """

    state: str
    mode: int
    filter: str
    precision: str
    covariance_diag: tuple[float, ...] | None = None
    gyro_bias_rad_s: tuple[float, float, float] | None = None
    accel_bias_mps2: tuple[float, float, float] | None = None
    counters: dict[str, int] = field(default_factory=dict)
    decoders: dict[str, dict[str, Any]] = field(default_factory=dict)
    cycles: list[dict[str, Any]] | dict[str, Any] | None = None
    tick_budget_cycles: int | None = None
    #: the sensor spec sheet the filter was configured from (None: not applicable)
    spec_sheet: str | None = None
    #: normalised innovation squared sums per measurement type (``{"gnss_pos": {"n": .., "nis_sum": .., ...}}``)
    innovation: dict[str, dict[str, float]] = field(default_factory=dict)


@runtime_checkable
class FirmwareProtocol(Protocol):
    """The whole interface between the virtual DSP and a firmware (contract C3, docs/architecture.md)."""

    def receive(self, uart: int, data: bytes, t_rx_s: float | None = None) -> None:
        """Bytes that survived ``uart``'s FIFO and ring; the last one arrived at ``t_rx_s`` (s, FPGA time)."""

    def service(self) -> list[TickResult]:
        """Run the cyclic executive once per pending IMU frame."""

    def note_deadline_miss(self) -> None:
        """The DSP found a tick late."""

    def snapshot(self) -> FirmwareSnapshot:
        """State, covariance diagonal, biases, mode and counters now."""


#: firmware implementations by ``firmware.implementation`` name (``psns_hil``: :class:`firmware_model.Firmware`,
#: entered by :mod:`firmware_model.firmware`)
FIRMWARE_IMPLEMENTATIONS: dict[str, Callable[[FirmwareConfig], FirmwareProtocol]] = {}

#: parameter models of the built-in variants, by filter name: the sections of :class:`VariantParams` (their values
#: also come from ``firmware.variants.NAME``); ``mode_manager`` is shared by every variant, ``plugins`` holds the rest
BUILTIN_FILTER_PARAMS: dict[str, type[Any]] = {
    name: tp for name, tp in get_type_hints(VariantParams, vars(_params)).items()
    if name not in ("mode_manager", "plugins")}


def register_firmware(name: str, factory: Callable[[FirmwareConfig], FirmwareProtocol]) -> None:
    """Make ``factory`` selectable as ``firmware.implementation: name``."""
    FIRMWARE_IMPLEMENTATIONS[name] = factory


def filter_params_model(name: str) -> type[Any] | None:
    """The parameter model (a dataclass) the filter ``name`` declares, None for a filter without parameters."""
    if name in BUILTIN_FILTER_PARAMS:
        return BUILTIN_FILTER_PARAMS[name]
    cls = FILTER_VARIANTS.get(name)
    model = getattr(cls, "params_model", None) if cls is not None else None
    if model is not None and not (isinstance(model, type) and is_dataclass(model)):
        raise TypeError(f"filter {name!r}: params_model must be a dataclass, got {model!r}")
    return model


def filter_params(cfg: FirmwareConfig, name: str) -> Any:
    """The parameters of filter ``name`` in ``cfg`` (an instance of its :func:`filter_params_model`): the
    scenario's ``firmware.params`` when given, else the model's defaults."""
    if name in BUILTIN_FILTER_PARAMS:
        return getattr(cfg.variants, name)
    got = cfg.variants.plugins.get(name)
    if got is not None:
        return got
    model = filter_params_model(name)
    return model() if model is not None else None


def params_fields(model: type[Any]) -> list[str]:
    """Field names of a parameter model (for messages)."""
    return [f.name for f in fields(model)]
