"""Base models of every scenario section: unknown keys are errors."""

from __future__ import annotations

import typing
from typing import Any, ClassVar

from pydantic import BaseModel, ConfigDict, model_validator

__all__ = ["Model", "OneKindModel"]


def _model_doc(annotation: Any) -> str | None:
    """The first paragraph of the docstring of the section model a field holds (``CameraSpec | None``,
    ``list[Fault]``), or None."""
    if isinstance(annotation, type) and issubclass(annotation, BaseModel):
        doc = (annotation.__doc__ or "").strip()
        if doc and not doc.startswith(("A base", "Usage docs")):
            return " ".join(doc.split("\n\n")[0].split())
        return None
    for arg in typing.get_args(annotation):
        d = _model_doc(arg)
        if d:
            return d
    return None


class Model(BaseModel):
    """Base of every scenario section; unknown keys are errors.

    A field without its own ``description`` takes one from :data:`.descriptions.DESCRIPTIONS`, or, when it
    holds another section, that section's docstring (first paragraph), so the JSON Schema describes its
    properties (editors show the text on completion).
    """

    model_config = ConfigDict(extra="forbid", validate_assignment=False)

    @classmethod
    def __pydantic_init_subclass__(cls, **kwargs: Any) -> None:
        super().__pydantic_init_subclass__(**kwargs)
        from .descriptions import DESCRIPTIONS

        changed = False
        for name, f in cls.model_fields.items():
            if not f.description:
                d = DESCRIPTIONS.get(f"{cls.__name__}.{name}") or _model_doc(f.annotation)
                if d:
                    f.description = d
                    changed = True
        if changed:
            cls.model_rebuild(force=True)


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
