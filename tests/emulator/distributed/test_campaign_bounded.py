"""``psns-hil campaign`` reads its scenario once, through the bounded reader every scenario goes through
(``emulator.scenario.loader.read_scenario_text``: at most 1 MiB) -- docs/hostile-input.md section 7 (issue 41).
Before, it validated the file through that reader and then read it again whole (``Path.read_text``).

The opens are counted by a CPython audit hook (PEP 578 ``open`` events) in the real command's process. (A FIFO
whose second writer would hand a second reader 8 MiB raced: the writer could reopen before the first reader had
seen its end of file.)"""

from __future__ import annotations

import subprocess
import sys

SCN = """\
name: camp
epoch: 2019-09-18T08:14:00Z
duration_s: 10
origin: {lat_deg: 39.979, lon_deg: 116.339, height_m: 50}
"""

COUNTING = """\
import atexit, os, sys
target = os.path.realpath(sys.argv[1])
opens = []
def hook(event, args):
    if event == "open" and isinstance(args[0], (str, bytes, os.PathLike)):
        try:
            if os.path.realpath(os.fsdecode(args[0])) == target:
                opens.append(1)
        except (OSError, ValueError):
            pass
sys.addaudithook(hook)
atexit.register(lambda: sys.stderr.write(f"\\nOPENS={len(opens)}\\n"))
from emulator.cli.main import main
sys.exit(main(sys.argv[2:]))
"""


def test_the_campaign_reads_its_scenario_once_bounded(tmp_path):
    scn = tmp_path / "s.yaml"
    scn.write_text(SCN)
    # a cheap error after the scenario is read: no cluster is started
    r = subprocess.run([sys.executable, "-c", COUNTING, str(scn), "campaign", str(scn), "--runs", "2",
                        "--vary", "no.such_key=uniform(0, 1)", "--out", str(tmp_path / "out")],
                       capture_output=True, text=True, timeout=180, cwd=tmp_path)
    out = r.stdout + r.stderr
    assert r.returncode == 2, out
    assert "Traceback" not in out
    assert "no.such_key" in out
    assert "OPENS=1" in out, f"the scenario was not read exactly once: {out}"


def test_the_campaign_refuses_an_oversized_scenario(tmp_path):
    scn = tmp_path / "s.yaml"
    scn.write_text(SCN + "# " + "x" * (2 << 20) + "\n")
    r = subprocess.run([sys.executable, "-m", "emulator", "campaign", str(scn), "--runs", "2",
                        "--out", str(tmp_path / "out")], capture_output=True, text=True, timeout=180, cwd=tmp_path)
    out = r.stdout + r.stderr
    assert r.returncode == 2, out
    assert "Traceback" not in out
    assert "larger than 1 MiB" in out
