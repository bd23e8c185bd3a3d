"""The decoder fuzz in short (the long one is ``make fuzz``) and its regression corpus (tests/fuzz/corpus/)."""

from __future__ import annotations

from pathlib import Path

import pytest

from protocols.crc import nmea_checksum
from protocols.stream import StreamDecoder

from .fuzz_inputs import NMEA_DECODER_SETS, NMEA_ONLY, feed_field_case, fuzz_decoders, fuzz_fields, seed_frames

CORPUS = Path(__file__).parent / "corpus" / "nmea_hostile_fields.nmea"
GOOD = b"$GPGGA,123519.00,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*69\r\n"


def _corpus() -> list[bytes]:
    return [line + b"\r\n" for line in CORPUS.read_bytes().split(b"\r\n") if line]


def test_corpus_is_what_it_says() -> None:
    cases = _corpus()
    assert len(cases) == 66
    for c in cases:  # well framed with valid checksums: every case reaches the parser
        body = c[1 : c.rindex(b"*")]
        assert c.startswith(b"$") and c.endswith(b"\r\n")
        assert int(c[-4:-2], 16) == nmea_checksum(body)
    assert GOOD[-4:-2] == f"{nmea_checksum(GOOD[1:-5]):02X}".encode()


@pytest.mark.parametrize("decoders", sorted(NMEA_DECODER_SETS))
def test_regression_corpus_every_nmea_decoder(decoders: str) -> None:
    """Every case: no exception, counted as a parse (or length) error, the decoder advances (the good sentence comes
    out)."""
    for case in _corpus():
        for chunked in (False, True):
            dec = StreamDecoder(NMEA_DECODER_SETS[decoders]())  # type: ignore[arg-type]
            # whole, or byte by byte
            out = [o for b in case + GOOD for o in dec.feed(bytes([b]))] if chunked else dec.feed(case + GOOD)
            assert dec.pending() == 0 or decoders not in NMEA_ONLY, case
            # refused: a parse error, or a length error where a case is longer than the decoder's line limit (82)
            assert dec.stats.parse_errors + dec.stats.length_errors == 1, case
            assert dec.stats.format_faults == 0, case  # refused by the field rules, not by containment
            assert len(out) == 1 and dec.stats.frames == 1, case
            feed_field_case(dec, case, GOOD, nmea_only=decoders in NMEA_ONLY)  # again on a used decoder
            assert dec.stats.parse_errors + dec.stats.length_errors == 2


@pytest.fixture(scope="module")
def seeds() -> list[bytes]:
    return [d for v in seed_frames(2.0).values() for d in v]


@pytest.mark.parametrize("seed", [20260118, 20260119, 20260120])
def test_field_fuzz_short(seed: int, seeds: list[bytes]) -> None:
    """The hostile-field-token mutator over the three seeds of ``make fuzz``, 3 000 cases each."""
    failures: list[bytes] = []
    cases, errors = fuzz_fields(3000, seed, seeds, failures)
    assert cases == 3000
    assert errors == 0, failures[:5]


def test_byte_fuzz_short(seeds: list[bytes]) -> None:
    cases, errors = fuzz_decoders(700, 20260118, seeds)
    assert (cases, errors) == (700, 0)
