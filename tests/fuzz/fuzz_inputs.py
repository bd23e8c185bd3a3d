"""Long seeded fuzz of every decoder and of the firmware's input path (``make fuzz``; not part of the test run).

``python -m tests.fuzz.fuzz_inputs [--decoder-cases N] [--firmware-cases M] [--seed S]``

* Decoders: every frame format the firmware and the monitor tool use, alone and all together, fed mutated valid
  frames (bit flips, hostile bytes, truncation, duplication, splices, random chunking). A decoder must never raise.
* Firmware input path: a :class:`Firmware` (every filter variant in turn) navigating on a clean synthetic stream
  receives well-framed hostile messages on every UART: NMEA sentences whose fields are replaced by hostile tokens
  (``nan``, ``inf``, ``1e300``, out-of-range values) with a valid checksum, NAV-PVT with random field values,
  IMU frames with random words and time stamps, random host commands and PSNS frames, and the mutated byte streams
  above; then it runs its ticks (strict: any exception counts). After every tick the navigation state must be finite.

Prints the case counts and the number of exceptions; exit 1 when any case raised or left a non-finite state.
"""

from __future__ import annotations

import argparse
import dataclasses
import random
import sys
import time
import traceback
from collections.abc import Callable, Iterator

import numpy as np

from firmware_model import Firmware, FirmwareConfig
from firmware_model.config import FILTER_VARIANTS
from protocols.crc import nmea_checksum
from protocols.host import HostFormat
from protocols.imu_frame import FpgaFrameFormat, ImuFrame, ImuFrameFormat
from protocols.monitor import MonitorFormat
from protocols.nmea import NmeaFormat
from protocols.psns import PsnsFormat
from protocols.stim import Stim210Format
from protocols.stream import StreamDecoder
from protocols.ubx import NavPvt, UbxFormat, encode_nav_pvt

from ..firmware_model.synth import SensorErrors, StaticTruth, StreamConfig, static_stream

UART_HOST, UART_IMU, UART_PSNS, UART_GNSS = 0, 1, 2, 3
HOSTILE_TOKENS = ["nan", "NaN", "inf", "-inf", "Infinity", "1e300", "-1e300", "1e-320", "", "-", ".", "9" * 40,
                  "-0", "0x1A", "1_000", "+5", " 5", "99999.99999", "-99999", "361", "-1", "9100.0", "18100.0"]
EDGES = [0, 1, -1, 2**7 - 1, -(2**7), 2**15 - 1, -(2**15), 2**23 - 1, -(2**23), 2**31 - 1, -(2**31)]


def seed_frames(seconds: float = 12.0) -> dict[int, list[bytes]]:
    """Valid messages per UART from a clean synthetic stream (NMEA and UBX GNSS, IMU, PSNS)."""
    out: dict[int, list[bytes]] = {UART_IMU: [], UART_GNSS: [], UART_PSNS: []}
    for gnss in ("nmea", "ubx"):
        for _t, uart, data in static_stream(StaticTruth(), SensorErrors(), StreamConfig(gnss_output=gnss), seconds):
            if uart in out and (uart == UART_GNSS or gnss == "nmea"):
                out[uart].append(data)
    return out


def mutate(rng: random.Random, data: bytes) -> bytes:
    b = bytearray(data)
    for _ in range(rng.randint(1, 4)):
        op = rng.randrange(7)
        if op == 0 and b:  # bit flip
            i = rng.randrange(len(b))
            b[i] ^= 1 << rng.randrange(8)
        elif op == 1 and b:  # hostile byte
            b[rng.randrange(len(b))] = rng.choice([0x00, 0xFF, 0x24, 0x0A, 0x0D, 0x2A, 0xB5, 0x62, 0x2C, 0x80])
        elif op == 2 and b:  # truncate
            del b[rng.randrange(len(b)) :]
        elif op == 3 and b:  # duplicate a slice
            i = rng.randrange(len(b))
            j = min(len(b), i + rng.randint(1, 64))
            b[i:i] = b[i:j]
        elif op == 4:  # random bytes
            i = rng.randrange(len(b) + 1)
            b[i:i] = bytes(rng.getrandbits(8) for _ in range(rng.randint(1, 16)))
        elif op == 5 and b:  # delete
            i = rng.randrange(len(b))
            del b[i : i + rng.randint(1, 8)]
        else:  # a run of one byte (stuck line, sync flood)
            i = rng.randrange(len(b) + 1)
            b[i:i] = bytes([rng.choice([0x00, 0x24, 0xB5, 0xAA, 0x55])]) * rng.randint(1, 300)
    return bytes(b)


