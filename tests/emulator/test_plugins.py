"""The example plugin package (examples/plugin_package) installed with pip into a private directory
(``--target``: the main environment is left alone) and run from a scenario, unchanged: its filter
(``psns_hil.filters``) and its link scheme (``psns_hil.links``) come in through entry points (docs/plugins.md).

Checked against references: ``scaled_q`` with ``q_scale: 1`` is the base filter (the same filter_state.csv, value
for value, as an in-process base run); with ``q_scale: 4`` its covariance grows faster than the base filter's
(the process noise enters P as Q dt: every diagonal term is at least the base one, and the gyro-bias terms,
driven only by Q between updates, are larger); the ``logfile://`` port holds exactly the bytes the host port
carried, whose frames decode to the run's navigation frames.
"""

from __future__ import annotations

import csv
import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from emulator.assembly.session import run_scenario
from emulator.plugins import filter_names
from emulator.scenario import load_scenario
from protocols.host import HostFormat, NavSolution
from protocols.stream import StreamDecoder

pytestmark = pytest.mark.slow  # pip builds the package (about 10 s) and three short runs

ROOT = Path(__file__).resolve().parents[2]
DURATION_S = 6.0


def _scenario(path: Path, filt: str, params: dict | None = None, host_url: str = "mem://host") -> Path:
    data = yaml.safe_load((ROOT / "scenarios" / "quickstart.yaml").read_text())
    data.update(name=f"plugin_{filt}", duration_s=DURATION_S, mode="fast",
                motion=[{"static": {"duration_s": DURATION_S}}], expectations=[])
    data["sensors"].pop("camera", None)
    data["links"].pop("psns", None)
    data["links"]["host"] = {"url": host_url, "baud": 460800}
    data["firmware"] = {"filter": filt, "params": params or {},
                        "alignment": {"time_s": 1.0, "heading_deg": 30.0, "fine_time_s": 2.0}}
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    """The package, copied (the build writes next to its sources) and installed into a private directory."""
    d = tmp_path_factory.mktemp("plugin")
    src = d / "src"
    shutil.copytree(ROOT / "examples" / "plugin_package", src, ignore=shutil.ignore_patterns("build", "*.egg-info"))
    target = d / "site"
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--target", str(target),
                    str(src)], check=True, timeout=300)
    return target


def _run_with_plugin(site: Path, scenario: Path, out: Path) -> dict:
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(site), str(ROOT)]))
    proc = subprocess.run([sys.executable, "-m", "emulator", "run", str(scenario), "--out", str(out), "--json",
                           "--quiet", "--no-report"], env=env, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    return json.loads(proc.stdout)


def _filter_state(run_dir: Path) -> list[dict[str, str]]:
    return list(csv.DictReader((run_dir / "filter_state.csv").read_text().splitlines()))


def test_the_main_environment_does_not_have_the_plugin():
    assert "scaled_q" not in filter_names()  # installed only into the test's own directory


def test_plugin_filter_and_link_run_from_a_scenario(site, tmp_path):
    base = run_scenario(load_scenario(_scenario(tmp_path / "base.yaml", "base")), tmp_path / "base")
    same = _run_with_plugin(site, _scenario(tmp_path / "q1.yaml", "scaled_q", {"q_scale": 1.0},
                                            host_url="logfile://host_out"), tmp_path / "q1")
    big = _run_with_plugin(site, _scenario(tmp_path / "q4.yaml", "scaled_q", {"q_scale": 4.0}), tmp_path / "q4")
    assert same["firmware"]["filter"] == big["firmware"]["filter"] == "scaled_q"
    assert base["firmware"]["filter"] == "base"

    # q_scale 1 is the base filter, value for value
    fs_base, fs_same, fs_big = (_filter_state(tmp_path / n) for n in ("base", "q1", "q4"))
    assert len(fs_base) == len(fs_same) == len(fs_big) >= DURATION_S - 1
    for a, b in zip(fs_base, fs_same):
        assert a == b
    # q_scale 4: P grows faster (gyro-bias variances p9..p11 are driven by Q alone between updates)
    last_base, last_big = fs_base[-1], fs_big[-1]
    for i in range(15):
        assert float(last_big[f"p{i}"]) >= float(last_base[f"p{i}"]) * (1 - 1e-6)
    for i in (9, 10, 11):
        assert float(last_big[f"p{i}"]) > float(last_base[f"p{i}"]) * 1.000001

    # the logfile:// port got the host port's bytes: its frames are the run's navigation frames
    port = next(p for p in same["ports"] if p["name"] == "host")
    assert port["url"] == "logfile://host_out"
    data = Path(port["path"]).read_bytes()
    assert len(data) == same["link_stats"]["host"]["bytes_out"] > 0
    frames = [f for f in StreamDecoder([HostFormat()]).feed(data) if isinstance(f, NavSolution)]
    assert len(frames) == same["nav_frames"] == base["nav_frames"] > 0


def test_unknown_filter_lists_the_registered_ones_with_the_plugin(site, tmp_path):
    bad = _scenario(tmp_path / "bad.yaml", "scaled")
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(site), str(ROOT)]))
    proc = subprocess.run([sys.executable, "-m", "emulator", "validate", str(bad)], env=env, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode != 0
    assert "unknown filter 'scaled'; did you mean 'scaled_q'?" in proc.stderr
    assert "registered: base, dual_vector, federated, kmeans_3d, scaled_q, sun_elevation" in proc.stderr
    bad = _scenario(tmp_path / "bad2.yaml", "scaled_q", {"q_scal": 2.0})
    proc = subprocess.run([sys.executable, "-m", "emulator", "validate", str(bad)], env=env, capture_output=True,
                          text=True, timeout=120)
    assert "filter 'scaled_q' has no parameter 'q_scal' (did you mean 'q_scale'?)" in proc.stderr
