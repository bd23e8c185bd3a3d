"""The firmware's NMEA 0183 navigation output (firmware.nmea; docs/icd.md "NMEA navigation output"), in fast mode.

Each tick's NMEA group follows that tick's NAV_SOLUTION frame on the host port: the sentences must carry that
frame's solution, rounded as the sentence formats round (checked against the NAV_SOLUTION fields, re-derived
here: course from the ENU velocity, knots from m/s), and the cycles the firmware charges for them are the declared
cost of the sentences it wrote.
"""

from __future__ import annotations

import datetime as dt
import itertools
import math
import os

import pynmea2
import pytest

from firmware_model import c674x
from protocols.host import HostFormat, NavSolution
from protocols.nmea import NmeaFormat
from protocols.nmea_build import KNOT_MPS
from protocols.stream import StreamDecoder
from tests.conftest import SCENARIOS

QS = SCENARIOS / "quickstart.yaml"
ALL = ["GGA", "RMC", "VTG", "ZDA", "HDT", "THS", "PASHR"]


def _run(tmp_path, **extra):
    from emulator.assembly.session import run_scenario
    from emulator.testing import load_test_scenario

    motion = [{"static": {"duration_s": 4.0}}, {"accelerate": {"duration_s": 3.0, "to_speed_mps": 8.0}},
              {"cruise": {"duration_s": 3.0}}]
    ov = {"duration_s": 10.0, "motion": motion, "expectations": [], "links.psns": None, "sensors.camera": None,
          "firmware.alignment.heading_source": "config", "firmware.alignment.heading_deg": 30.0,
          "firmware.nmea": {"sentences": ALL, "rate_hz": 1.0, "attitude_rate_hz": 2.0}}
    ov.update(extra)
    scn = load_test_scenario(QS, ov)
    return scn, run_scenario(scn, tmp_path)


def _host_out(run_dir) -> bytes:
    from emulator.recording.capture import read_capture

    _h, recs = read_capture(run_dir / "capture.psnscap")
    return b"".join(r.data for r in recs if r.link == "host" and r.direction == "out")


def test_nmea_sentences_carry_the_nav_frame_of_their_tick(tmp_path):
    scn, s = _run(tmp_path)
    assert s["links"]["host"]["garbage_bytes"] == 0 and s["links"]["host"]["crc_errors"] == 0
    epoch = scn.epoch.replace(tzinfo=None)
    # the host stream in order: NAV_SOLUTION frames, and the NMEA sentences after each (our decoder frames them;
    # pynmea2 reads them: HDT, PASHR and THS come back from our decoder as generic sentences)
    dec = StreamDecoder([HostFormat(), NmeaFormat()])
    groups: list[tuple[NavSolution, list]] = []
    for f in dec.feed(_host_out(tmp_path)):
        if isinstance(f, NavSolution):
            groups.append((f, []))
        elif type(f).__name__ in ("Gga", "Rmc", "Vtg", "Zda", "NmeaSentence"):
            groups[-1][1].append(f)
    assert dec.stats.crc_errors == 0 and dec.stats.garbage_bytes == 0
    with_nmea = [(n, g) for n, g in groups if g]
    def name(f: object) -> str:  # a proprietary sentence by its whole address ($PASHR: maker ASH, sentence R)
        kind = getattr(f, "kind", type(f).__name__.upper())
        talker = getattr(f, "talker", "")
        return talker + kind if talker.startswith("P") else kind

    kinds_of = [[name(f) for f in g] for _n, g in with_nmea]
    # 1 Hz position group from the first UTC (the first GNSS fix, t = 1.05 s): 1.995 .. 9.995 s; 2 Hz attitude,
    # every half second without a gap, from the first solution to the end
    assert sum("GGA" in k for k in kinds_of) == 9
    t_att = [n.time_s for (n, _g), k in zip(with_nmea, kinds_of, strict=True) if "HDT" in k]
    assert t_att[0] < 3.5 and t_att[-1] == pytest.approx(9.495, abs=1e-6)  # 9.995: on the line at the end
    assert all(b - a == pytest.approx(0.5, abs=1e-6) for a, b in itertools.pairwise(t_att))
    # heading and attitude first (HDT, THS, PASHR), then the position group in its order; before the first
    # solution only what can say "no solution" (THS mode V, GGA quality 0, RMC V) and ZDA
    att, pos, none_att, none_pos = ["HDT", "THS", "PASHR"], ["GGA", "RMC", "VTG", "ZDA"], ["THS"], ["GGA", "RMC", "ZDA"]
    for k in kinds_of:
        assert k in (att, pos, att + pos, none_att, none_pos, none_att + none_pos), k
    checked = 0
    for n, g in with_nmea:
        utc = epoch + dt.timedelta(seconds=n.time_s)
        for f in g:
            tm = getattr(f, "time_utc", None)
            if tm is not None:
                ts = dt.datetime.combine(utc.date(), tm)
                assert abs((ts - utc).total_seconds()) <= 0.0051  # UTC of the tick, to the 10 ms of hhmmss.ss
            name = type(f).__name__
            if name == "NmeaSentence" and f.kind == "THS":  # pynmea2 1.19 has no THS: heading, mode
                assert f.fields[1] in "AV" and (f.fields[1] == "V" or float(f.fields[0]) == pytest.approx(
                    n.heading_deg % 360.0, abs=0.0051))
            elif name == "NmeaSentence":
                m = pynmea2.parse(f"${f.talker}{f.kind}," + ",".join(f.fields))  # independent reader
                if f.kind == "HDT":
                    assert float(m.heading) == pytest.approx(n.heading_deg % 360.0, abs=0.0051)
                elif f.kind == "SHR":
                    assert m.true_heading == pytest.approx(n.heading_deg % 360.0, abs=0.0051)
                    assert m.roll == pytest.approx(n.roll_deg, abs=0.0051)
                    assert m.pitch == pytest.approx(n.pitch_deg, abs=0.0051)
                    ts = dt.datetime.combine(utc.date(), m.timestamp.replace(tzinfo=None))
                    assert abs((ts - utc).total_seconds()) <= 0.0051
            elif name == "Gga" and f.quality > 0:
                assert round(f.lat_deg * 60e5) == round(n.lat_deg * 60e5)  # 1e-5 arc-minute
                assert round(f.lon_deg * 60e5) == round(n.lon_deg * 60e5)
                assert f.altitude_msl_m == pytest.approx(n.height_m, abs=6e-4) and f.geoid_sep_m == 0.0
                assert f.quality == 1  # GNSS-aided all along
                checked += 1
            elif name == "Rmc" and f.valid:
                ve, vn, _ = n.vel_enu_mps
                assert f.speed_mps == pytest.approx(math.hypot(ve, vn), abs=0.0006 * KNOT_MPS + 1e-6)
                if math.hypot(ve, vn) > 1.0:
                    course = math.degrees(math.atan2(ve, vn)) % 360.0
                    assert f.course_deg == pytest.approx(course, abs=0.0051)
    assert checked >= 7


