"""Real receiver output (tests/protocols/corpus/receivers/, README there: provenance and licences) decodes with zero
errors wherever the independent parsers accept a message (issue 37 items 6 and 7).

Oracles: pynmeagps (``NMEAReader.parse`` with checksum validation) for every ``$...*hh`` line, pyubx2
(``UBXReader``, UBX only) for every UBX frame. Each accepted message must come out of our decoder as one frame with
no error counted, alone and within the whole file (the GNSS port's decoder: NMEA up to ``NMEA_RX_MAX_LEN`` and UBX).
"""

from __future__ import annotations

import io
import re
from pathlib import Path

import pytest
from pynmeagps import VALCKSUM, NMEAReader
from pyubx2 import UBX_PROTOCOL, UBXReader

from protocols.nmea import NMEA_RX_MAX_LEN, Gga, Gsa, Gsv, NmeaFormat, NmeaSentence, Rmc
from protocols.stream import StreamDecoder
from protocols.ubx import UbxFormat

CORPUS = Path(__file__).parent / "corpus" / "receivers"
FILES = sorted(CORPUS.glob("*.log"))
#: a sentence with its checksum, printable ASCII between '$' and '*'
SENTENCE = re.compile(rb"\$[\x20-\x7e]*?\*[0-9A-Fa-f]{2}\r?\n")


def nmea_accepted(data: bytes) -> list[bytes]:
    out = []
    for m in SENTENCE.finditer(data):
        try:
            NMEAReader.parse(m.group(0), validate=VALCKSUM)
        except Exception:  # the oracle refuses it: no demand on our decoder
            continue
        out.append(m.group(0))
    return out


def ubx_accepted(data: bytes) -> list[bytes]:
    return [raw for raw, _parsed in UBXReader(io.BytesIO(data), protfilter=UBX_PROTOCOL, quitonerror=0)
            if raw is not None]


def test_corpus_is_small_and_documented() -> None:
    assert len(FILES) >= 20
    assert sum(f.stat().st_size for f in FILES) < 300_000
    readme = (CORPUS / "README.md").read_text()
    for f in FILES:
        assert f.name in readme, f"{f.name}: provenance and licence missing from the README"


@pytest.mark.parametrize("path", FILES, ids=[f.name for f in FILES])
def test_every_message_the_oracles_accept_decodes(path: Path) -> None:
    data = path.read_bytes()
    sentences, frames = nmea_accepted(data), ubx_accepted(data)
    assert sentences or frames
    for s in sentences:
        dec = StreamDecoder([NmeaFormat(NMEA_RX_MAX_LEN)])
        assert len(dec.feed(s)) == 1, (s, dec.stats)
    for raw in frames:
        dec = StreamDecoder([UbxFormat()])
        assert len(dec.feed(raw)) == 1, (raw[:8].hex(), dec.stats)
    # the whole file through the GNSS port's decoder, in one piece and in 7-byte chunks
    for chunk in (len(data), 7):
        dec = StreamDecoder([NmeaFormat(NMEA_RX_MAX_LEN), UbxFormat()])
        out = [o for i in range(0, len(data), chunk) for o in dec.feed(data[i : i + chunk])]
        st = dec.stats
        assert st.parse_errors == 0 and st.format_faults == 0, st
        assert st.per_format["nmea"] >= len(sentences) and st.per_format["ubx"] >= len(frames), st
        assert len(out) == st.frames


def _decode_lines(*lines: bytes) -> list[object]:
    dec = StreamDecoder([NmeaFormat(NMEA_RX_MAX_LEN)])
    out = dec.feed(b"".join(lines))
    assert dec.stats.parse_errors == 0 and dec.stats.crc_errors == 0 and len(out) == len(lines), dec.stats
    return out