def hostile_nmea(rng: random.Random, sentence: bytes) -> bytes:
    """A sentence whose fields are replaced by hostile tokens, re-checksummed so it reaches the parser."""
    try:
        body = sentence[1 : sentence.index(b"*")].decode("ascii")
    except ValueError:
        return sentence
    f = body.split(",")
    for _ in range(rng.randint(1, 3)):
        f[rng.randrange(1, len(f))] = rng.choice(HOSTILE_TOKENS) if rng.random() < 0.8 else str(rng.uniform(-1e6, 1e6))
    body = ",".join(f)
    return f"${body}*{nmea_checksum(body.encode()):02X}\r\n".encode()


_PVT_FIELDS = [f.name for f in dataclasses.fields(NavPvt)]


def hostile_pvt(rng: random.Random, p: NavPvt) -> bytes:
    changes = {}
    for name in rng.sample(_PVT_FIELDS, rng.randint(1, 4)):
        v = rng.choice([*EDGES, rng.randint(-2 ** 31, 2 ** 31 - 1), 60, 13, 0, 32, 24])
        changes[name] = v
    try:
        return encode_nav_pvt(dataclasses.replace(p, **changes))
    except Exception:
        return encode_nav_pvt(dataclasses.replace(p, **{k: max(0, min(int(v), 255)) for k, v in changes.items()}))


def hostile_imu(rng: random.Random, fr: ImuFrame) -> ImuFrame:
    ch: dict[str, object] = {}
    r = rng.random()
    if r < 0.3:
        ch["gyro"] = tuple(rng.choice([*EDGES[:9], rng.randint(-2 ** 23, 2 ** 23 - 1)]) for _ in range(3))
    elif r < 0.6:
        ch["accel"] = tuple(rng.choice([*EDGES[:9], rng.randint(-2 ** 23, 2 ** 23 - 1)]) for _ in range(3))
    elif r < 0.8:
        ch["t_trigger_us"] = (fr.t_trigger_us + rng.choice([-5000, 0, 1, 10_000_000, 1_000_000_000, 2**31])) \
            & 0xFFFFFFFF
    else:
        ch["t_pps_us"] = rng.getrandbits(32)
        ch["pps_count"] = rng.getrandbits(8)
        ch["fpga_status"] = rng.getrandbits(8)
    return dataclasses.replace(fr, **ch)  # type: ignore[arg-type]


DECODER_SETS: dict[str, Callable[[], list[object]]] = {
    "gnss": lambda: [NmeaFormat(), UbxFormat()], "imu": lambda: [FpgaFrameFormat()], "host": lambda: [HostFormat()],
    "psns": lambda: [PsnsFormat()], "stim210": lambda: [Stim210Format("m")], "monitor": lambda: [MonitorFormat()],
    "all": lambda: [HostFormat(), FpgaFrameFormat(), Stim210Format("m"), NmeaFormat(), PsnsFormat(), UbxFormat(),
                    MonitorFormat()],
}


def fuzz_decoders(n: int, seed: int, seeds: list[bytes]) -> tuple[int, int]:
    rng = random.Random(seed)
    cases = errors = 0
    names = list(DECODER_SETS)
    decs = {k: StreamDecoder(DECODER_SETS[k]()) for k in names}  # type: ignore[arg-type]
    while cases < n:
        k = names[cases % len(names)]
        data = mutate(rng, b"".join(rng.choice(seeds) for _ in range(rng.randint(1, 3))))
        try:
            p = 0
            while p < len(data):  # random chunking
                q = p + rng.randint(1, 64)
                decs[k].feed(data[p:q])
                p = q
            if decs[k].pending() > 1 << 16:
                raise AssertionError(f"{k}: buffer grew to {decs[k].pending()}")
        except Exception:
            errors += 1
            if errors <= 5:
                traceback.print_exc()
            decs[k] = StreamDecoder(DECODER_SETS[k]())  # type: ignore[arg-type]
        cases += 1
    return cases, errors


