"""The README and docs/runtime.md examples run as written.

Every ``psns-hil`` command line in their shell blocks parses with the real command line; the pty recipe (a
``my.yaml`` that is the quickstart with the README's ``links`` block, shortened) runs: the ``run`` line as
written, then the ``monitor`` line as written decodes navigation frames from the live pty.
"""

from __future__ import annotations

import re
import shlex
import subprocess
import sys
import time

import pytest
import yaml

from emulator.cli.main import build_parser
from tests.conftest import ROOT

DOCS = [ROOT / "README.md", ROOT / "docs" / "runtime.md"]


def _blocks(path, lang=("sh", "")):
    text = path.read_text(encoding="utf-8")
    return [body for tag, body in re.findall(r"```(\w*)\n(.*?)```", text, re.S) if tag in lang]


def _commands(path):
    out = []
    for block in _blocks(path):
        for line in block.splitlines():
            line = line.split("  #")[0].strip()
            m = re.match(r"^(?:\.venv/bin/)?psns-hil (.*)$", line)
            if m and "[" not in line:  # synopsis lines with [optional] parts are not commands
                out.append(shlex.split(m.group(1)))
    return out


@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.name)
def test_every_documented_command_parses(doc):
    cmds = _commands(doc)
    assert cmds, f"no psns-hil command found in {doc}"
    parser = build_parser()
    for argv in cmds:
        parser.parse_args(argv)  # SystemExit (a usage error) fails the test


def _recipe(doc, verb, arg=None):
    """The first documented ``psns-hil VERB`` command (with ``arg`` among its arguments, when given)."""
    return next(c for c in _commands(doc) if c[0] == verb and (arg is None or arg in c))


@pytest.mark.pty
@pytest.mark.realtime
@pytest.mark.parametrize("doc", DOCS, ids=lambda p: p.name)
def test_the_pty_recipe_runs_as_written(doc, tmp_path):
    readme_links = next(b for b in _blocks(ROOT / "README.md", ("yaml",)) if "pty://" in b)
    data = yaml.safe_load((ROOT / "scenarios" / "quickstart.yaml").read_text())
    data.setdefault("links", {}).update(yaml.safe_load(readme_links)["links"])
    data["duration_s"] = 4
    data["motion"] = [{"static": {"duration_s": 4}}]
    data["expectations"] = []
    (tmp_path / "my.yaml").write_text(yaml.safe_dump(data))
    run_argv = _recipe(doc, "run", "my.yaml")  # the pty recipe (the docs show other runs before it)
    run = subprocess.Popen([sys.executable, "-m", "emulator", *run_argv], cwd=tmp_path, text=True,
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=_env())
    try:
        deadline = time.monotonic() + 90  # start-up builds the camera's fixed pattern first
        while not (tmp_path / "runs" / "live" / "ports" / "uart0").exists():
            assert run.poll() is None, run.communicate()
            assert time.monotonic() < deadline, "the pty never appeared"
            time.sleep(0.05)
        mon_argv = _recipe(ROOT / "docs" / "runtime.md", "monitor")  # as written, plus a frame count to end it
        mon = subprocess.run([sys.executable, "-m", "emulator", *mon_argv, "--count", "20"], cwd=tmp_path,
                             text=True, capture_output=True, timeout=30, env=_env())
        assert mon.returncode == 0, mon.stderr
        assert mon.stdout.count("NavSolution") >= 15
        out, err = run.communicate(timeout=30)
    finally:
        if run.poll() is None:
            run.kill()
    assert run.returncode == 0, err
    assert "runs/live/ports/uart0 -> /dev/pts/" in out


def _env():
    import os

    return {**os.environ, "PYTHONPATH": str(ROOT)}
