"""The modelled u-blox's host port is contained (issue 41 item 2): hostile bytes and well-framed CFG / MON messages
with random payloads (valid checksums), hostile NMEA with valid checksums, never raise out of the receiver; each is
answered (ACK / NAK), or counted as ignored, and the receiver keeps sending its epochs."""

from __future__ import annotations

import random

from protocols.crc import nmea_checksum
from protocols.ubx import UbxFrame, build_ubx_frame

from .test_gnss_host_commands import GnssConfig, _session


def _hostile_script(seed: int, n: int) -> list[tuple[float, bytes]]:
    rng = random.Random(seed)
    out = []
    for k in range(n):
        r = rng.random()
        if r < 0.6:  # UBX CFG/MON with a random id and payload of a random length, checksum valid
            cls = rng.choice([0x06, 0x06, 0x0A, 0x01, 0x05, rng.randrange(256)])
            mid = rng.choice([0x00, 0x01, 0x08, 0x04, rng.randrange(256)])
            payload = bytes(rng.getrandbits(8) for _ in range(rng.choice([0, 1, 2, 3, 6, 8, 20, rng.randrange(300)])))
            data = build_ubx_frame(cls, mid, payload)
        elif r < 0.8:  # NMEA from the host with hostile tokens, checksum valid
            body = rng.choice(["PUBX,41,1,0007,0003,19200,0", "PMTK251,1e300", "PUBX,40,GGA," + "9" * 40 + ",0,0,0,0",
                               "GPGGA,1235inf,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,",
                               "GPZDA,201530.00,04,07," + "9" * 40 + ",00,00"])  # once: OverflowError
            data = f"${body}*{nmea_checksum(body.encode()):02X}\r\n".encode()
        else:  # raw garbage, a sync flood
            data = bytes(rng.getrandbits(8) for _ in range(rng.randrange(1, 200))) + b"\xb5b" * rng.randrange(5)
        out.append((0.5 + 0.01 * k, data))
    return out


def test_hostile_host_bytes_never_raise_and_epochs_go_on() -> None:
    script = _hostile_script(20260118, 400)
    script.append((7.0, build_ubx_frame(0x0A, 0x04, b"")))  # then a MON-VER poll: still answered
    rx, got, _raw, _pps = _session(GnssConfig(), script, 8.0)
    assert any(t >= 7.0 and isinstance(f, UbxFrame) and (f.cls, f.id) == (0x0A, 0x04) for t, f in got), \
        "the host port stopped answering after the hostile bytes"
    answered = rx.host_acks + rx.host_naks + rx.host_polls + rx.host_ignored
    assert answered > 100
    assert rx._host_dec.pending() < 1024  # the decoder is not stuck on a sentence
    # the receiver kept sending: an epoch every second after the hostile bytes (1 Hz default)
    times = sorted({round(t) for t, _f in got if t > 5.0})
    assert len(times) >= 2
