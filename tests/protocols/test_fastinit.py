"""The fast __init__ of the frame dataclasses keeps every dataclass behaviour."""

import copy
import dataclasses
import pickle

import pytest

from protocols._fastinit import fast_frozen_init, fast_new
from protocols.nmea import Gga
from protocols.stim import StimDatagram


def test_behaves_like_the_generated_dataclass():
    g = Gga("GP", None, 1.0, 2.0, 1, 12, 0.8, 50.0, -8.5)
    assert g == Gga(talker="GP", time_utc=None, lat_deg=1.0, lon_deg=2.0, quality=1, num_sats=12, hdop=0.8,
                    altitude_msl_m=50.0, geoid_sep_m=-8.5)
    assert hash(g) == hash(copy.copy(g)) and pickle.loads(pickle.dumps(g)) == g
    assert dataclasses.replace(g, quality=2).quality == 2
    assert repr(g).startswith("Gga(talker='GP'")
    with pytest.raises(dataclasses.FrozenInstanceError):
        g.quality = 5  # type: ignore[misc]
    with pytest.raises(TypeError):
        Gga("GP")  # type: ignore[call-arg]
    d = StimDatagram(0x90, (1, 2, 3), 0)  # defaults kept
    assert d.counter is None and d.reserved is None
    assert StimDatagram(0x90, (1, 2, 3), 0, counter=5).counter == 5


def test_refuses_classes_it_cannot_speed_up():
    @dataclasses.dataclass
    class Mutable:
        x: int

    with pytest.raises(TypeError):
        fast_frozen_init(Mutable)

    @dataclasses.dataclass(frozen=True, slots=True)
    class WithPost:
        x: int

        def __post_init__(self) -> None:
            pass

    with pytest.raises(TypeError):
        fast_frozen_init(WithPost)


def _fast_init_classes() -> list[type]:
    """Every class of the protocols package that :func:`fast_frozen_init` decorated (its ``__init__`` generated)."""
    import importlib
    import pkgutil

    import protocols

    found: dict[str, type] = {}
    for mod in pkgutil.iter_modules(protocols.__path__):
        m = importlib.import_module(f"protocols.{mod.name}")
        for obj in vars(m).values():
            # the generated __init__ stores each field through its descriptor, _s0 the first one's __set__
            if isinstance(obj, type) and dataclasses.is_dataclass(obj) and obj.__module__ == m.__name__ \
                    and "_s0" in getattr(obj.__init__, "__globals__", {}):
                found[f"{obj.__module__}.{obj.__qualname__}"] = obj
    return [found[k] for k in sorted(found)]


FAST_INIT_CLASSES = _fast_init_classes()


def _args(cls: type, salt: int) -> list[object]:
    """One distinct value per required field (a fresh object each, so identity is checked too)."""
    return [(salt, i, f.name) for i, f in enumerate(dataclasses.fields(cls))
            if f.default is dataclasses.MISSING]


def test_every_decoded_frame_class_has_a_fast_constructor():
    assert len(FAST_INIT_CLASSES) >= 30  # the frame classes of every format
    assert [c.__name__ for c in FAST_INIT_CLASSES if fast_new(c) is c] == []


@pytest.mark.parametrize("cls", FAST_INIT_CLASSES, ids=lambda c: c.__qualname__)
def test_fast_new_builds_what_the_class_builds(cls):
    new = fast_new(cls)
    for salt in range(2):
        args = _args(cls, salt)
        a, b = new(*args), cls(*args)
        assert type(a) is cls and a == b and repr(a) == repr(b) and hash(a) == hash(b)
        for f in dataclasses.fields(cls):  # the same objects, defaults included
            assert getattr(a, f.name) is getattr(b, f.name)
        assert pickle.loads(pickle.dumps(a)) == b and copy.copy(a) == b
        first = dataclasses.fields(cls)[0].name
        assert getattr(dataclasses.replace(a, **{first: "x"}), first) == "x"
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(a, first, 0)
    # keywords and defaults as the class takes them; the same refusals
    kw = {f.name: (9, f.name) for f in dataclasses.fields(cls)}
    assert new(**kw) == cls(**kw)
    with pytest.raises(TypeError):
        new(*_args(cls, 0), *range(len(dataclasses.fields(cls)) + 1))


def test_a_class_whose_layout_cannot_be_shared_keeps_its_own_constructor():
    class Base:
        __slots__ = ()

    @fast_frozen_init
    @dataclasses.dataclass(frozen=True, slots=True)
    class Derived(Base):
        x: int

    assert fast_new(Derived) is Derived and Derived(3).x == 3

    @fast_frozen_init
    @dataclasses.dataclass(frozen=True, slots=True)
    class Plain:
        x: int
        y: tuple[int, ...] = (1,)

    assert fast_new(Plain) is not Plain and fast_new(Plain)(3) == Plain(3, (1,))
    assert fast_new(int) is int  # not decorated: the class itself
