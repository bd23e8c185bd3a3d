"""The entry-point registries (emulator.plugins) with entry points made in the test (no package installed):
a whole firmware through ``psns_hil.firmware`` is all the virtual DSP and the summary use (FirmwareProtocol), a
broken plugin is reported where a scenario names it, built-in names are never replaced, link schemes come
from ``psns_hil.links``."""

from __future__ import annotations

from importlib.metadata import EntryPoint
from pathlib import Path

import pytest
import yaml

import emulator.plugins as plugins
from emulator.assembly.session import run_scenario
from emulator.errors import LinkConfigError
from emulator.links import parse_link_url
from emulator.scenario import load_scenario
from emulator.scenario.loader import ScenarioError
from firmware_model.config import FILTER_VARIANTS
from firmware_model.registry import FIRMWARE_IMPLEMENTATIONS, FirmwareProtocol, FirmwareSnapshot

ROOT = Path(__file__).resolve().parents[2]


class CountingFirmware:
    """A firmware that takes every byte and never runs a tick: it counts what each UART brought."""

    def __init__(self, cfg) -> None:
        self.cfg = cfg
        self.rx: dict[int, int] = {}
        self.misses = 0

    def receive(self, uart: int, data: bytes, t_rx_s: float | None = None) -> None:
        self.rx[uart] = self.rx.get(uart, 0) + len(data)

    def service(self) -> list:
        return []

    def note_deadline_miss(self) -> None:
        self.misses += 1

    def snapshot(self) -> FirmwareSnapshot:
        return FirmwareSnapshot(state="counting", mode=0, filter=self.cfg.filter, precision=self.cfg.precision,
                                counters={f"uart{u}_bytes": n for u, n in sorted(self.rx.items())})


@pytest.fixture
def eps(monkeypatch):
    """Install entry points (group -> [(name, value)]) for one test; the registries are restored after it."""
    filters, impls = dict(FILTER_VARIANTS), dict(FIRMWARE_IMPLEMENTATIONS)
    table: dict[str, list[EntryPoint]] = {}

    def fake(group: str):
        return table.get(group, [])

    def install(group: str, name: str, value: str) -> None:
        table.setdefault(group, []).append(EntryPoint(name=name, value=value, group=group))
        plugins.reset()

    monkeypatch.setattr(plugins, "entry_points", fake)
    plugins.reset()
    yield install
    plugins.reset()
    FILTER_VARIANTS.clear()
    FILTER_VARIANTS.update(filters)
    FIRMWARE_IMPLEMENTATIONS.clear()
    FIRMWARE_IMPLEMENTATIONS.update(impls)


def _scenario(path: Path, firmware: dict) -> Path:
    data = {"name": "plugins", "seed": 3, "epoch": "2019-09-18T02:30:00Z", "duration_s": 2.0, "mode": "fast",
            "origin": {"lat_deg": 39.9, "lon_deg": 116.3, "height_m": 50.0},
            "attitude": {"heading_deg": 30.0, "pitch_deg": 0.0, "roll_deg": 0.0},
            "motion": [{"static": {"duration_s": 2.0}}], "firmware": firmware}
    path.write_text(yaml.safe_dump(data, sort_keys=False))
    return path


def test_a_firmware_plugin_is_all_the_dsp_and_the_summary_use(eps, tmp_path):
    eps("psns_hil.firmware", "counting", f"{__name__}:CountingFirmware")
    assert isinstance(CountingFirmware(None), FirmwareProtocol)
    scn = load_scenario(_scenario(tmp_path / "s.yaml", {"implementation": "counting"}))
    s = run_scenario(scn, tmp_path / "run")
    # this firmware never runs a tick: the DSP's main loop is idle all along and empties the RX ring as the bytes
    # come (emulator.dsp.host), so every UART1 byte reaches it and none overflows the ring
    imu_in = s["link_stats"]["uart1"]["bytes_in"]
    assert imu_in > 4096 and s["firmware"]["counters"]["uart1_bytes"] == imu_in
    assert s["dsp"]["uarts"]["uart1"]["ring_overflow_bytes"] == 0
    assert s["firmware"]["counters"]["uart3_bytes"] == s["link_stats"]["uart3"]["bytes_in"] > 0
    assert s["nav_frames"] == 0 and s["dsp"]["ticks"] == 0 and s["dsp"]["tasks"] == []
    rows = (tmp_path / "run" / "filter_state.csv").read_text().splitlines()
    assert rows[0] == "time_s,state,mode" and rows[1].split(",")[1:] == ["counting", "0"]


def test_unknown_firmware_lists_the_registered_ones(eps, tmp_path):
    eps("psns_hil.firmware", "counting", f"{__name__}:CountingFirmware")
    with pytest.raises(ScenarioError, match=r"unknown firmware implementation 'countin'; did you mean 'counting'\? "
                                            r"registered: counting, psns_hil"):
        load_scenario(_scenario(tmp_path / "s.yaml", {"implementation": "countin"}))