def test_the_sentences_of_issue_37() -> None:
    """The valid sentences real receivers send that were counted as errors (checksums checked by the oracle)."""
    lines = (
        b"$GPGSV,3,1,00,,,,,,,,,,,,,,,,*7B\r\n",
        b"$GPGGA,130711,5012.790800,N,00806.879600,W,2,,,,,,,*6A\r\n",
        b"$GPGSA,A,1,,,,*32\r\n",
        b"$PSRFTXTVersion GSW3.2.2_3.1.00.12-SDK003P1.01a *78\r\n",  # gpsd test/daemon/blumax-gps009.log
        b"$LOG108,4,-1,-1,1,0,1,0,15,285*5E\r\n",  # RGM-3800 (gpsd test/daemon/rgm3800.log form)
        b"$GPRMC,071732.929,V,8960.0000,N,00000.0000,E,0.00,0.00,111111,,,N*73\r\n",  # gpsd tr737A+.log
        b"$GPGGA,071733.929,8960.0000,N,00000.0000,E,0,0,,137.0,M,13.0,M,,*40\r\n",
    )
    for s in lines:
        NMEAReader.parse(s, validate=VALCKSUM)  # the oracle accepts each
    o = _decode_lines(*lines)
    assert isinstance(o[0], Gsv) and o[0].sats == () and o[0].num_sv == 0
    assert isinstance(o[1], Gga) and o[1].quality == 2 and o[1].lat_deg == pytest.approx(50 + 12.7908 / 60)
    assert o[1].num_sats is None and o[1].altitude_msl_m is None and o[1].geoid_sep_m is None
    assert isinstance(o[2], Gsa) and o[2].fix_type == 1 and o[2].pdop is None and o[2].sat_ids == (None,) * 12
    assert isinstance(o[3], NmeaSentence) and o[3].talker == "PSRF" and o[3].kind.startswith("TXTVersion GSW3.2.2")
    assert isinstance(o[4], NmeaSentence) and o[4].kind == "LOG108" and o[4].fields[0] == "4"
    # no-fix placeholders: position absent, time and date kept
    assert isinstance(o[5], Rmc) and not o[5].valid and o[5].lat_deg is None and o[5].lon_deg is None
    assert str(o[5].date) == "2011-11-11" and str(o[5].time_utc) == "07:17:32.929000"
    assert isinstance(o[6], Gga) and o[6].quality == 0 and o[6].lat_deg is None and str(o[6].time_utc) == \
        "07:17:33.929000"


def test_placeholder_36000_and_an_18th_gsa_field() -> None:
    from protocols.crc import nmea_checksum

    def s(body: str) -> bytes:
        return f"${body}*{nmea_checksum(body.encode()):02X}\r\n".encode()

    rmc, gga, gsa = _decode_lines(
        s("GPRMC,000214.991,V,36000.0000,N,72000.0000,E,,,270102,,"),
        s("GPGGA,000215.990,36000.0000,N,72000.0000,E,0,00,50.0,0.0,M,,M,,0000"),
        s("GPGSA,A,3,04,05,,09,12,,,24,,,,,5.1,1.3,4.9,3.3"))
    assert isinstance(rmc, Rmc) and rmc.lat_deg is None and rmc.date is not None and str(rmc.date) == "2002-01-27"
    assert isinstance(gga, Gga) and gga.lat_deg is None and gga.lon_deg is None and gga.time_utc is not None
    assert isinstance(gsa, Gsa) and gsa.system_id is None and (gsa.pdop, gsa.hdop, gsa.vdop) == (5.1, 1.3, 4.9)
    # with a fix, a placeholder is not a position: refused when malformed, passed on (for the firmware) when not
    dec = StreamDecoder([NmeaFormat(NMEA_RX_MAX_LEN)])
    assert dec.feed(s("GPRMC,000214.991,A,8960.0000,N,00000.0000,E,,,270102,,")) == []
    assert dec.stats.parse_errors == 1


def test_a_pmtkchn_of_204_characters() -> None:
    data = (CORPUS / "gpsd-mtk-3301.log").read_bytes()
    chn = [m.group(0) for m in SENTENCE.finditer(data) if m.group(0).startswith(b"$PMTKCHN")]
    assert chn and max(len(c) for c in chn) > 128
    for c in chn:
        (o,) = _decode_lines(c)
        assert isinstance(o, NmeaSentence) and o.talker == "PMTK" and o.kind == "CHN"
