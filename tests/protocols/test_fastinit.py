"""The fast __init__ of the frame dataclasses keeps every dataclass behaviour."""

import copy
import dataclasses
import pickle

import pytest

from protocols._fastinit import fast_frozen_init
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
