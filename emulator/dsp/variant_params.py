"""The filter variants' parameters, declared once by the firmware and read twice by the emulator.

:mod:`firmware_model.variants.params` declares every variant parameter with its default and its bounds
(:func:`firmware_model.variants.params.param`). From those declarations this module

- writes the scenario's ``firmware.variants`` section, ``emulator/scenario/variants_schema.py`` (pydantic models:
  same names, defaults, ranges and descriptions): ``python -m emulator.dsp.variant_params`` regenerates it,
  ``--check`` says whether it is current (``tests/emulator/dsp/test_variant_params.py`` runs the check);
- turns a validated section back into :class:`firmware_model.variants.params.VariantParams`
  (:func:`variant_params`), field by field by name, with no list of fields of its own.

The schema is generated as source, not built at import time, because the scenario layer sits below the world and
the sensors, which never import the firmware (the independence rule, ``[tool.importlinter]`` in pyproject.toml):
the generated module imports only pydantic and the scenario's base model (D-8.11, docs/decisions/scenarios.md).
"""

from __future__ import annotations

import argparse
import json
import sys
import types
import typing
from dataclasses import MISSING, fields
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal, get_args, get_origin, get_type_hints

from firmware_model.variants import params as _params
from firmware_model.variants.params import VariantParams, bounds_of

if TYPE_CHECKING:  # the generated module is this module's output: it is not needed to write it
    from ..scenario.variants_schema import VariantsSpec

__all__ = ["GENERATED", "main", "render", "sections", "spec_name", "variant_params"]

#: the generated scenario module
GENERATED = Path(__file__).resolve().parents[1] / "scenario" / "variants_schema.py"


def sections() -> dict[str, type]:
    """``firmware.variants`` key -> the parameter dataclass it holds, in declaration order (``plugins`` is not a
    section: a plugin's parameters are validated against its own model, ``firmware.params``)."""
    hints = get_type_hints(VariantParams, vars(_params))
    return {f.name: hints[f.name] for f in fields(VariantParams) if f.name != "plugins"}


def spec_name(cls: type) -> str:
    """The scenario model's name for a parameter dataclass: ``KmeansParams`` -> ``KmeansSpec``."""
    return cls.__name__.removesuffix("Params") + "Spec"


def _literal(v: Any) -> str:
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, tuple):
        return "[" + ", ".join(_literal(x) for x in v) + "]"
    return repr(v)


def _type(tp: Any) -> str:
    """Source text of a parameter's type in the scenario model (a tuple of any length is a YAML list)."""
    if tp is type(None):
        return "None"
    if tp in (bool, int, float, str):
        return str(tp.__name__)
    origin, args = get_origin(tp), get_args(tp)
    if origin in (typing.Union, types.UnionType):
        return " | ".join(_type(a) for a in args)
    if origin is Literal:
        return "Literal[" + ", ".join(_literal(a) for a in args) + "]"
    if origin is tuple:
        if len(args) == 2 and args[1] is Ellipsis:
            return f"list[{_type(args[0])}]"
        return "tuple[" + ", ".join(_type(a) for a in args) + "]"
    raise TypeError(f"no scenario type for the parameter type {tp!r}")


def _field(name: str, tp: Any, f: Any) -> str:
    b = bounds_of(f)
    ann = _type(tp)
    ignore = ""
    if b.choices is not None:  # floats in Literal: pydantic validates them as an enum; typing allows none there
        ann = "Literal[" + ", ".join(_literal(c) for c in b.choices) + "]"
        ignore = "  # type: ignore[valid-type]"
    if f.default is MISSING:
        raise TypeError(f"parameter {name} has no default")
    args = [_literal(f.default)]
    if ann.startswith("list[") and isinstance(f.default, tuple):  # a fresh list per model; str literals: see below
        args = [f"default_factory=lambda: {_literal(f.default)}"]
        ignore = "  # type: ignore[arg-type]"  # mypy infers list[str] for the lambda's list of Literal strings
    for key in ("ge", "gt", "le", "lt"):
        v = getattr(b, key)
        if v is not None:
            args.append(f"{key}={v!r}")
    if b.min_items is not None:
        args.append(f"min_length={b.min_items}")
    if b.description is not None:
        args.append(f"description={json.dumps(b.description)}")
    return f"    {name}: {ann} = Field({', '.join(args)}){ignore}\n"


def render() -> str:
    """The source of ``emulator/scenario/variants_schema.py`` from the firmware's declarations."""
    secs = sections()
    names = sorted([spec_name(c) for c in secs.values()] + ["VariantsSpec"])
    out = ['"""The scenario section ``firmware.variants``: GENERATED from firmware_model/variants/params.py by\n',
           "``python -m emulator.dsp.variant_params``; do not edit (the declarations, their defaults and bounds are\n",
           "there; tests/emulator/dsp/test_variant_params.py fails when this file is stale). Only the selected\n",
           'variant reads its own section (docs/variants.md)."""\n',
           "# ruff: noqa: E501\n\n",
           "from __future__ import annotations\n\n",
           "from typing import Literal\n\n",
           "from pydantic import Field\n\n",
           "from .base import Model\n\n",
           "__all__ = [" + ", ".join(json.dumps(n) for n in names) + "]\n"]
    for cls in secs.values():
        hints = get_type_hints(cls, vars(sys.modules[cls.__module__]))
        out.append(f"\n\nclass {spec_name(cls)}(Model):\n")
        out.append(f"    # {cls.__module__}.{cls.__name__}\n")
        out.extend(_field(f.name, hints[f.name], f) for f in fields(cls))
    out.append("\n\nclass VariantsSpec(Model):\n")
    out.extend(f"    {key}: {spec_name(cls)} = {spec_name(cls)}()\n" for key, cls in secs.items())
    return "".join(out)


def variant_params(spec: VariantsSpec, plugins: dict[str, Any] | None = None) -> VariantParams:
    """A validated ``firmware.variants`` section as the firmware's :class:`VariantParams` (lists become tuples);
    ``plugins``: the parameters of a filter added by entry point, by filter name."""
    groups: dict[str, Any] = {}
    for key, cls in sections().items():
        values = getattr(spec, key).model_dump()
        groups[key] = cls(**{k: tuple(v) if isinstance(v, list) else v for k, v in values.items()})
    return VariantParams(**groups, plugins=dict(plugins or {}))


def main(argv: list[str] | None = None) -> int:
    """Write the generated module (or, with ``--check``, exit 1 when it is stale)."""
    ap = argparse.ArgumentParser(prog="python -m emulator.dsp.variant_params", description=__doc__.split("\n")[0])
    ap.add_argument("--check", action="store_true", help="exit 1 when the generated module is stale")
    args = ap.parse_args(argv)
    text = render()
    if args.check:
        current = GENERATED.read_text(encoding="utf-8") if GENERATED.exists() else ""
        if current != text:
            print(f"{GENERATED} is stale: run python -m emulator.dsp.variant_params", file=sys.stderr)
            return 1
        return 0
    GENERATED.write_text(text, encoding="utf-8")
    print(f"wrote {GENERATED}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
