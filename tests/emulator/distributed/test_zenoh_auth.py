"""zenoh authentication (issue 41 item 4, decision D-9.6): an uninvited local process is refused.

The intruder is a real zenoh session opened here without the run's credentials (as any local process could before):
it must neither see a key nor get a byte into the run. The witness is a session with the credentials, opened the same
way, which sees and delivers everything in the same time.
"""

from __future__ import annotations

import json
import os
from typing import Any

import pytest

from emulator.errors import LinkConfigError
from emulator.links.zenoh import ZenohCredentials, ZenohEndpointConfig, open_sessions, run_credentials

from .conftest import free_tcp_port, wait_until, write_short_scenario

pytestmark = pytest.mark.realtime  # sockets on the wall clock


def _uninvited_config(connect: str, mode: str = "peer", creds: ZenohCredentials | None = None) -> Any:
    """A plain zenoh configuration as a local tool would write it (scouting off, loopback)."""
    import zenoh

    cfg = zenoh.Config()
    cfg.insert_json5("mode", json.dumps(mode))
    cfg.insert_json5("scouting/multicast/enabled", "false")
    cfg.insert_json5("scouting/gossip/enabled", "false")
    cfg.insert_json5("listen/endpoints", "[]")
    cfg.insert_json5("connect/endpoints", json.dumps([connect]))
    if creds is not None:
        cfg.insert_json5("transport/auth/usrpwd", json.dumps({"user": creds.user, "password": creds.password}))
    return cfg


class _Inbound:
    """Link listener: what the device end received from the far side."""

    def __init__(self) -> None:
        self.data = bytearray()

    def on_link_bytes(self, link: Any, direction: str, t: float, data: bytes) -> None:
        if direction == "in":
            self.data += data


def test_an_uninvited_zenoh_session_sees_no_key_and_publishes_into_nothing(zenoh_links, rt_loop, tmp_path):
    import zenoh

    p = free_tcp_port()
    ep = f"tcp/127.0.0.1:{p}"
    gnss = zenoh_links(f"zenoh://auth1/gnss?listen={ep}", "gnss")
    inbound = _Inbound()
    gnss.listeners.append(inbound)
    seen: dict[str, list[str]] = {"witness": [], "intruder": [], "wrong_password": []}

    def recorder(who: str) -> Any:
        return lambda smp: seen[who].append(str(smp.key_expr))

    # a client-mode session without credentials cannot even open: its only transport is refused
    with pytest.raises(zenoh.ZError):
        zenoh.open(_uninvited_config(ep, mode="client"))
    wrong = ZenohCredentials.generate(str(tmp_path))  # a well-formed pair that is not the run's
    with zenoh.open(_uninvited_config(ep)) as intruder, \
            zenoh.open(_uninvited_config(ep, creds=wrong)) as wrong_pw, \
            zenoh.open(ZenohEndpointConfig(connect=(ep,)).build()) as witness:
        subs = [intruder.declare_subscriber("psns/**", recorder("intruder")),
                wrong_pw.declare_subscriber("psns/**", recorder("wrong_password")),
                witness.declare_subscriber("psns/**", recorder("witness"))]
        try:
            # the GNSS-off attempt of the audit: bytes into the port's rx key, before the witness's own
            intruder.put("psns/auth1/gnss/rx", b"$PSNSX,GNSS,OFF*00\r\n")
            wrong_pw.put("psns/auth1/gnss/rx", b"$PSNSX,GNSS,OFF*00\r\n")

            async def main() -> None:
                assert await wait_until(gnss.peer_matched, 10.0)
                witness.put("psns/auth1/gnss/rx", b"$GPGGA,witness\r\n")
                gnss.send(b"$GPRMC,from-the-box\r\n")
                assert await wait_until(lambda: bytes(inbound.data) == b"$GPGGA,witness\r\n"
                                        and "psns/auth1/gnss/tx" in seen["witness"], 10.0)

            rt_loop.run_until_complete(main())
            # the device's session knows one peer, the witness; the intruders have no transport at all
            peers = {str(z) for z in gnss.session.info.peers_zid()}
            assert peers == {str(witness.info.zid())}
            assert list(intruder.info.peers_zid()) == [] and list(wrong_pw.info.peers_zid()) == []
        finally:
            for s in subs:
                s.undeclare()
    # each intruder sees only its own put (zenoh delivers a session's samples to its own subscribers): not the box's
    # tx, not the witness's rx
    assert seen["intruder"] == ["psns/auth1/gnss/rx"] and seen["wrong_password"] == ["psns/auth1/gnss/rx"]
    assert seen["witness"].count("psns/auth1/gnss/rx") == 1  # the witness's own; the intruders' never crossed
    assert bytes(inbound.data) == b"$GPGGA,witness\r\n"  # nothing of the intruders' reached the port


