"""The emulated receiver's geoid (EGM96 from proj-data's 15' grid) against PROJ's own interpolation (pyproj), and
the separation the receiver reports."""

from __future__ import annotations

import asyncio
import datetime as dt

import numpy as np
import pytest
from pyproj import Transformer

from emulator.clock import EmulatorLoop
from emulator.devices.geoid import _grid_path, egm96_separation_m
from emulator.devices.gnss import GnssConfig, GnssErrors, GnssReceiver
from emulator.links import LineConfig, MemHub
from emulator.world.trajectory import StaticTrajectory
from protocols.nmea import Gga, NmeaFormat
from protocols.stream import StreamDecoder

EPOCH = dt.datetime(2019, 9, 18, 8, 14, tzinfo=dt.UTC)
QUIET = GnssErrors(pos_sigma_h_m=0.0, pos_sigma_v_m=0.0, vel_sigma_h_mps=0.0, vel_sigma_v_mps=0.0)


def test_egm96_reader_matches_proj_vgridshift() -> None:
    """Our GTX reader and bilinear interpolation equal PROJ's vgridshift on the same grid (2000 random points)."""
    proj = Transformer.from_pipeline(f"+proj=vgridshift +grids={_grid_path()} +multiplier=1")
    rng = np.random.default_rng(1)
    for lat, lon in zip(rng.uniform(-89.9, 89.9, 2000), rng.uniform(-180.0, 180.0, 2000), strict=True):
        assert egm96_separation_m(lat, lon) == pytest.approx(proj.transform(lon, lat, 0.0)[2], abs=1e-6)


def test_egm96_known_extremes() -> None:
    """The EGM96 low south of India (about -106 m) and the high over New Guinea (about +85 m)."""
    assert -108.0 < egm96_separation_m(4.75, 78.75) < -104.0
    assert 83.0 < egm96_separation_m(-8.0, 147.0) < 86.0


def _receiver_bytes(cfg: GnssConfig, lat: float, lon: float, h: float) -> bytes:
    """What the emulated receiver sends over 2.5 s of the emulator's clock, standing at (lat, lon, h)."""
    loop = EmulatorLoop("fast")
    a, b = MemHub().pair("gnss", LineConfig(baud=115200), loop)
    rx = GnssReceiver(a, StaticTrajectory(lat, lon, h), EPOCH, np.random.default_rng(1), cfg)
    raw = bytearray()
    b.on_receive = raw.extend

    async def main() -> None:
        rx.start()
        await asyncio.sleep(2.5)

    loop.run_until_complete(main())
    loop.close()
    return bytes(raw)


def _gga(cfg: GnssConfig, lat: float, lon: float, h: float) -> list[Gga]:
    return [f for f in StreamDecoder([NmeaFormat()]).feed(_receiver_bytes(cfg, lat, lon, h)) if isinstance(f, Gga)]


@pytest.mark.parametrize(("lat", "lon"), [(6.0, 77.0), (-8.0, 147.0), (55.0, -20.0)])
def test_the_receiver_reports_the_egm96_separation(lat: float, lon: float) -> None:
    """GGA carries N from EGM96 at the position and the height above MSL h - N (no longer a separation of 0)."""
    n = egm96_separation_m(lat, lon)
    assert abs(n) >= 30.0
    ggas = _gga(GnssConfig(sentences=("GGA",), errors=QUIET), lat, lon, 100.0)
    assert len(ggas) == 3
    for g in ggas:
        assert g.geoid_sep_m == pytest.approx(n, abs=6e-4)
        assert g.altitude_msl_m == pytest.approx(100.0 - n, abs=6e-4)


def test_an_empty_separation_field_and_a_fixed_one() -> None:
    lat, lon = 6.0, 77.0
    ggas = _gga(GnssConfig(sentences=("GGA",), errors=QUIET, geoid_sep_field="empty"), lat, lon, 100.0)
    assert ggas and all(g.geoid_sep_m is None for g in ggas)
    assert ggas[0].altitude_msl_m == pytest.approx(100.0 - egm96_separation_m(lat, lon), abs=6e-4)
    ggas = _gga(GnssConfig(sentences=("GGA",), errors=QUIET, geoid_sep_m=-8.5), lat, lon, 100.0)
    assert ggas[0].geoid_sep_m == -8.5 and ggas[0].altitude_msl_m == pytest.approx(108.5, abs=6e-4)


def test_the_legacy_ubx_set_decodes_in_ours_and_pyubx2() -> None:
    """The emulated u-blox 6 set (NAV-SOL, NAV-POSLLH, NAV-VELNED, NAV-TIMEUTC, NAV-TIMEGPS, NAV-STATUS): every
    frame decodes here and in pyubx2, with the same values."""
    import io

    from pyubx2 import UBXReader

    from protocols.ubx import NavPosllh, NavSol, UbxFormat

    legacy = ("NAV-SOL", "NAV-POSLLH", "NAV-VELNED", "NAV-TIMEUTC", "NAV-TIMEGPS", "NAV-STATUS")
    raw = _receiver_bytes(GnssConfig(sentences=(), ubx=legacy, errors=QUIET), 39.979, 116.339, 50.0)
    dec = StreamDecoder([UbxFormat()])
    ours = dec.feed(raw)
    assert len(ours) == 3 * len(legacy) and dec.stats.crc_errors == 0 and dec.stats.garbage_bytes == 0
    peer = [m for _, m in UBXReader(io.BytesIO(bytes(raw)), protfilter=2)]
    assert [m.identity for m in peer[: len(legacy)]] == list(legacy)
    pos = next(o for o in ours if isinstance(o, NavPosllh))
    ppos = next(m for m in peer if m.identity == "NAV-POSLLH")
    assert ppos.lat == pytest.approx(pos.lat * 1e-7) and ppos.height == pos.height == 50000
    sol = next(o for o in ours if isinstance(o, NavSol))
    psol = next(m for m in peer if m.identity == "NAV-SOL")
    assert (psol.ecefX, psol.ecefY, psol.ecefZ, psol.numSV) == (sol.ecefX, sol.ecefY, sol.ecefZ, sol.numSV)
    tu = next(m for m in peer if m.identity == "NAV-TIMEUTC")
    assert (tu.year, tu.month, tu.day, tu.hour, tu.min, tu.sec, tu.validUTC) == (2019, 9, 18, 8, 14, 0, 1)
    tg = next(m for m in peer if m.identity == "NAV-TIMEGPS")
    assert tg.leapS == 18 and tg.leapSValid == 1
