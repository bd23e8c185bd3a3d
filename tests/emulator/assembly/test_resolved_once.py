"""The scenario resolved once (issue 42 item 5, decision D-11.R1): a run's build merges each sensor's preset once and
parses each port's URL once (counted by wrapping the real functions wherever the emulator has bound them), and
``psns-hil validate --effective`` prints the values the run is built from and uses."""

from __future__ import annotations

import collections
import json
import sys
from typing import Any

import pytest

import emulator.links as links_pkg
import emulator.scenario.presets as presets_mod
from emulator.assembly.session import Emulator, run_emulator
from emulator.devices.imu.stim210 import group_delay_s
from emulator.scenario.resolved import SENSOR_KINDS
from emulator.testing import load_test_scenario
from tests.conftest import SCENARIOS

QS = SCENARIOS / "quickstart.yaml"
#: the quickstart with real ports (ptys: one replacing the host, one carrying the modelled GNSS out, the monitor)
#: beside the in-process ones, in virtual time; short
OVERRIDES: dict[str, Any] = {
    "duration_s": 0.5, "motion": [{"static": {"duration_s": 0.5}}], "expectations": [], "mode": "fast",
    "links.host.url": "pty://host", "links.gnss.url": "pty://gnss", "links.gnss.direction": "tee",
    "links.monitor": {"url": "pty://monitor"},
}


def _counting(monkeypatch: pytest.MonkeyPatch) -> collections.Counter[str]:
    """Count the calls of the links package's URL parser (by URL) and of the preset loader (by kind): each real
    function is wrapped (it still runs) and the wrapper bound wherever an emulator module holds the original."""
    calls: collections.Counter[str] = collections.Counter()
    parse0, preset0 = links_pkg.parse_link_url, presets_mod.preset

    def parse(url: str, *a: Any, **kw: Any) -> Any:
        calls[f"url {url}"] += 1
        return parse0(url, *a, **kw)

    def preset(kind: str, name: str) -> dict[str, Any]:
        calls[f"preset {kind}"] += 1
        return preset0(kind, name)

    for mod in list(sys.modules.values()):
        if not getattr(mod, "__name__", "").startswith("emulator"):
            continue
        if getattr(mod, "parse_link_url", None) is parse0:
            monkeypatch.setattr(mod, "parse_link_url", parse)
        if getattr(mod, "preset", None) is preset0:
            monkeypatch.setattr(mod, "preset", preset)
    return calls


def test_a_run_merges_each_preset_once_and_parses_each_url_once(tmp_path, monkeypatch):
    scn = load_test_scenario(QS, OVERRIDES)  # validation parses the URLs and checks presets: not counted
    calls = _counting(monkeypatch)
    emu = Emulator(scn, tmp_path / "run")
    summary = run_emulator(emu)
    assert summary["sim_duration_s"] == pytest.approx(0.5)
    urls = {f"url {spec.url}" for spec in (scn.links.gyro, scn.links.gnss, scn.links.host, scn.links.psns,
                                            scn.links.monitor) if spec is not None}
    assert len(urls) == 5
    # every port's URL parsed once (the pty ones were opened from that parse; the tee'd GNSS port too), each
    # sensor's preset loaded once (the IMU's five settings and the firmware's ranges read one merge)
    assert dict(calls) == {**dict.fromkeys(urls, 1), **{f"preset {k}": 1 for k in SENSOR_KINDS}}
    # and what was opened is what the parse said
    ports = {p["name"]: p for p in json.loads((tmp_path / "run" / "ports.json").read_text())}
    assert ports["host"]["url"] == "pty://host" and ports["gnss"]["url"] == "pty://gnss"
    assert ports["gnss"]["direction"] == "tee" and ports["gyro"]["direction"] == "model"


def _set_args(overrides: dict[str, Any]) -> list[str]:
    out: list[str] = []
    for k, v in overrides.items():
        out += ["--set", f"{k}={json.dumps(v)}"]  # JSON is YAML: each value as --set reads it
    return out


def test_validate_effective_prints_what_the_run_is_built_from_and_uses(tmp_path, capsys):
    from emulator.cli.main import main

    assert main(["validate", str(QS), "--effective", *_set_args(OVERRIDES)]) == 0
    printed = json.loads(capsys.readouterr().out)
    scn = load_test_scenario(QS, OVERRIDES)
    emu = Emulator(scn, tmp_path / "run")
    # the same resolution: the run's configuration is the printed one, value for value
    assert json.loads(json.dumps(emu.cfg.as_dict())) == printed
    run_emulator(emu)
    # ... and the built run used those values: the seed, the mode, each port's URL, each sensor's merged figures
    assert (printed["seed"], printed["mode"]) == (emu.seed, emu.mode) == (scn.seed, "fast")
    for name, p in printed["ports"].items():  # a port bound out: its real port; else the FPGA's link
        opened = emu.bindings[name].port if name in emu.bindings else emu.links[name]
        assert (opened.url, opened.scheme) == (p["url"], p["scheme"]), name
    assert printed["ports"]["gnss"]["direction"] == "tee" and set(emu.bindings) == {"gnss"}
    imu = printed["sensors"]["imu"]
    assert imu["preset"] == "field"  # the quickstart's suite preset
    gyro = emu.sensors.gyro
    for k, v in imu["gyro"].items():
        got = getattr(gyro.err, k)
        assert (list(got) if isinstance(got, tuple) else got) == v, k
    for k, v in imu["accel"].items():
        got = getattr(emu.sensors.accel.err, k)
        assert (list(got) if isinstance(got, tuple) else got) == v, k
    assert imu["lp_filter_hz"] == 262.0 and gyro.group_delay_s == group_delay_s(262.0) > 0
    fw = emu.fw
    assert fw is not None
    assert fw.cfg.gyro_range_dps == imu["gyro"]["range_dps"]  # type: ignore[attr-defined]
    gnss = printed["sensors"]["gnss"]
    assert emu.gnss is not None and emu.gnss.cfg.latency_s == gnss["latency_s"]
    for k, v in gnss["errors"].items():
        got = getattr(emu.gnss.cfg.errors, k)
        assert (list(got) if isinstance(got, tuple) else got) == v, k
    comp = printed["sensors"]["compass"]
    assert emu.unit.compass.dop_noise_model == comp["dop_noise_model"]
    mag = printed["sensors"]["magnetometer"]
    assert emu.unit.magnetometer.noise_nt == mag["noise_nt"]
    assert list(emu.unit.magnetometer.hard_iron_nt) == mag["hard_iron_nt"]
