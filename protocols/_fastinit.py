"""A faster ``__init__`` for the frozen, slotted frame dataclasses on the decode hot paths.

``@dataclass(frozen=True)`` generates an ``__init__`` that assigns every field through
``object.__setattr__`` (it must bypass the class's own frozen ``__setattr__``), about 0.1 us per
field on CPython 3.11. With ``slots=True`` each field is a C member descriptor whose ``__set__``
stores the value directly, at half that cost. :func:`fast_frozen_init` swaps in an ``__init__``
that calls those descriptors, so a decoded frame object costs less to build while the class
stays exactly what ``dataclass`` made it: frozen (assignment still raises
``FrozenInstanceError``), same signature and defaults, same ``__eq__``, ``__hash__``, ``__repr__``,
``dataclasses.replace`` and pickling. ``tests/protocols/test_fastinit.py`` checks all of that.

The decoders go one step further (:func:`fast_new`): a constructor derived from the same fields that builds the
object as an instance of a plain slotted *twin* class (the same ``__slots__``, so the same memory layout, but no
frozen ``__setattr__``: each field is one specialised attribute store) and then sets its ``__class__`` to the
dataclass. The result is an ordinary instance of the dataclass, equal to ``cls(*args)`` in every respect;
building it costs about half of ``cls(*args)`` (no ``type.__call__``, no descriptor call per field). A class
whose layout the twin cannot share (a dataclass base) keeps ``cls`` itself.
"""

from __future__ import annotations

import dataclasses
import types
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, TypeVar, cast

if TYPE_CHECKING:
    from _typeshed import DataclassInstance

T = TypeVar("T")

__all__ = ["fast_frozen_init", "fast_new"]

#: the constructors derived by :func:`fast_frozen_init`, by class (:func:`fast_new`)
_FAST_NEW: dict[type, Callable[..., Any]] = {}


def fast_new(cls: type[T]) -> Callable[..., T]:
    """A callable equal to ``cls`` (the same arguments, an equal instance of ``cls``) and faster for a class of
    :func:`fast_frozen_init`: the decoders' constructor (see the module docstring); ``cls`` itself otherwise."""
    return _FAST_NEW.get(cls, cls)


def _slots_twin(cls: type) -> type | None:
    """A plain class with ``cls``'s ``__slots__`` whose instances can become ``cls`` instances by ``__class__``
    assignment (the layout check is CPython's own, tried once here), or None."""
    if cls.__bases__ != (object,):
        return None
    twin = type(f"{cls.__name__}Builder", (), {"__slots__": cls.__dict__["__slots__"], "__module__": cls.__module__})
    probe: object = object.__new__(twin)
    try:
        probe.__class__ = cls
    except TypeError:  # pragma: no cover - a layout CPython will not swap
        return None
    return twin


def fast_frozen_init(cls: type[T]) -> type[T]:
    """Replace the dataclass ``__init__`` of a frozen, slotted dataclass by descriptor stores."""
    params = getattr(cls, "__dataclass_params__", None)
    if params is None or not params.frozen or "__slots__" not in cls.__dict__:
        raise TypeError(f"{cls.__name__} must be a frozen dataclass with slots=True")
    if hasattr(cls, "__post_init__"):
        raise TypeError(f"{cls.__name__} has __post_init__; the fast __init__ would skip it")
    fields = [f for f in dataclasses.fields(cast("type[DataclassInstance]", cls)) if f.init]
    ns: dict[str, object] = {}
    args = []
    for i, f in enumerate(fields):
        if f.default_factory is not dataclasses.MISSING:
            raise TypeError(f"{cls.__name__}.{f.name}: default_factory is not supported")
        if f.default is not dataclasses.MISSING:
            ns[f"_d{i}"] = f.default
            args.append(f"{f.name}=_d{i}")
        else:
            args.append(f.name)
        ns[f"_s{i}"] = cls.__dict__[f.name].__set__
    body = "".join(f"    _s{i}(self, {f.name})\n" for i, f in enumerate(fields)) or "    pass\n"
    src = f"def __init__(self, {', '.join(args)}):\n{body}"
    exec(src, ns)
    init = ns["__init__"]
    if not isinstance(init, types.FunctionType):  # pragma: no cover - exec defined it above
        raise TypeError("generated __init__ is not a function")
    init.__qualname__ = f"{cls.__qualname__}.__init__"
    init.__doc__ = cls.__init__.__doc__
    # Replacing the dataclass's __init__ is the point of this decorator (mypy refuses assignment to a method).
    cls.__init__ = init  # type: ignore[method-assign]
    twin = _slots_twin(cls)
    if twin is not None:
        # the same parameters; the fields stored on the twin, then the object made a cls instance
        ns = {k: v for k, v in ns.items() if k.startswith("_d")}
        ns.update(_new=object.__new__, _Twin=twin, _Cls=cls)
        body = "".join(f"    _o_.{f.name} = {f.name}\n" for f in fields)
        exec(f"def new({', '.join(args)}):\n    _o_ = _new(_Twin)\n{body}    _o_.__class__ = _Cls\n"
             "    return _o_\n", ns)
        new = ns["new"]
        if not isinstance(new, types.FunctionType):  # pragma: no cover - exec defined it above
            raise TypeError("generated constructor is not a function")
        new.__qualname__ = f"{cls.__qualname__}.<fast_new>"
        _FAST_NEW[cls] = new
    return cls