def _clean_fw(variant: str) -> tuple[Firmware, Iterator[tuple[float, int, bytes]]]:
    fw = Firmware(FirmwareConfig(filter=variant, fine_align_time_s=2.0))
    fw.raise_faults = True
    stream = static_stream(StaticTruth(), SensorErrors(), StreamConfig(), 1e6)
    for t, uart, data in stream:
        fw.receive(uart, data, t)
        if uart == UART_IMU:
            fw.service()
        if t > 6.0:
            break
    return fw, stream


def fuzz_firmware(n: int, seed: int, seeds: dict[int, list[bytes]]) -> tuple[int, int]:
    rng = random.Random(seed)
    imu_fmt = ImuFrameFormat()
    pvt_seed = next(o for d in seeds[UART_GNSS] for o in StreamDecoder([UbxFormat()]).feed(d))
    nmea_seeds = [d for d in seeds[UART_GNSS] if d.startswith(b"$")]
    imu_seed = StreamDecoder([imu_fmt]).feed(seeds[UART_IMU][0])[0]
    all_seeds = [d for v in seeds.values() for d in v]
    cases = errors = 0
    variants = sorted(FILTER_VARIANTS)
    per_variant = max(1, n // len(variants))
    for variant in variants:
        fw, stream = _clean_fw(variant)
        done = 0
        while done < per_variant:
            # one clean second of stream between bursts of hostile messages, so the firmware keeps navigating
            t = 0.0
            for t, uart, data in stream:
                if rng.random() < 0.2:
                    kind = rng.randrange(6)
                    try:
                        if kind == 0:
                            lines = [x for x in rng.choice(nmea_seeds).split(b"\r\n") if x]
                            fw.receive(UART_GNSS, hostile_nmea(rng, rng.choice(lines) + b"\r\n"), t)
                        elif kind == 1:
                            fw.receive(UART_GNSS, hostile_pvt(rng, pvt_seed), t)
                        elif kind == 2:
                            fr = dataclasses.replace(imu_seed, t_trigger_us=fw._t_last_us or 0)
                            fw.receive(UART_IMU, imu_fmt.build(hostile_imu(rng, fr)), t)
                        elif kind == 3:
                            fw.receive(rng.randrange(4), mutate(rng, rng.choice(all_seeds)), t)
                        elif kind == 4:
                            fw.receive(UART_HOST, bytes(rng.getrandbits(8) for _ in range(rng.randint(1, 64))), t)
                        else:
                            fw.receive(UART_PSNS, mutate(rng, rng.choice(seeds[UART_PSNS])), t)
                        for r in fw.service():
                            if fw.nav is not None and not (np.isfinite(fw.nav.q).all() and np.isfinite(fw.nav.pos).all()
                                                           and np.isfinite(fw.nav.v).all()):
                                raise AssertionError(f"non-finite navigation state at t = {r.t_fpga_s}")
                    except Exception:
                        errors += 1
                        if errors <= 5:
                            traceback.print_exc()
                        fw, stream = _clean_fw(variant)
                        break
                    cases += 1
                    done += 1
                    if done >= per_variant:
                        break
                fw.receive(uart, data, t)
                if uart == UART_IMU:
                    try:
                        fw.service()
                    except Exception:
                        errors += 1
                        if errors <= 5:
                            traceback.print_exc()
                        fw, stream = _clean_fw(variant)
                        break
    return cases, errors


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m tests.fuzz.fuzz_inputs", description=__doc__.split("\n\n")[0])
    ap.add_argument("--decoder-cases", type=int, default=1_000_000)
    ap.add_argument("--firmware-cases", type=int, default=100_000)
    ap.add_argument("--seed", type=int, default=20260118)
    a = ap.parse_args(argv)
    seeds = seed_frames()
    flat = [d for v in seeds.values() for d in v]
    t0 = time.time()
    dc, de = fuzz_decoders(a.decoder_cases, a.seed, flat)
    t1 = time.time()
    print(f"decoders: {dc} cases, {de} exceptions ({t1 - t0:.0f} s, seed {a.seed})", flush=True)
    fc, fe = fuzz_firmware(a.firmware_cases, a.seed + 1, seeds)
    t2 = time.time()
    print(f"firmware input path: {fc} cases over {len(FILTER_VARIANTS)} filter variants, {fe} exceptions or "
          f"non-finite states ({t2 - t1:.0f} s)")
    print(f"total: {dc + fc} cases, {de + fe} failures")
    return 1 if de + fe else 0


if __name__ == "__main__":
    sys.exit(main())
