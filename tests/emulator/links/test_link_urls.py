"""A transport owns its URL syntax (as pyserial's URL handlers do): ``url_usage``, ``url_options`` and
``check_target`` on its class, read by the one parser, :func:`emulator.links.parse_link_url`."""

from __future__ import annotations

import importlib
from pathlib import Path

import pytest

from emulator.errors import LinkConfigError
from emulator.links import LINK_SCHEMES, parse_link_url
from tests.conftest import ROOT


def _cls(scheme: str):
    mod, name = LINK_SCHEMES[scheme].split(":")
    return getattr(importlib.import_module(mod), name)


@pytest.mark.parametrize("scheme", sorted(LINK_SCHEMES))
def test_every_transport_declares_its_usage_and_errors_show_it(scheme):
    cls = _cls(scheme)
    assert cls.scheme == scheme
    assert cls.url_usage.startswith(f"{scheme}://"), cls.url_usage
    with pytest.raises(LinkConfigError) as exc:
        parse_link_url(f"{scheme}://x?bogus=1")
    assert cls.url_usage in str(exc.value)
    for opt in cls.url_options:  # its own options are accepted (the values are the transport's to check)
        assert opt in cls.url_usage, (scheme, opt)


def test_each_usage_is_written_once_in_the_package():
    sources = {p: p.read_text(encoding="utf-8") for p in (ROOT / "emulator").rglob("*.py")}
    for scheme in LINK_SCHEMES:
        usage = _cls(scheme).url_usage
        head = usage[: min(len(usage), 40)]
        holders = [p.relative_to(ROOT).as_posix() for p, text in sources.items() if head in text]
        assert holders == [f"emulator/links/{scheme}.py"], (scheme, holders)


@pytest.mark.parametrize("url", ["zenoh://run/*", "zenoh://run//port", "can://usb/0", "can://virtual"])
def test_a_target_the_transport_cannot_open_is_refused_when_parsed(url):
    scheme = url.split(":")[0]
    with pytest.raises(LinkConfigError) as exc:
        parse_link_url(url)
    assert _cls(scheme).url_usage in str(exc.value)


@pytest.mark.parametrize("url", ["zenoh://run1/gnss?role=peer", "can://virtual/0?rate=10", "can://socketcan/vcan0",
                                 "serial:///dev/ttyUSB0?baud=9600&pps=dcd", "pty://gnss?peer_baud=check"])
def test_good_urls_parse(url):
    u = parse_link_url(url)
    assert u.scheme == url.split(":")[0] and u.target


def test_the_scenario_refuses_a_bad_zenoh_key_at_load(tmp_path: Path):
    from emulator.errors import ScenarioError
    from emulator.scenario import load_scenario

    p = tmp_path / "s.yaml"
    p.write_text("name: t\nepoch: 2019-09-18T08:14:00Z\nduration_s: 10\n"
                 "origin: {lat_deg: 39.9, lon_deg: 116.3, height_m: 50}\n"
                 "links:\n  host: {url: \"zenoh://run/a*b\"}\n")
    with pytest.raises(ScenarioError, match="zenoh://RUN/PORT"):
        load_scenario(p)
