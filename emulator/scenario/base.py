"""Base models of every scenario section: unknown keys are errors."""

from __future__ import annotations

from typing import Any, ClassVar

from pydantic import BaseModel, ConfigDict, model_validator

__all__ = ["Model", "OneKindModel"]


class Model(BaseModel):
    model_config = ConfigDict(extra="forbid", validate_assignment=False)


class OneKindModel(Model):
    """A tagged union written as a mapping with exactly one key (``- turn: {...}``, ``- gnss_outage: {...}``).

    Subclasses declare every kind as an optional field and name themselves in ``kind_label`` for the
    error message ("a fault has exactly one kind, got [...]").
    """

    kind_label: ClassVar[str] = "an entry"

    @model_validator(mode="after")
    def _exactly_one_kind(self) -> OneKindModel:
        set_keys = [k for k in type(self).model_fields if getattr(self, k) is not None]
        if len(set_keys) != 1:
            raise ValueError(f"{self.kind_label} has exactly one kind, got {set_keys or 'none'}")
        return self

    @property
    def kind(self) -> str:
        """The one key that is set."""
        for k in type(self).model_fields:
            if getattr(self, k) is not None:
                return k
        return ""

    @property
    def value(self) -> Any:
        """The parameters under that key."""
        return getattr(self, self.kind)
