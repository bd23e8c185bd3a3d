"""``scaled_q``: the base filter with its process-noise power spectral density scaled by ``q_scale``.

A study knob (how much does the navigation lean on the IMU model?) and the smallest filter a plugin can add:
a :class:`firmware_model.filters.base.BaseFilter` subclass that declares its parameter model (``params_model``, a
dataclass); the scenario's ``firmware.params`` is validated against it and reaches the filter through
:func:`firmware_model.registry.filter_params`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from firmware_model.filters.base import BaseFilter
from firmware_model.registry import filter_params


@dataclass
class ScaledNoiseParams:
    """Parameters of ``scaled_q``."""

    #: factor on the process-noise PSD Q of every state (1: the base filter)
    q_scale: float = 1.0

    def __post_init__(self) -> None:
        if not self.q_scale > 0:
            raise ValueError(f"q_scale must be > 0, got {self.q_scale}")


class ScaledNoiseFilter(BaseFilter):
    """The base filter with ``Q`` multiplied by ``q_scale``."""

    params_model = ScaledNoiseParams

    def __init__(self, cfg: Any, meter: Any, dtype: Any) -> None:
        super().__init__(cfg, meter, dtype)
        self.params: ScaledNoiseParams = filter_params(cfg, self.name)
        self.q = self.q * self.params.q_scale
