"""``psns-hil campaign`` reads its scenario once, through the bounded reader every scenario goes through
(``emulator.scenario.loader.read_scenario_text``: at most 1 MiB) -- docs/hostile-input.md section 7 (issue 41).
Before, it validated the file through that reader and then read it again whole (``Path.read_text``)."""

from __future__ import annotations

import os
import subprocess
import sys

SCN = """\
name: camp
epoch: 2019-09-18T08:14:00Z
duration_s: 10
origin: {lat_deg: 39.979, lon_deg: 116.339, height_m: 50}
"""

WRITER = """\
import sys
path, first = sys.argv[1], sys.argv[2].encode()
with open(path, "wb") as f:  # the first reader gets a valid scenario
    f.write(first)
with open(path, "wb") as f:  # a second reader would get 8 MiB (blocks here until one opens the FIFO)
    try:
        f.write(b"# " + b"x" * (8 << 20) + b"\\n")
    except BrokenPipeError:
        pass
"""


def test_the_campaign_reads_its_scenario_once_bounded(tmp_path):
    fifo = tmp_path / "s.yaml"
    os.mkfifo(fifo)
    writer = subprocess.Popen([sys.executable, "-c", WRITER, str(fifo), SCN])
    try:
        # a cheap error after the scenario is read: no cluster is started
        r = subprocess.run([sys.executable, "-m", "emulator", "campaign", str(fifo), "--runs", "2",
                            "--vary", "no.such_key=uniform(0, 1)", "--out", str(tmp_path / "out")],
                           capture_output=True, text=True, timeout=180, cwd=tmp_path)
    finally:
        writer.kill()
        writer.wait(timeout=30)
    out = r.stdout + r.stderr
    assert r.returncode == 2, out
    assert "Traceback" not in out
    assert "larger than" not in out, "the scenario was read a second time"
    assert "no.such_key" in out
