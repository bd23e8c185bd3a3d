"""HDT, THS and PASHR builders (protocols.nmea_nav) against independent parsers (pynmea2, pynmeagps) and golden
sentences, both ways: the bytes are pinned, and what the other libraries read back is what was given."""

from __future__ import annotations

import datetime as dt

import pynmea2
import pytest
from pynmeagps import NMEAReader

from protocols.nmea_nav import build_hdt, build_pashr, build_ths

GOLDEN = {
    # checksums: XOR of the bytes between $ and *, computed by hand for the first and checked by pynmea2 for all
    "hdt": (lambda: build_hdt(30.19), b"$GNHDT,30.19,T*20\r\n"),
    "ths": (lambda: build_ths(30.19, "A"), b"$GNTHS,30.19,A*22\r\n"),
    "pashr": (lambda: build_pashr(dt.time(8, 14, 2, 500000), 30.19, 0.01, 0.32, 0.0, 0.072, 0.128, 0.094, 1),
              b"$PASHR,081402.500,30.19,T,0.01,0.32,0.00,0.072,0.128,0.094,1,0*23\r\n"),
}


@pytest.mark.parametrize("name", sorted(GOLDEN))
def test_golden_sentences(name):
    build, want = GOLDEN[name]
    assert build() == want
    if name == "ths":  # pynmea2 1.19 has no THS
        assert NMEAReader.parse(want, validate=1).msgID == "THS"
    else:
        pynmea2.parse(want.decode().strip(), check=True)


def test_hdt_and_ths_read_back_by_pynmeagps_with_wrapping():
    assert float(NMEAReader.parse(build_hdt(-0.25)).headingT) == 359.75
    assert float(NMEAReader.parse(build_hdt(359.999)).headingT) == 0.0  # never "360.00"
    m = NMEAReader.parse(build_ths(725.5, "E", talker="IN"))
    assert (m.talker, float(m.headt), m.mi) == ("IN", 5.5, "E")
    assert NMEAReader.parse(build_ths(None, "V")).headt == ""
    with pytest.raises(ValueError, match="THS mode"):
        build_ths(1.0, "X")


def test_pashr_read_back_by_pynmea2_as_the_attitude_sentence():
    s = build_pashr(dt.time(23, 59, 59, 990000), 271.234, -12.345, 3.456, 0.5, 0.01, 0.02, 0.03, aiding=2,
                    imu_ok=False)
    m = pynmea2.parse(s.decode().strip(), check=True)
    assert type(m).__name__ == "ASHRATT"
    assert m.timestamp.replace(tzinfo=None) == dt.time(23, 59, 59, 990000)
    assert (m.true_heading, m.roll, m.pitch, m.heave) == (271.23, -12.35, 3.46, 0.5)  # 2 decimals, rounded
    assert (m.roll_accuracy, m.pitch_accuracy, m.heading_accuracy) == (0.01, 0.02, 0.03)
    assert (int(m.aiding_status), int(m.imu_status)) == (2, 1)
    with pytest.raises(ValueError, match="aiding"):
        build_pashr(dt.time(0), 0.0, 0.0, 0.0, aiding=3)
