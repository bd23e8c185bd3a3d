"""psns-hil monitor / replay / realtime run, as subprocesses, as a user would call them."""

from __future__ import annotations

import asyncio
import json
import subprocess
import sys

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
def test_realtime_run_prints_port_map_and_status_lines(tmp_path):
    """A pty port implies real time; the port map names the pty; a status line every second."""
    links = 'links:\n  gyro: {url: "mem://gyro", baud: 460800}\n  host: {url: "pty://uart0", baud: 460800}\n'
    text = open(_scenario(tmp_path, 3)).read().replace("mode: fast\n", "")
    text = text[: text.index("links:")] + links + text[text.index("dsp:"):]
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
async def test_monitor_command_decodes_a_live_pty(tmp_path):
    from emulator.testing import start_emulator

    ov = {"duration_s": 10.0, "motion": [{"static": {"duration_s": 10.0}}], "expectations": [],
          "links.host.url": "pty://uart0"}
    async with start_emulator(SCENARIOS / "quickstart.yaml", run_dir=tmp_path / "run", overrides=ov) as emu:
        proc = await asyncio.create_subprocess_exec(
            sys.executable, "-m", "emulator", "monitor", str(tmp_path / "run" / "ports" / "uart0"),
            "--count", "30", "--json", cwd=ROOT, stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE)
        out, err = await asyncio.wait_for(proc.communicate(), timeout=30.0)
        assert proc.returncode == 0, err.decode()
        rows = [json.loads(x) for x in out.decode().splitlines()]
        assert len(rows) == 30 and all(x["type"] == "NavSolution" for x in rows)
        seqs = [x["fields"]["seq"] for x in rows]
        assert seqs == list(range(seqs[0], seqs[0] + 30))
        assert emu.link_stats("host")["bytes_out"] > 0