def test_credentials_are_per_run_private_and_never_printed(tmp_path, rt_loop):
    from emulator.links import open_link

    creds = run_credentials()
    shown = open_link("zenoh://r/host?listen=tcp/127.0.0.1:1", "host", rt_loop).describe()
    assert shown.endswith(f"credentials {creds.file})")  # the path (ports.json), never the password
    assert os.environ["PSNS_HIL_ZENOH_AUTH"] == creds.file  # what processes started by the run inherit
    assert os.stat(creds.file).st_mode & 0o777 == 0o600
    assert os.stat(os.path.dirname(creds.file)).st_mode & 0o777 == 0o700
    assert len(creds.password) >= 43 and creds.password not in repr(creds)  # 256 bits, not in a repr
    assert ZenohCredentials.load(creds.file).password == creds.password
    loose = tmp_path / "loose.txt"
    loose.write_text("u:p\n")
    loose.chmod(0o644)
    with pytest.raises(LinkConfigError, match="readable by group or others"):
        ZenohCredentials.load(str(loose))
    bad = tmp_path / "bad.txt"
    bad.write_text("secret-without-colon\n")
    bad.chmod(0o600)
    with pytest.raises(LinkConfigError, match="expected one line USER:PASSWORD") as ei:
        ZenohCredentials.load(str(bad))
    assert "secret-without-colon" not in str(ei.value)  # the content is never quoted


def test_a_split_run_refuses_an_uninvited_session_and_its_gnss_is_unaffected(tmp_path):
    """The audit's case: during ``--split`` an uninvited session subscribes to everything and publishes into the
    DSP's GNSS UART (``uart3/tx`` is what the DSP process receives). It sees nothing, and the DSP process receives
    exactly the bytes the FPGA sent on UART3."""
    import zenoh

    from emulator.assembly.session import run_emulator
    from emulator.distributed.split import SplitFpgaEmulator
    from emulator.scenario import load_scenario

    scn = load_scenario(write_short_scenario(tmp_path / "s.yaml", 3.0, name="split_auth", mode="realtime",
                                             expectations=[]))
    emu = SplitFpgaEmulator(scn, tmp_path / "run")
    seen: list[str] = []
    state: dict[str, Any] = {}

    def on_started(e: Any) -> None:
        s = zenoh.open(_uninvited_config(f"tcp/127.0.0.1:{e.zenoh_port}"))
        state["session"] = s
        state["sub"] = s.declare_subscriber("psns/**", lambda smp: seen.append(str(smp.key_expr)))
        for _ in range(50):
            s.put(f"psns/{e.run_key}/uart3/tx", b"$GPGGA,000000.00,0000.0000,N,00000.0000,E,0,00,,,M,,M,,*66\r\n")
            s.put(f"psns/{e.run_key}/ctl/stop", b"{}")
        state["peers"] = list(s.info.peers_zid())

    try:
        summary = run_emulator(emu, 2.0, on_started)
    finally:
        if "session" in state:
            state["sub"].undeclare()
            state["session"].close()
    assert summary["split"]["error"] is None and not summary["interrupted"]
    assert set(seen) <= {f"psns/{emu.run_key}/uart3/tx", f"psns/{emu.run_key}/ctl/stop"}  # its own puts only
    assert len(seen) <= 100 and state["peers"] == []
    # what the DSP process received on UART3 is exactly what the FPGA sent, none of the intruder's 50 sentences
    fpga_out = summary["link_stats"]["uart3"]["bytes_out"]
    dsp_in = summary["split"]["dsp_link_stats"]["uart3"]["bytes_in"]
    assert fpga_out > 0 and dsp_in == fpga_out
    events = (tmp_path / "run" / "events.jsonl").read_text().splitlines()
    updates = [ev for ev in map(json.loads, events) if ev["event"] == "gnss_update"]
    assert len(updates) >= 1  # the DSP navigated with GNSS
    assert open_sessions() == 0