def test_nmea_output_is_charged_its_declared_cycles(tmp_path):
    from emulator.assembly.session import Emulator, run_emulator

    scn, _ = _run(tmp_path / "a", **{"firmware.nmea": {"sentences": ["GGA", "HDT"], "rate_hz": 1.0,
                                                        "attitude_rate_hz": 1.0}})
    emu = Emulator(scn, tmp_path / "b")
    run_emulator(emu)
    task = emu.fw.meter.tasks["nmea_output"]
    fmt = c674x.nmea_sentence(72, 4) + c674x.nmea_sentence(18, 1)
    math_ = c674x.mathlib("asinsp") + 2 * c674x.mathlib("atan2sp") + c674x.mathlib("sqrtsp") + c674x.mathlib("atan2sp")
    assert task.cycles_max == fmt + math_  # a navigating tick: both sentences, attitude and course
    assert task.kernels["nmea_format"] >= fmt and task.calls == 10  # one call per second, t = 1 .. 10 s


def test_nmea_on_a_second_host_port_leaves_the_host_port_binary(tmp_path):
    _scn, s = _run(tmp_path, **{"links.host_nmea": {"url": "mem://nmea"},
                               "fpga.routing": {"host": "uart0", "gnss": "uart3", "host_nmea": "uart2"}})
    assert s["links"]["host"]["garbage_bytes"] == 0 and b"$GN" not in _host_out(tmp_path)
    assert s["links"]["host_nmea"]["frames"] >= 9 * 4 + 18 * 3 - 10 and s["links"]["host_nmea"]["garbage_bytes"] == 0
    row = next(p for p in s["ports"] if p["name"] == "host_nmea")
    assert row["direction"] == "out"
    dec = StreamDecoder([NmeaFormat()])
    from emulator.recording.capture import read_capture

    _h, recs = read_capture(tmp_path / "capture.psnscap")
    dec.feed(b"".join(r.data for r in recs if r.link == "host_nmea" and r.direction == "out"))
    assert dec.stats.crc_errors == 0


def test_host_nmea_without_sentences_is_a_validation_error_and_without_a_route_shares_uart0():
    from emulator.assembly.build import effective_routing
    from emulator.errors import ScenarioError
    from emulator.testing import load_test_scenario

    scn = load_test_scenario(QS, {"links.host_nmea": {"url": "mem://nmea"}, "firmware.nmea.sentences": ["GGA"]})
    assert effective_routing(scn) == {"host": "uart0", "psns": "uart2", "gnss": "uart3", "host_nmea": "uart0"}
    with pytest.raises(ScenarioError, match=r"firmware\.nmea\.sentences is empty"):
        load_test_scenario(QS, {"links.host_nmea": {"url": "mem://nmea"}, "links.psns": None, "sensors.camera": None,
                                "firmware.alignment.heading_source": "config",
                                "fpga.routing": {"host": "uart0", "gnss": "uart3", "host_nmea": "uart2"}})


