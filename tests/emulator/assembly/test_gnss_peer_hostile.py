"""A GNSS peer on a pty that sends the sentences which once raised OverflowError out of the decoders
(tests/fuzz/corpus/) between good epochs leaves the run alive (issue 41 item 1): the firmware counts each as a
parse error on UART3 and keeps taking the peer's fixes; the recorder's GNSS tap counts them too."""

from __future__ import annotations

import datetime as dt
import os
from pathlib import Path

import pytest

from emulator.testing import start_emulator
from protocols.nmea import build_gga, build_rmc
from tests.conftest import SCENARIOS

CORPUS = Path(__file__).resolve().parents[2] / "fuzz" / "corpus" / "nmea_hostile_fields.nmea"
QS = SCENARIOS / "quickstart.yaml"


def _epoch(k: int) -> bytes:
    t = dt.time(2, 30, k)
    return (build_gga(t, 39.979, 116.339, 50.0, -8.0, quality=1, num_sats=9, hdop=0.9)
            + build_rmc(t, dt.date(2019, 9, 18), 39.979, 116.339, 0.0, 0.0))


@pytest.mark.pty
@pytest.mark.realtime
@pytest.mark.psns_emulator(mode="realtime")
async def test_a_gnss_peer_sending_hostile_sentences_is_counted(tmp_path: Path) -> None:
    cases = [c + b"\r\n" for c in CORPUS.read_bytes().split(b"\r\n") if c][:12]
    ov = {"duration_s": 6.0, "motion": [{"static": {"duration_s": 6.0}}], "expectations": [], "links.psns": None,
          "sensors.camera": None, "firmware.alignment.heading_source": "config",
          "firmware.alignment.heading_deg": 30.0, "links.gnss.url": "pty://gnss"}
    async with start_emulator(QS, run_dir=tmp_path, overrides=ov) as emu:
        fd = os.open(tmp_path / "ports" / "gnss", os.O_RDWR | os.O_NOCTTY)
        try:
            for k in range(1, 5):  # one epoch a second, hostile sentences in front of each
                await emu.run_for(1.0 if k > 1 else 0.05)
                os.write(fd, b"".join(cases[3 * (k - 1): 3 * k]) + _epoch(k))
            await emu.run_for(1.2)
            dec = emu.fw.decoder_stats()["uart3"]
        finally:
            os.close(fd)
    assert dec["parse_errors"] == 12 and dec["format_faults"] == 0
    assert dec["per_format"]["nmea"] == 8  # every GGA and RMC of the peer's epochs
    assert (tmp_path / "summary.json").is_file()