def test_a_broken_filter_plugin_is_reported_where_a_scenario_names_it(eps, tmp_path):
    eps("psns_hil.filters", "broken", "no_such_module_xyz:Filter")
    with pytest.raises(ScenarioError, match=r"filter 'broken': its plugin failed to load: no_such_module_xyz:Filter: "
                                            r"ModuleNotFoundError"):
        load_scenario(_scenario(tmp_path / "s.yaml", {"filter": "broken"}))
    load_scenario(_scenario(tmp_path / "ok.yaml", {"filter": "base"}))  # the others are not affected


def test_a_plugin_never_replaces_a_built_in_name(eps, tmp_path):
    base = FILTER_VARIANTS["base"]
    eps("psns_hil.filters", "base", f"{__name__}:CountingFirmware")
    eps("psns_hil.links", "pty", "emulator.links.mem:MemLink")
    from emulator.dsp.firmware_setup import register_plugins
    from emulator.links import link_schemes

    register_plugins()
    assert FILTER_VARIANTS["base"] is base
    assert "built in" in plugins.PLUGIN_ERRORS[("psns_hil.filters", "base")]
    assert link_schemes()["pty"] == "emulator.links.pty:PtyLink"


def test_link_schemes_come_from_entry_points(eps):
    with pytest.raises(LinkConfigError, match=r"unknown link scheme 'memo' in 'memo://x' \(did you mean 'mem'\?\)"):
        parse_link_url("memo://x")
    eps("psns_hil.links", "memo", "emulator.links.mem:MemLink")
    assert parse_link_url("memo://x?baud=9600").scheme == "memo"
    with pytest.raises(LinkConfigError, match=r"unknown option\(s\) bogus; expected memo://\.\.\."):
        parse_link_url("memo://x?bogus=1")
    eps("psns_hil.links", "gone", "no_such_module_xyz:Link")
    with pytest.raises(LinkConfigError, match=r"the gone:// transport .* could not be loaded: .*ModuleNotFoundError"):
        parse_link_url("gone://x")


# -- issue 41 item 8: validate checks the firmware side; a run imports only the plugins it names --------------------

class NotAFilter:
    """An entry point of ``psns_hil.filters`` whose object is no NavFilter."""


def _validate(path: Path, capsys) -> tuple[int, str]:
    from emulator.cli.main import main

    rc = main(["validate", str(path)])
    return rc, capsys.readouterr().err


def test_validate_refuses_a_filter_plugin_that_is_not_a_navfilter(eps, tmp_path, capsys):
    eps("psns_hil.filters", "odd", f"{__name__}:NotAFilter")
    p = _scenario(tmp_path / "s.yaml", {"filter": "odd"})
    load_scenario(p)  # the schema knows the name (it imports nothing of the firmware)
    rc, err = _validate(p, capsys)
    assert rc == 2 and "Traceback" not in err
    assert "firmware.filter: 'odd' cannot be used: not a firmware_model.filters.interface.NavFilter subclass" in err
    assert str(p) in err


def test_validate_refuses_a_firmware_plugin_that_is_not_callable(eps, tmp_path, capsys):
    eps("psns_hil.firmware", "odd_fw", f"{__name__}:ROOT")
    rc, err = _validate(_scenario(tmp_path / "s.yaml", {"implementation": "odd_fw"}), capsys)
    assert rc == 2 and "firmware.implementation: 'odd_fw' cannot be used: not callable" in err


@pytest.mark.parametrize("sheet, text, expect", [
    ("nosuch.yaml", None, "firmware.spec_sheet: nosuch.yaml: no such file"),
    ("bad.yaml", "figures: [1, 2\n", "firmware.spec_sheet: bad.yaml"),
    ("wrong.yaml", "gyro.arw_deg_rt_h: -3\n", "firmware.spec_sheet: wrong.yaml"),
])
def test_validate_reads_the_spec_sheet_file(eps, tmp_path, capsys, sheet, text, expect):
    """Before issue 41 ``validate`` said ok for a scenario whose spec sheet is missing or invalid; ``run`` then
    failed."""
    if text is not None:
        (tmp_path / sheet).write_text(text)
    rc, err = _validate(_scenario(tmp_path / "s.yaml", {"spec_sheet": sheet}), capsys)
    assert rc == 2 and "Traceback" not in err and expect in err


def test_validate_accepts_the_default_scenario_firmware(eps, tmp_path, capsys):
    rc, err = _validate(_scenario(tmp_path / "s.yaml", {"filter": "base"}), capsys)
    assert rc == 0, err


def test_a_run_imports_only_the_plugins_it_names(eps, tmp_path):
    """Two broken plugins installed, neither named: building the firmware imports neither (a failed import would
    be recorded in PLUGIN_ERRORS); naming one imports that one only."""
    from emulator.dsp.firmware_setup import build_firmware

    eps("psns_hil.filters", "broken_f", "no_such_module_xyz:Filter")
    eps("psns_hil.firmware", "broken_fw", "no_such_module_xyz:Firmware")
    eps("psns_hil.firmware", "counting", f"{__name__}:CountingFirmware")
    build_firmware(load_scenario(_scenario(tmp_path / "s.yaml", {"filter": "base"})))
    assert plugins.PLUGIN_ERRORS == {}
    fw = build_firmware(load_scenario(_scenario(tmp_path / "c.yaml", {"implementation": "counting"})))
    assert isinstance(fw, CountingFirmware) and plugins.PLUGIN_ERRORS == {}
    assert "broken_f" not in FILTER_VARIANTS
