"""Crafted captures (issue 41 item 5): the header is validated (types, nesting, size) and records are read in bounded
pieces; ``monitor`` and ``replay`` exit 2 with one line naming the file and the line, field or byte offset; damaged
time stamps are reported, never silently used.

Before: wrong header types, a 100 000-deep JSON header and a 4 GiB declared length gave tracebacks in monitor and
replay; a NaN time stamp made replay use 750 of 2 061 records while saying ``truncated: false``. The bounds are
asserted as work (the check runs before the decoder or the read that would cost), not as wall-clock time."""

from __future__ import annotations

import json
import math
import os
import struct
import subprocess
import sys
import tracemalloc
from pathlib import Path

import pytest

import emulator.recording.capture as capture
from emulator.errors import RecordingError
from emulator.recording.capture import CAPTURE_MAGIC, CaptureWriter, iter_capture, read_capture

ROOT = Path(__file__).resolve().parents[3]
_REC = struct.Struct("<dHBBI")


def _cli(*args: str) -> tuple[int, list[str]]:
    r = subprocess.run([sys.executable, "-m", "emulator", *args], capture_output=True, text=True, timeout=120,
                       env=dict(os.environ, PYTHONPATH=str(ROOT)), cwd=ROOT)
    assert "Traceback" not in r.stderr, r.stderr
    return r.returncode, [ln for ln in r.stderr.strip().splitlines() if ln.startswith("error:")]


def _capture(path: Path, header_line: bytes, records: bytes = b"") -> Path:
    path.write_bytes(CAPTURE_MAGIC + header_line + b"\n" + records)
    return path


def _one_error_line(path: Path, *commands: str) -> list[str]:
    """Run monitor and replay on ``path``: both exit 2 with one error line naming the file; the lines."""
    lines = []
    for cmd in commands:
        args = [cmd, str(path)] + (["--out", str(path.parent / f"out-{cmd}")] if cmd == "replay" else [])
        rc, errs = _cli(*args)
        assert rc == 2 and len(errs) == 1 and str(path) in errs[0], (cmd, rc, errs)
        lines.append(errs[0])
    return lines


@pytest.mark.parametrize(("header", "field"), [
    ({"version": 2, "links": 5}, "links"),
    ({"version": 2, "links": ["uart0", 3]}, "links"),
    ({"version": "2", "links": []}, "version"),
    ({"version": 2, "links": [], "scenario_spec": [1]}, "scenario_spec"),
    ({"version": 2, "links": [], "seed": "x"}, "seed"),
    ({"version": 2, "links": [], "link_baud": 9600}, "link_baud"),
])
def test_wrong_header_types_name_the_field(tmp_path: Path, header: dict, field: str) -> None:
    p = _capture(tmp_path / "h.psnscap", json.dumps(header).encode())
    with pytest.raises(RecordingError, match=rf"line 2, field '{field}': must be"):
        iter_capture(p)
    for line in _one_error_line(p, "monitor", "replay"):
        assert f"line 2, field '{field}'" in line


def test_a_deep_json_header_is_refused_before_it_is_decoded(tmp_path: Path, monkeypatch) -> None:
    deep = b'{"version": 2, "links": [], "x": ' + b"[" * 100_000 + b"]" * 100_000 + b"}"
    p = _capture(tmp_path / "deep.psnscap", deep)

    def no_decode(*a, **k):
        raise AssertionError("decoded a header nested beyond the cap")

    monkeypatch.setattr(capture.json, "loads", no_decode)
    with pytest.raises(RecordingError, match="line 2: the capture header nests deeper than 64 levels"):
        iter_capture(p)
    monkeypatch.undo()
    _one_error_line(p, "monitor", "replay")
    # brackets inside strings, escaped quotes and backslashes do not count
    assert capture._json_depth(b'{"a": "[[[\\"[[", "b": "\\\\", "c": [[1]]}') == 3


def test_a_header_longer_than_the_cap_is_refused_after_one_bounded_read(tmp_path: Path) -> None:
    p = _capture(tmp_path / "long.psnscap", b'{"version": 2, "links": [], "pad": "' + b"x" * (5 << 20) + b'"}')
    with open(p, "rb") as f:
        with pytest.raises(RecordingError, match="line 2: the capture header is longer than 4 MiB"):
            capture._read_header(f, p)
        assert f.tell() == len(CAPTURE_MAGIC) + capture.MAX_HEADER_BYTES + 1  # read no further than the cap
    _one_error_line(p, "monitor")


def test_a_4_gib_declared_length_is_refused_before_any_read(tmp_path: Path, monkeypatch) -> None:
    rec = _REC.pack(0.5, 0, 1, 0, 0xFFFFFFFF) + b"\x00" * 64
    p = _capture(tmp_path / "len.psnscap", json.dumps({"version": 2, "links": ["uart3"]}).encode(), rec)

    def no_read(*a, **k):
        raise AssertionError("read a record longer than the cap")

    monkeypatch.setattr(capture, "_read_exact", no_read)
    _header, it = iter_capture(p)
    with pytest.raises(RecordingError, match=r"record at byte \d+: declares 4294967295 bytes, more than 16 MiB"):
        next(it)
    monkeypatch.undo()
    _one_error_line(p, "monitor", "replay")


