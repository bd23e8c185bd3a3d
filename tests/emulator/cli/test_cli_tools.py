"""psns-hil monitor / replay / realtime run, as subprocesses, as a user would call them."""

from __future__ import annotations

import asyncio
import json
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

import pytest

from tests.conftest import ROOT, SCENARIOS


def psns_hil(*args, timeout=120):
    return subprocess.run([sys.executable, "-m", "emulator", *args], capture_output=True, text=True, cwd=ROOT,
                          timeout=timeout)


def _scenario(tmp_path, duration: float, extra: str = "") -> str:
    text = (SCENARIOS / "quickstart.yaml").read_text()
    text = text.replace("duration_s: 120", f"duration_s: {duration}").replace(
        "- static: {duration_s: 120}", f"- static: {{duration_s: {duration}}}")
    text = text[: text.index("expectations:")] + extra
    p = tmp_path / "s.yaml"
    p.write_text(text)
    return str(p)


@pytest.fixture(scope="module")
def fast_run(tmp_path_factory):
    d = tmp_path_factory.mktemp("cli")
    r = psns_hil("run", _scenario(d, 6), "--out", str(d / "run"), "--quiet")
    assert r.returncode == 0, r.stderr
    return d / "run"


def test_monitor_decodes_a_capture_as_json_lines(fast_run):
    r = psns_hil("monitor", str(fast_run / "capture.psnscap"), "--link", "host", "--count", "5", "--json")
    assert r.returncode == 0, r.stderr
    rows = [json.loads(x) for x in r.stdout.splitlines()]
    assert [x["type"] for x in rows] == ["NavSolution"] * 5
    assert [x["fields"]["seq"] for x in rows] == [0, 1, 2, 3, 4]
    assert all(x["port"] == "host" and x["dir"] == "out" for x in rows)


def test_monitor_table_covers_every_link_with_statistics(fast_run):
    r = psns_hil("monitor", str(fast_run / "capture.psnscap"), "--stats")
    assert r.returncode == 0, r.stderr
    kinds = {ln.split()[3] for ln in r.stdout.splitlines()[1:] if ln.strip()}
    assert {"NavSolution", "ImuFrame", "StimDatagram", "Gga", "Rmc"} <= kinds
    assert "crc errors 0" in r.stderr and "uart1/in" in r.stderr


def test_monitor_rejects_unknown_protocol_and_missing_endpoint(tmp_path):
    r = psns_hil("monitor", str(tmp_path / "nope"))
    assert r.returncode == 2 and "no such file or device" in r.stderr and "Traceback" not in r.stderr
    f = tmp_path / "uartX"
    f.write_bytes(b"")
    r = psns_hil("monitor", str(f))
    assert r.returncode == 2 and "--protocol" in r.stderr


def test_replay_command_reproduces_nav_csv(fast_run, tmp_path):
    r = psns_hil("replay", str(fast_run / "capture.psnscap"), "--out", str(tmp_path / "rp"),
                 "--compare", str(fast_run))
    assert r.returncode == 0, r.stdout + r.stderr
    assert "identical" in r.stdout and ": yes" in r.stdout
    s = json.loads((tmp_path / "rp" / "summary.json").read_text())
    assert s["replay"]["records"] > 1000 and s["replay"]["source"].endswith("capture.psnscap")


def test_replay_of_a_file_that_is_not_a_capture_is_exit_2(tmp_path):
    bad = tmp_path / "x.psnscap"
    bad.write_bytes(b"hello")
    r = psns_hil("replay", str(bad))
    assert r.returncode == 2 and "not a psns-hil capture" in r.stderr


@pytest.mark.pty
@pytest.mark.realtime
def test_realtime_run_prints_port_map_and_status_lines(tmp_path):
    """A pty port implies real time; the port map names the pty; a status line every second."""
    text = Path(_scenario(tmp_path, 3)).read_text().replace("mode: fast\n", "")
    text = text.replace('host: {url: "mem://host"', 'host: {url: "pty://uart0"')
    assert "pty://uart0" in text
    p = tmp_path / "rt.yaml"
    p.write_text(text)
    r = psns_hil("run", str(p), "--out", str(tmp_path / "run"), "--status", "1")
    assert r.returncode == 0, r.stderr
    assert "realtime" in r.stdout.splitlines()[0]
    host_line = next(ln for ln in r.stdout.splitlines() if ln.startswith("  host "))
    assert f"{tmp_path / 'run' / 'ports' / 'uart0'} -> /dev/pts/" in host_line
    status = [ln for ln in r.stderr.splitlines() if "frames/s" in ln]
    assert len(status) >= 2, r.stderr
    # every second the firmware sent ~100 nav frames (counted on the host port, read or not)
    assert "real time" in status[-1]
    fps = float(status[-1].split("nav")[1].split("frames/s")[0])
    assert 95.0 <= fps <= 105.0
    ports = json.loads((tmp_path / "run" / "ports.json").read_text())
    assert next(x for x in ports if x["name"] == "host")["url"] == "pty://uart0"
    s = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert s["mode"] == "realtime" and 0.9 < s["realtime_factor"] < 1.1


