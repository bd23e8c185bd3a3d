"""A link URL in a scenario names files too: zenoh's ``auth=FILE`` (credentials) and ``config=FILE`` (session
configuration). They are confined to the scenario's directory as every file a scenario names, resolved against it
(not against the working directory), and the run opens the link with the confined path (decision D-7.32,
docs/hostile-input.md section 6). Before, ``auth=/home/me/other-run/credentials.txt&connect=tcp/far-host:7447``
would have presented another run's password to a far host."""

from __future__ import annotations

import asyncio
import os
import subprocess
import sys
from pathlib import Path

import pytest

from emulator.scenario.paths import ALLOW_HOOKS_ENV, ALLOW_PATHS_ENV, PathNotAllowed, confined_link_url

ROOT = Path(__file__).resolve().parents[3]
QUICKSTART = (ROOT / "scenarios" / "quickstart.yaml").read_text()
HOST_LINE = '  host: {url: "mem://host"'


def _scenario(d: Path, url: str) -> Path:
    assert HOST_LINE in QUICKSTART
    p = d / "s.yaml"
    p.write_text(QUICKSTART.replace(HOST_LINE, f'  host: {{url: "{url}"'))
    return p


def _validate(p: Path) -> subprocess.CompletedProcess[str]:
    env = {k: v for k, v in os.environ.items() if k not in (ALLOW_HOOKS_ENV, ALLOW_PATHS_ENV)}
    return subprocess.run([sys.executable, "-m", "emulator", "validate", str(p)], capture_output=True, text=True,
                          timeout=120, env=env, cwd=ROOT)


@pytest.mark.parametrize("option", ["auth", "config"])
def test_a_link_file_outside_the_scenario_directory_is_refused_whatever_lies_there(tmp_path: Path,
                                                                                  option: str) -> None:
    msgs = []
    for exists in (True, False):
        d = tmp_path / f"c{int(exists)}"
        (d / "scen").mkdir(parents=True)
        secret = d / "secret.txt"
        if exists:
            secret.write_text("psns-hil:abc\n")
            secret.chmod(0o600)
        r = _validate(_scenario(d / "scen", f"zenoh://r1/host?connect=tcp/127.0.0.1:7447&{option}={secret}"))
        assert r.returncode == 2, (r.stdout, r.stderr)
        assert "Traceback" not in r.stderr
        lines = [ln for ln in r.stderr.splitlines() if "outside the scenario's directory" in ln]
        assert len(lines) == 1 and "links.host.url" in lines[0] and f"link {option} file" in lines[0], r.stderr
        msgs.append(lines[0].replace(str(d), "D"))
    assert msgs[0] == msgs[1]  # no existence oracle


def test_link_files_resolve_against_the_scenario_directory(tmp_path: Path, monkeypatch) -> None:
    scen, elsewhere = tmp_path / "scen", tmp_path / "elsewhere"
    scen.mkdir()
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    monkeypatch.delenv(ALLOW_PATHS_ENV, raising=False)
    url = "zenoh://r1/host?connect=tcp/127.0.0.1:7447,tcp/[::1]:7447&auth=creds.txt&config=z/c.json5&pace=0"
    out = confined_link_url(url, scen)
    assert out == (f"zenoh://r1/host?connect=tcp/127.0.0.1:7447,tcp/[::1]:7447&auth={scen.resolve()}/creds.txt"
                   f"&config={scen.resolve()}/z/c.json5&pace=0")
    assert confined_link_url("pty://uart0", scen) == "pty://uart0"
    assert confined_link_url("zenoh://r1/host?listen=tcp/127.0.0.1:7447", scen) == \
        "zenoh://r1/host?listen=tcp/127.0.0.1:7447"
    (scen / "out").symlink_to(elsewhere, target_is_directory=True)  # a link out of the directory
    for bad in ("auth=../elsewhere/creds.txt", "auth=out/creds.txt", "config=/etc/passwd", "auth=~/x"):
        with pytest.raises(PathNotAllowed):
            confined_link_url(f"zenoh://r1/host?{bad}", scen)
    monkeypatch.setenv(ALLOW_PATHS_ENV, str(elsewhere))  # a trusted setup widens the roots
    assert confined_link_url("zenoh://r1/host?auth=../elsewhere/creds.txt", scen) == \
        f"zenoh://r1/host?auth={elsewhere.resolve()}/creds.txt"


def test_the_run_opens_the_link_with_the_confined_path(tmp_path: Path, monkeypatch) -> None:
    """What the run hands to the transport: the path under the scenario's directory, whatever the working
    directory (the link is not opened: the first open_link stops the start)."""
    from emulator.assembly import session
    from emulator.clock import new_loop
    from emulator.scenario.loader import load_scenario

    scen, elsewhere = tmp_path / "scen", tmp_path / "elsewhere"
    scen.mkdir()
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    scn = load_scenario(_scenario(scen, "zenoh://r2/host?listen=tcp/127.0.0.1:7447&auth=creds.txt"))
    opened: list[str] = []

    class Stop(Exception):
        pass

    def fake_open_link(url, *args, **kwargs):  # the run hands over the URL it parsed once (D-11.R1)
        opened.append(url.url)
        assert url.options["auth"] == f"{scen.resolve()}/creds.txt"
        raise Stop

    monkeypatch.setattr(session, "open_link", fake_open_link)
    emu = session.Emulator(scn, run_dir=tmp_path / "run")
    loop = new_loop("fast")
    try:
        with pytest.raises(Stop):
            loop.run_until_complete(emu.start())
    finally:
        loop.close()
        asyncio.set_event_loop(None)
    assert opened == [f"zenoh://r2/host?listen=tcp/127.0.0.1:7447&auth={scen.resolve()}/creds.txt"]
