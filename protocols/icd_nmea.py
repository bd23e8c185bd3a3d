"""docs/icd.md 5.1.2: what the NMEA parser (:mod:`protocols.nmea`) parses, what the firmware uses, what is only
counted; and the field rules by which a sentence is refused (a parse error) or a value read as absent.

Kept apart from :mod:`protocols.icd` (which writes it after 5.1.1) so that the parser's rules and the firmware's
use of fields are edited in different places."""

from __future__ import annotations

from . import nmea

#: docs/icd.md 5.1.2, written by :func:`protocols.icd.generate`.
NMEA_PARSE_TEXT = f"""#### 5.1.2 NMEA sentences: parsed, used, counted

What `protocols.nmea.NmeaFormat` makes of each sentence with a good checksum (the firmware's `uart3`, the
monitor's and the emulated u-blox's decoders: lines up to `NMEA_RX_MAX_LEN` = {nmea.NMEA_RX_MAX_LEN} characters;
82 elsewhere), and which of them the firmware uses (5.1.1 says how). A refused sentence is one `parse_errors`
of its decoder, never an exception (`DecoderStats.format_faults` counts any exception a parser raised besides
its refusals: 0 unless a parser meets a case nobody foresaw). Tests: `tests/protocols/test_nmea_fields.py`,
`tests/protocols/test_receiver_corpus.py`, `tests/fuzz/test_decoder_fuzz.py`.

| sentence | parsed as | used by the firmware | otherwise |
|---|---|---|---|
| GGA | `Gga`: time, position, quality, satellites, HDOP, MSL altitude, geoid separation | yes (5.1.1) | - |
| GNS (NMEA 3.0/4.10) | `Gns`: time, position, mode per constellation, satellites, HDOP, altitude, separation, \
status | yes | - |
| RMC | `Rmc`: time, status, position, speed, course, date, mode, 4.10 status | yes | - |
| GSA | `Gsa`: mode, fix type, 12 satellite slots, PDOP/HDOP/VDOP, 4.10 system id | fix type | - |
| ZDA | `Zda`: time, day, month, year, zone | date and time (5.1.3) | - |
| GST | `Gst`: time, range RMS, error ellipse (semi-major, semi-minor, orientation), latitude, longitude and \
altitude error (m, 1 sigma) | time (it opens an epoch, 5.1.3); the latitude and longitude errors widen the fix's \
sigmas (D-5.51) | - |
| VTG, GSV | `Vtg`, `Gsv` | no | `gnss_nmea_other` |
| GBS, GRS, GLL | `NmeaSentence` (talker, kind, raw fields) | time only: they open an epoch (5.1.3) | - |
| any other `$ttsss` (TXT ...) | `NmeaSentence` (talker, kind, raw fields) | no | `gnss_nmea_other` |
| proprietary `$P` + maker, whatever the length (`$PGRME`, `$PUBX`, `$PMTKCHN` 204 characters, \
`$PSRFTXTVersion GSW3.2.2 ...` with spaces and \
no comma) | `NmeaSentence`, talker `P` + maker code, kind the rest of the address as sent | no | `gnss_nmea_other` |
| another upper-case address of 3..10 characters (`$LOG108` of the RGM-3800) | `NmeaSentence`, talker `""`, \
kind the address | no | `gnss_nmea_other` |
| an address of other characters, non-ASCII bytes | refused | - | `parse_errors` |
| a line of more than 128 characters with a byte that is not printable ASCII (or a `$`) | refused at its 128th \
byte, as when 128 was the limit: a stray `$` before binary UBX does not hold the UBX frames back | - | \
`length_errors` |

Field rules (every typed sentence):

| field | accepted | refused (`parse_errors`) or read as absent |
|---|---|---|
| trailing fields omitted (`$GPGGA,130711,5012.790800,N,00806.879600,W,2,,,,,,,`: 13 fields; \
`$GPGSA,A,1,,,,`; ZDA without the zone) | the omitted fields are None | - |
| time `hhmmss[.s...]` | six ASCII digits, then `.` and digits or nothing; hh < 24, mm < 60, ss < 61; second \
60 (a leap second) held at hh:mm:59.999999; fractions cut at the microsecond | anything else (`hhmminf`, \
`hhmm1e300`, 40 nines, a sign, an exponent): refused |
| RMC date `ddmmyy` | six ASCII digits of a real date, read as 20yy (which century, and whether it is believed, \
is the firmware's business: 5.1.1) | refused |
| ZDA day, month, year, zone | day 1..31 and a real date, month 1..12, a four-digit year, zone hours -13..13, \
minutes 0..59 | refused; a date with one or two of its three fields empty: refused |
| position with a fix (GGA quality > 0, RMC `A`, GNS mode not all `N`) | `ddmm.mmmm` with minutes < 60 and hemisphere \
N/S/E/W; out-of-range degrees are passed on for the firmware to refuse and count | malformed: refused |
| position without a fix (GGA quality 0, RMC `V`, GNS mode `N`) | kept when it is well formed and in range | \
placeholders (`36000.0000,N,72000.0000,E`, `8960.0000,N`) and malformed values: read as absent (None); the \
sentence's time and date are kept |
| GST statistics | empty (None), or a finite number >= 0 (the orientation any finite number, taken modulo 360); the \
firmware refuses latitude and longitude errors above 10 km (`input_rejected_gst_range`) and reads a zero as no \
estimate | `inf`, `nan`, a negative standard deviation: refused |
| GSA 18th field | one hex digit 1..F: the NMEA 4.10 system id | anything else (`...,4.9,3.3`): not read |
| GSV satellite block | PRN, elevation, azimuth, C/N0 (empty: None); a last block cut short is padded | a block \
with an empty PRN (`$GPGSV,3,1,00,,,,,,,,,,,,,,,,`) is skipped |

"""