def test_a_declared_length_under_the_cap_on_a_short_file_is_read_in_pieces(tmp_path: Path) -> None:
    rec = _REC.pack(0.5, 0, 1, 0, 15 << 20) + b"$GPGGA" * 10  # 15 MiB declared, 60 bytes there
    p = _capture(tmp_path / "short.psnscap", json.dumps({"version": 2, "links": ["uart3"]}).encode(), rec)
    tracemalloc.start()
    try:
        header, records = read_capture(p)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert records == [] and header["truncated_record"] is True
    assert peak < 3 << 20  # one 1 MiB piece at a time, not the declared 15 MiB


def _write(path: Path, header: dict, records: list[tuple[float, str, bool, bytes]]) -> None:
    links = sorted({r[1] for r in records})
    w = CaptureWriter(path, header, links)
    for t, link, inbound, data in records:
        w.write(links.index(link), inbound, t, data)
    w.close()


def test_nan_and_backward_times_are_counted_and_monitor_says_so(tmp_path: Path) -> None:
    p = tmp_path / "t.psnscap"
    _write(p, {}, [(0.1, "uart3", True, b"a"), (math.nan, "uart3", True, b"b"), (0.3, "uart3", True, b"c"),
                   (0.2, "uart3", True, b"d"), (-1.0, "uart1", True, b"e"), (0.25, "uart3", False, b"f")])
    header, records = read_capture(p)
    assert len(records) == 6  # the reader yields them all and counts; the consumer decides
    assert header["bad_time_records"] == 2 and header["backward_time_records"] == 1
    r = subprocess.run([sys.executable, "-m", "emulator", "monitor", str(p), "--protocol", "nmea"],
                       capture_output=True, text=True, timeout=120, env=dict(os.environ, PYTHONPATH=str(ROOT)),
                       cwd=ROOT)
    assert r.returncode == 0 and "Traceback" not in r.stderr
    assert (f"warning: {p}: 2 record(s) with a time that is not finite or negative, 1 going back in time within "
            "their link and direction\n") in r.stderr


@pytest.mark.slow
def test_replay_reports_damaged_time_stamps_and_uses_every_other_record(tmp_path: Path) -> None:
    from emulator.assembly.session import run_scenario
    from emulator.postrun.replay import run_replay
    from emulator.scenario import load_scenario

    scn = load_scenario(ROOT / "scenarios" / "quickstart.yaml").model_copy(update={"duration_s": 3.0})
    run_scenario(scn, tmp_path / "run", mode="fast")
    header, records = read_capture(tmp_path / "run" / "capture.psnscap")
    links = [str(x) for x in header["links"]]
    uart_in = [i for i, r in enumerate(records) if r.link.startswith("uart") and r.direction == "in"]
    nan_at, back_at = uart_in[len(uart_in) // 3], uart_in[len(uart_in) // 2]
    crafted = tmp_path / "crafted.psnscap"
    w = CaptureWriter(crafted, header, links)
    for i, r in enumerate(records):
        t = math.nan if i == nan_at else (r.t_s - 0.5 if i == back_at else r.t_s)
        w.write(links.index(r.link), r.direction == "in", t, r.data, r.pitch_s)
    w.close()
    summary = run_replay(crafted, tmp_path / "replay", mode="fast")
    rep = summary["replay"]
    assert rep["records_in_capture"] == len(uart_in)
    assert rep["bad_time_records"] == 1 and rep["backward_time_records"] == 1
    assert rep["records"] == len(uart_in) - 1  # every other record delivered (before: a NaN stopped the delivery)
    assert rep["truncated"] is False


def test_the_header_cannot_widen_where_a_replay_reads_files(tmp_path: Path, monkeypatch) -> None:
    """``scenario_base_dir`` (where the run found the scenario's relative files) is taken only inside the user's
    trusted roots (the working directory, ``PSNS_HIL_ALLOW_PATHS``); a crafted ``/`` falls back to the capture's
    directory, so ``firmware.spec_sheet: home/...`` cannot reach the whole file system."""
    from emulator.postrun.replay import replay_base_dir
    from emulator.scenario.paths import ALLOW_PATHS_ENV

    monkeypatch.chdir(ROOT)
    monkeypatch.delenv(ALLOW_PATHS_ENV, raising=False)
    cap = tmp_path / "run" / "capture.psnscap"
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    assert replay_base_dir(cap, "/") == cap.parent.resolve()
    assert replay_base_dir(cap, str(elsewhere)) == cap.parent.resolve()
    assert replay_base_dir(cap, str(ROOT / "scenarios")) == (ROOT / "scenarios").resolve()  # the usual case
    assert replay_base_dir(cap, str(ROOT / "no-such-dir")) == cap.parent.resolve()
    assert replay_base_dir(cap, 5) == cap.parent.resolve() and replay_base_dir(cap, "rel/dir") == cap.parent.resolve()
    monkeypatch.setenv(ALLOW_PATHS_ENV, str(elsewhere))
    assert replay_base_dir(cap, str(elsewhere)) == elsewhere.resolve()
