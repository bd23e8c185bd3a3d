"""The recorder's taps are contained (issue 41 item 2): the NMEA sentences that once raised OverflowError out of the
decoders (tests/fuzz/corpus/), on a counting tap and on the navigation port's tap (host frames and NMEA text), never
raise; each is counted as an error and the frames after it are still decoded."""

from __future__ import annotations

from pathlib import Path

from emulator.clock import EmulatorLoop
from emulator.links import LineConfig, MemHub
from emulator.recording.recorder import Recorder
from emulator.world.trajectory import StaticTrajectory
from protocols.host import HostFormat, NavMode, NavSolution, encode_host
from protocols.nmea import NMEA_RX_MAX_LEN, NmeaFormat
from protocols.ubx import UbxFormat

CORPUS = Path(__file__).resolve().parents[2] / "fuzz" / "corpus" / "nmea_hostile_fields.nmea"
GOOD = b"$GPGGA,123519.00,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*69\r\n"


def _nav(k: int) -> NavSolution:
    return NavSolution(seq=k, time_s=0.01 * k, lat_deg=39.98, lon_deg=116.34, height_m=50.0,
                       vel_enu_mps=(0.0, 0.0, 0.0), roll_deg=0.0, pitch_deg=0.0, heading_deg=1.0, sigma=(0.1,) * 9,
                       mode=int(NavMode.NAVIGATING), gnss_status=1, psns_status=0, cpu_load_pct=0.2,
                       deadline_misses=0)


def test_hostile_sentences_on_every_tap_are_counted(tmp_path: Path) -> None:
    cases = [c + b"\r\n" for c in CORPUS.read_bytes().split(b"\r\n") if c]
    loop = EmulatorLoop("fast")
    gnss, _peer = MemHub().pair("gnss", LineConfig(baud=115200), loop)
    host, _peer2 = MemHub().pair("host", LineConfig(baud=115200), loop)
    rec = Recorder(tmp_path / "run", StaticTrajectory(39.98, 116.34, 50.0))
    rec.tap("gnss", gnss, {"out": [NmeaFormat(NMEA_RX_MAX_LEN), UbxFormat()]})
    rec.tap("host", host, {"out": [HostFormat(), NmeaFormat()]})
    rec.start({"scenario": "test"})
    for k, c in enumerate(cases):
        rec.on_bytes("gnss", "out", 0.01 * k, c + GOOD)
        rec.on_bytes("host", "out", 0.01 * k, c + encode_host(_nav(k)))
    summary = rec.link_summary()
    assert summary["gnss"]["frames"] == len(cases)  # every good sentence after a hostile one
    assert summary["host"]["frames"] == len(cases)
    assert rec.nav_count == len(cases)
    for name in ("gnss", "host"):
        st = rec._taps[name].decoders["out"].stats
        assert st.parse_errors + st.length_errors == len(cases) and st.format_faults == 0, (name, st)
    rec.close()
    loop.close()