@pytest.mark.pty
@pytest.mark.psns_emulator(mode="realtime")
@pytest.mark.realtime
async def test_monitor_command_decodes_a_live_pty(tmp_path):
    from emulator.testing import start_emulator

    ov = {"duration_s": 10.0, "motion": [{"static": {"duration_s": 10.0}}], "expectations": [],
          "links.host.url": "pty://uart0"}
    async with start_emulator(SCENARIOS / "quickstart.yaml", run_dir=tmp_path / "run", overrides=ov) as emu:
        proc = await asyncio.create_subprocess_exec(
            sys.executable, "-m", "emulator", "monitor", str(tmp_path / "run" / "ports" / "uart0"),
            "--count", "40", "--json", cwd=ROOT, stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE)
        out, err = await asyncio.wait_for(proc.communicate(), timeout=30.0)
        assert proc.returncode == 0, err.decode()
        rows = [json.loads(x) for x in out.decode().splitlines()]
        # 40 frames of the host port: NavSolution at 100 Hz and, once a second, a HostStatus (own sequence)
        assert len(rows) == 40 and {x["type"] for x in rows} <= {"NavSolution", "HostStatus"}
        nav = [x for x in rows if x["type"] == "NavSolution"]
        assert len(nav) >= 38
        seqs = [x["fields"]["seq"] for x in nav]
        assert seqs == list(range(seqs[0], seqs[0] + len(nav)))
        assert emu.link_stats("host")["bytes_out"] > 0


def _poll(pred, timeout_s: float, every_s: float = 0.01) -> bool:
    """Wall-clock wait until ``pred()``; False on timeout."""
    end = time.monotonic() + timeout_s
    while not pred():
        if time.monotonic() >= end:
            return False
        time.sleep(every_s)
    return True


def _matched(publisher: Any) -> bool:
    """A zenoh publisher has a subscriber (``matching_status`` is an object with ``matching`` at run time)."""
    return bool(publisher.matching_status.matching)


@pytest.mark.realtime
def test_monitor_decodes_what_is_published_on_a_zenoh_key():
    """``psns-hil monitor zenoh://RUN/PORT``: the key's tx (out) and rx (in) decoded, garbage counted."""
    import zenoh

    from emulator.distributed.split import free_tcp_port
    from emulator.links.zenoh import ZenohEndpointConfig
    from protocols.host import NavMode, NavSolution, RequestStatus, encode_command, encode_nav_solution

    navs = [encode_nav_solution(NavSolution(
        seq=k, time_s=0.01 * k, lat_deg=39.979, lon_deg=116.339, height_m=50.0, vel_enu_mps=(0.0, 0.0, 0.0),
        roll_deg=0.1, pitch_deg=-0.2, heading_deg=30.0, sigma=(0.1,) * 9, mode=int(NavMode.NAVIGATING),
        gnss_status=1, psns_status=0, cpu_load_pct=0.2, deadline_misses=0)) for k in range(20)]
    commands = [encode_command(RequestStatus(token=k)) for k in range(5)]
    tx_blob = b"".join(navs[:7]) + b"\xde\xad\xbe" + b"".join(navs[7:])  # 3 garbage bytes between frames
    p = free_tcp_port()
    # the publisher listens, the monitor connects (scouting off in both configurations)
    with zenoh.open(ZenohEndpointConfig(listen=(f"tcp/127.0.0.1:{p}",)).build()) as session:
        block = zenoh.CongestionControl.BLOCK
        tx = session.declare_publisher("psns/mon1/host/tx", congestion_control=block)
        rx = session.declare_publisher("psns/mon1/host/rx", congestion_control=block)
        proc = subprocess.Popen(
            [sys.executable, "-m", "emulator", "monitor", f"zenoh://mon1/host?connect=tcp/127.0.0.1:{p}",
             "--count", "25", "--duration", "60", "--json", "--stats"],
            cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            subscribed = _poll(lambda: proc.poll() is not None or (_matched(tx) and _matched(rx)), 60.0)
            assert subscribed and proc.poll() is None, "the monitor did not subscribe to psns/mon1/host/{tx,rx}"
            for i in range(0, len(tx_blob), 150):  # arbitrary chunks: the decoders are stream decoders
                tx.put(tx_blob[i:i + 150])
            for c in commands:
                rx.put(c)
            out, err = proc.communicate(timeout=60)
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.communicate()
            tx.undeclare()
            rx.undeclare()
    assert proc.returncode == 0, err
    rows = [json.loads(x) for x in out.splitlines()]
    assert len(rows) == 25
    out_rows = [r for r in rows if r["dir"] == "out"]
    in_rows = [r for r in rows if r["dir"] == "in"]
    assert [r["type"] for r in out_rows] == ["NavSolution"] * 20
    assert [r["fields"]["seq"] for r in out_rows] == list(range(20))
    assert [r["type"] for r in in_rows] == ["RequestStatus"] * 5
    assert [r["fields"]["token"] for r in in_rows] == list(range(5))
    assert all(r["port"] == "host" for r in rows)
    assert "25 frames" in err
    assert "host/out: frames 20, crc errors 0, garbage bytes 3" in err
    assert "host/in: frames 5, crc errors 0, garbage bytes 0" in err


def test_monitor_zenoh_endpoint_errors_are_usage_errors():
    r = psns_hil("monitor", "zenoh://mon2/host?role=peer")
    assert r.returncode == 2 and "do not apply to monitor" in r.stderr and "Traceback" not in r.stderr
    r = psns_hil("monitor", "zenoh://mon2/nowhere")
    assert r.returncode == 2 and "--protocol" in r.stderr
