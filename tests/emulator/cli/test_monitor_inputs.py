"""``psns-hil monitor`` on what users hand it (issue 38's monitor items, issue 41 item 2), in process:

* a NAV_SOLUTION line is whole (its mode and counters were cut off at 160 characters);
* a frame with +-inf / NaN values is shown and counted (``nonfinite_frames``), never raised; JSON gets ``null``;
* a plain byte dump is decoded from the file (it was opened as a serial device), its time at the line rate;
* a run's pty named freely in its URL (``ports/nmea`` of ``links.host_nmea``) is told from ``ports.json``;
* the sentences that once raised OverflowError out of the decoders (tests/fuzz/corpus/) are counted."""

from __future__ import annotations

import dataclasses
import io
import json
import math
from pathlib import Path

import pytest

from emulator.cli.monitor import FrameRow, formats_for, port_of_run_pty, run_monitor
from emulator.errors import EmulatorError
from protocols.host import NavMode, NavSolution, encode_host

CORPUS = Path(__file__).resolve().parents[2] / "fuzz" / "corpus" / "nmea_hostile_fields.nmea"
GOOD = b"$GPGGA,123519.00,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,*69\r\n"


def _nav(k: int, **change: object) -> NavSolution:
    n = NavSolution(seq=k, time_s=0.01 * k, lat_deg=39.98, lon_deg=116.34, height_m=50.0,
                    vel_enu_mps=(0.0, 0.0, 0.0), roll_deg=0.0, pitch_deg=0.0, heading_deg=1.0, sigma=(0.1,) * 9,
                    mode=int(NavMode.NAVIGATING), gnss_status=1, psns_status=0, cpu_load_pct=0.2, deadline_misses=7)
    return dataclasses.replace(n, **change)  # type: ignore[arg-type]


def test_a_nav_line_is_whole() -> None:
    line = FrameRow(1.0, "host", "out", _nav(3)).text()
    assert "mode=" in line and "deadline_misses=7" in line and not line.endswith("...")
    assert FrameRow(1.0, "host", "out", _nav(3)).text(width=80).endswith("...")  # cut only when asked


def test_a_byte_dump_with_non_finite_frames(tmp_path: Path) -> None:
    frames = [_nav(0), _nav(1, roll_deg=math.inf), _nav(2, heading_deg=math.nan), _nav(3, pitch_deg=-math.inf),
              _nav(4)]
    dump = tmp_path / "uart0.bin"
    dump.write_bytes(b"garbage" + b"".join(encode_host(f) for f in frames))
    out = io.StringIO()
    stats = run_monitor(str(dump), baud=460800, out=out)
    lines = out.getvalue().splitlines()[1:]
    assert stats["frames"] == 5 and len(lines) == 5
    assert "roll_deg=inf" in lines[1] and "heading_deg=nan" in lines[2] and "pitch_deg=-inf" in lines[3]
    st = stats["decoders"]["uart0/in"]
    assert st["nonfinite_frames"] == 3 and st["garbage_bytes"] == 7
    t0 = float(lines[0].split()[0])  # the time of the chunk's first byte at the line rate: 0 for one chunk
    assert t0 == 0.0
    out = io.StringIO()
    run_monitor(str(dump), as_json=True, out=out)
    rows = [json.loads(x) for x in out.getvalue().splitlines()]
    assert rows[1]["fields"]["roll_deg"] is None and rows[0]["fields"]["roll_deg"] == 0.0


def test_a_byte_dump_needs_a_protocol_when_its_name_does_not_tell(tmp_path: Path) -> None:
    dump = tmp_path / "dump.bin"
    dump.write_bytes(GOOD * 3)
    with pytest.raises(EmulatorError, match="cannot tell the protocol"):
        run_monitor(str(dump), out=io.StringIO())
    stats = run_monitor(str(dump), protocol="nmea", out=io.StringIO())
    assert stats["frames"] == 3


def test_the_hostile_sentences_are_counted(tmp_path: Path) -> None:
    cases = [c + b"\r\n" for c in CORPUS.read_bytes().split(b"\r\n") if c]
    dump = tmp_path / "gnss.nmea"
    dump.write_bytes(b"".join(c + GOOD for c in cases))
    stats = run_monitor(str(dump), out=io.StringIO())
    st = stats["decoders"]["gnss/in"]
    assert stats["frames"] == len(cases) and st["parse_errors"] == len(cases) and st["format_faults"] == 0


def test_a_run_pty_is_told_from_ports_json(tmp_path: Path) -> None:
    run = tmp_path / "run"
    (run / "ports").mkdir(parents=True)
    (run / "ports.json").write_text(json.dumps([
        {"name": "host", "url": "pty://uart0", "path": "ports/uart0 -> /dev/pts/3"},
        {"name": "host_nmea", "url": "pty://nmea?baud=115200", "path": "ports/nmea -> /dev/pts/4"}]))
    assert port_of_run_pty(str(run / "ports" / "nmea")) == "host_nmea"
    assert port_of_run_pty(str(run / "ports" / "uart0")) == "host"
    assert port_of_run_pty(str(run / "ports" / "other")) is None
    assert port_of_run_pty(str(tmp_path / "nmea")) is None
    assert [type(f).__name__ for f in formats_for("host_nmea")] == ["NmeaFormat"]
    assert [type(f).__name__ for f in formats_for("nmea")] == ["NmeaFormat"]
    (run / "ports.json").write_text("[" * 100_000)  # a malformed ports.json is ignored, never raised
    assert port_of_run_pty(str(run / "ports" / "nmea")) is None