def test_the_full_box_carries_nmea_on_uart0_and_the_fpga_splits_it(tmp_path):
    """Camera on UART2, GNSS on UART3, ``links.host_nmea`` without a route (issue 38): the firmware writes NMEA and
    NAV_SOLUTION on UART0, the FPGA sends the binary frames to the host port and the sentences to host_nmea; nothing
    is lost or misrouted, and the host's NAV_SOLUTION frames are those of a run without NMEA, bit for bit."""
    from emulator.assembly.session import run_scenario
    from emulator.recording.capture import read_capture
    from emulator.testing import load_test_scenario

    base = {"duration_s": 6.0, "motion": [{"static": {"duration_s": 6.0}}], "expectations": []}
    scn = load_test_scenario(QS, {**base, "links.host_nmea": {"url": "mem://nmea", "baud": 115200},
                                  "firmware.nmea": {"sentences": ["GGA", "RMC", "ZDA", "HDT"], "rate_hz": 1.0,
                                                    "attitude_rate_hz": 1.0}})
    assert scn.links.psns is not None
    s = run_scenario(scn, tmp_path / "mux")
    plain = run_scenario(load_test_scenario(QS, base), tmp_path / "plain")
    for link in ("host", "host_nmea", "uart0"):
        assert s["links"][link]["garbage_bytes"] == 0 and s["links"][link]["crc_errors"] == 0, link
    assert s["links"]["uart0"]["frames"] == s["links"]["host"]["frames"] + s["links"]["host_nmea"]["frames"]
    assert s["links"]["host_nmea"]["frames"] >= 4 * 4
    _h, recs = read_capture(tmp_path / "mux" / "capture.psnscap")
    host = b"".join(r.data for r in recs if r.link == "host" and r.direction == "out")
    nmea = b"".join(r.data for r in recs if r.link == "host_nmea" and r.direction == "out")
    assert b"$GN" not in host and nmea.startswith(b"$GN") and nmea.endswith(b"\r\n")
    dec = StreamDecoder([NmeaFormat()])
    dec.feed(nmea)
    assert dec.stats.garbage_bytes == 0 and dec.stats.frames == s["links"]["host_nmea"]["frames"]
    assert (tmp_path / "mux" / "nav.csv").read_text().splitlines()[1:] != []
    mux_rows = [r.split(",")[:22] for r in (tmp_path / "mux" / "nav.csv").read_text().splitlines()]
    plain_rows = [r.split(",")[:22] for r in (tmp_path / "plain" / "nav.csv").read_text().splitlines()]
    # the solution is unchanged (not the CPU load, nor the arrival times: NMEA shares the line)
    assert mux_rows == plain_rows
    assert plain["nav_frames"] == s["nav_frames"]


def test_host_demux_splits_interleaved_frames_in_any_chunking():
    """Binary frames whose payload holds '$' and CR LF bytes, NMEA sentences between them, fed in random chunks:
    each goes to its port whole and in order; a corrupted sentence is dropped and counted."""
    import datetime as dt
    import random

    from emulator.devices.fpga import HostDemux
    from protocols.host import HostFormat, NavSolution
    from protocols.nmea_build import build_gga

    frames, want = [], {"host": [], "host_nmea": []}
    for k in range(40):
        nav = NavSolution(seq=k, time_s=0.01 * k, lat_deg=36.0, lon_deg=36.0, height_m=13.0 + 0.0001 * k,
                          vel_enu_mps=(0.0, 0.0, 0.0), roll_deg=0.0, pitch_deg=0.0, heading_deg=36.0,
                          sigma=(0.1,) * 9, mode=0x24, gnss_status=0x0D, psns_status=0x0A, cpu_load_pct=36.0,
                          deadline_misses=0)
        b = HostFormat().encode(nav)
        frames.append(b)
        want["host"].append(b)
        if k % 7 == 0:
            g = build_gga(dt.time(8, 14, k % 60), 39.979, 116.339, 50.0, 0.0, quality=1)
            frames.append(g)
            want["host_nmea"].append(g)
    stream = b"".join(frames)
    assert b"$" in b"".join(want["host"])  # the binary frames carry '$' bytes
    rng = random.Random(7)
    demux = HostDemux()
    got = {"host": [], "host_nmea": []}
    i = 0
    while i < len(stream):
        n = rng.randint(1, 50)
        for port, frame in demux.feed(stream[i:i + n]):
            got[port].append(frame)
        i += n
    assert got == want and demux.garbage_bytes == 0
    bad = bytearray(want["host_nmea"][0])
    bad[10] ^= 0x01
    assert HostDemux().feed(bytes(bad) + want["host"][0]) == [("host", want["host"][0])]


