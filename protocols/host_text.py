"""Host port text output for terminal users: the ``$PSNS...`` sentences (NMEA 0183 framing and checksum).

The proprietary sentences ``$PSNSPOS`` (time, position, mode), ``$PSNSVEL`` (time, ENU velocity), ``$PSNSATT``
(time, roll, pitch, heading) and ``$PSNSSTA`` (time, variant, rate, CPU load, misses) render one
:class:`~protocols.host.NavSolution` on the same port as the binary frames (:mod:`protocols.host`, which
re-exports this module's names). Each stays under 82 characters.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from ._fastinit import fast_frozen_init
from .nmea import NmeaFormat, NmeaSentence, build_sentence, encode_nmea

if TYPE_CHECKING:
    from .host import NavSolution

__all__ = ["TEXT_SENTENCES", "HostTextFormat", "NavText", "encode_nav_text", "nav_text_sentences"]

#: ``FilterVariant.BASE`` (:mod:`protocols.host`), the default variant of the ``$PSNSSTA`` sentence.
_BASE_VARIANT = 1


@fast_frozen_init
@dataclass(frozen=True, slots=True)
class NavText:
    """One decoded ``$PSNS...`` sentence: ``kind`` (POS, VEL, ATT, STA) and its typed values."""

    kind: str
    time_s: float
    values: tuple[float | int, ...]


#: kind -> (value names, formats) after the time field; the formats fix the decimals on the wire.
TEXT_SENTENCES: dict[str, tuple[tuple[str, ...], tuple[str, ...]]] = {
    "POS": (("lat_deg", "lon_deg", "height_m", "mode", "gnss_status", "psns_status"),
            (".7f", ".7f", ".2f", "04X", "d", "d")),
    "VEL": (("vel_e_mps", "vel_n_mps", "vel_u_mps"), (".3f", ".3f", ".3f")),
    "ATT": (("roll_deg", "pitch_deg", "heading_deg"), (".2f", ".2f", ".2f")),
    "STA": (("filter_variant", "cpu_load_pct", "deadline_misses"), ("d", ".2f", "d")),
}


def _text(kind: str, time_s: float, values: tuple[float | int, ...]) -> bytes:
    fmts = TEXT_SENTENCES[kind][1]
    return build_sentence("PSNS", kind, [f"{time_s:.3f}"] + [format(v, f) for v, f in zip(values, fmts)])


def encode_nav_text(t: NavText) -> bytes:
    """One ``$PSNS<kind>`` sentence (NMEA framing and checksum, CR LF)."""
    return _text(t.kind, t.time_s, t.values)


def nav_text_sentences(n: NavSolution, filter_variant: int = _BASE_VARIANT,
                       kinds: tuple[str, ...] = ("POS", "VEL", "ATT", "STA")) -> bytes:
    """The text rendering of one solution: ``$PSNSPOS``, ``$PSNSVEL``, ``$PSNSATT``, ``$PSNSSTA``."""
    vals: dict[str, tuple[float | int, ...]] = {
        "POS": (n.lat_deg, n.lon_deg, n.height_m, n.mode, n.gnss_status, n.psns_status),
        "VEL": tuple(n.vel_enu_mps),
        "ATT": (n.roll_deg, n.pitch_deg, n.heading_deg),
        "STA": (int(filter_variant), n.cpu_load_pct, n.deadline_misses),
    }
    return b"".join(_text(k, n.time_s, vals[k]) for k in kinds)


class HostTextFormat:
    """:class:`~protocols.stream.FrameFormat` of the ``$PSNS...`` text sentences (yields :class:`NavText`).

    Other NMEA sentences on the same stream come out as :class:`~protocols.nmea.NmeaSentence`.
    """

    name = "host-text"
    sync = b"$"

    def __init__(self) -> None:
        self._nmea = NmeaFormat()
        self.frame_length = self._nmea.frame_length
        self.check = self._nmea.check

    @staticmethod
    def encode(obj: Any) -> bytes:
        """Encode a :class:`NavText` (or any NMEA object) back to its sentence."""
        if isinstance(obj, NavText):
            return encode_nav_text(obj)
        return encode_nmea(obj)

    def parse(self, frame: bytes) -> NavText | object:
        s = self._nmea.parse(frame)
        if not isinstance(s, NmeaSentence) or s.talker != "PSNS" or s.kind not in TEXT_SENTENCES:
            return s
        names, fmts = TEXT_SENTENCES[s.kind]
        f = s.fields
        if len(f) != 1 + len(names):
            raise ValueError(f"$PSNS{s.kind} needs {1 + len(names)} fields")
        vals = tuple(int(v, 16) if fm == "04X" else int(v) if fm == "d" else float(v) for v, fm in zip(f[1:], fmts))
        return NavText(s.kind, float(f[0]), vals)