def test_psns_text_output_switched_on_from_the_scenario(tmp_path):
    """``firmware.text_rate_hz: 10`` with ``links.host_nmea``: the $PSNS text (docs/icd.md 7) of every tenth
    NAV_SOLUTION goes out on the NMEA port, text only, and says what the binary frame says to its printed digits."""
    from emulator.assembly.session import run_scenario
    from emulator.recording.capture import read_capture
    from emulator.testing import load_test_scenario
    from protocols.host import HostFormat, NavSolution
    from protocols.host_text import HostTextFormat, NavText

    scn = load_test_scenario(QS, {"duration_s": 4.0, "motion": [{"static": {"duration_s": 4.0}}], "expectations": [],
                                  "links.host_nmea": {"url": "mem://nmea", "baud": 115200},
                                  "firmware.text_rate_hz": 10.0})
    s = run_scenario(scn, tmp_path)
    assert s["links"]["host_nmea"]["garbage_bytes"] == 0 and s["links"]["host"]["garbage_bytes"] == 0
    _h, recs = read_capture(tmp_path / "capture.psnscap")
    text = b"".join(r.data for r in recs if r.link == "host_nmea" and r.direction == "out")
    assert text.startswith(b"$PSNSPOS,") and all(32 <= c < 127 or c in (13, 10) for c in text)  # printable text
    dec = StreamDecoder([HostTextFormat()])
    sentences = [f for f in dec.feed(text) if isinstance(f, NavText)]
    # POS VEL ATT STA at 10 Hz for 4 s; the last group may still be on the line when the run ends
    assert dec.stats.crc_errors == 0 and len(sentences) % 4 == 0 and 4 * 39 <= len(sentences) <= 4 * 40
    navs = {round(f.time_s, 3): f for f in StreamDecoder([HostFormat()]).feed(
        b"".join(r.data for r in recs if r.link == "host" and r.direction == "out")) if isinstance(f, NavSolution)}
    for t in (x for x in sentences if x.kind == "POS"):
        n = navs[round(t.time_s, 3)]
        lat, lon, h, mode = t.values[:4]
        assert abs(lat - n.lat_deg) <= 5e-8 and abs(lon - n.lon_deg) <= 5e-8 and abs(h - n.height_m) <= 0.005
        assert mode == n.mode


def test_text_rate_must_divide_the_output_rate():
    from emulator.errors import ScenarioError
    from emulator.testing import load_test_scenario

    with pytest.raises(ScenarioError, match=r"firmware\.text_rate_hz: must divide output_rate_hz"):
        load_test_scenario(QS, {"firmware.text_rate_hz": 30.0})


@pytest.mark.pty
@pytest.mark.realtime
@pytest.mark.psns_emulator(mode="realtime")
async def test_psns_text_can_be_read_on_the_pty(tmp_path):
    """What the README's terminal recipe shows: the quickstart (camera on) with ``links.host_nmea`` on a pty and
    ``firmware.text_rate_hz: 10``; a terminal reader on ports/nmea gets printable $PSNS lines, checksums valid."""
    import contextlib
    import termios
    import tty

    from emulator.testing import start_emulator
    from protocols.host_text import HostTextFormat, NavText

    ov = {"duration_s": 8.0, "motion": [{"static": {"duration_s": 8.0}}], "expectations": [],
          "links.host_nmea": {"url": "pty://nmea", "baud": 115200}, "firmware.text_rate_hz": 10.0}
    got = bytearray()
    async with start_emulator(QS, run_dir=tmp_path, overrides=ov) as emu:
        fd = os.open(tmp_path / "ports" / "nmea", os.O_RDONLY | os.O_NOCTTY | os.O_NONBLOCK)
        try:
            tty.setraw(fd, termios.TCSANOW)

            def lines() -> int:
                with contextlib.suppress(BlockingIOError):
                    while chunk := os.read(fd, 4096):
                        got.extend(chunk)
                return got.count(b"\r\n")

            await emu.wait_until(lambda: lines() >= 20, timeout=7.0, what="20 text lines on the pty")
        finally:
            os.close(fd)
    text = bytes(got[got.index(b"$"):got.rindex(b"\r\n") + 2])  # from the first whole sentence on
    assert all(32 <= c < 127 or c in (13, 10) for c in text), text[:200]
    dec = StreamDecoder([HostTextFormat()])
    kinds = [f.kind for f in dec.feed(text) if isinstance(f, NavText)]
    assert dec.stats.crc_errors == 0 and dec.stats.garbage_bytes == 0
    assert {"POS", "VEL", "ATT", "STA"} <= set(kinds) and len(kinds) >= 19
