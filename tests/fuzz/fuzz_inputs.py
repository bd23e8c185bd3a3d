"""Long seeded fuzz of every decoder and of the firmware's input path (``make fuzz``; not part of the test run).

``python -m tests.fuzz.fuzz_inputs [--decoder-cases N] [--field-cases F] [--firmware-cases M] [--seed S] [--seeds K]``
(``--seeds K`` runs the seeds S, S+1, ..., S+K-1 one after the other; ``make fuzz`` runs three).

* Decoders: every frame format the firmware and the monitor tool use, alone and all together, fed mutated valid
  frames (bit flips, hostile bytes, truncation, duplication, splices, random chunking). A decoder must never raise.
* Decoder fields: well-framed NMEA sentences of every type the parser knows (and proprietary ones) whose fields are
  replaced by, or extended with, hostile tokens (``inf``, ``nan``, ``-0``, ``1e300``, 40 nines, empty, huge integers,
  non-ASCII bytes, a time ``hhmm`` followed by any of them) with the checksum made valid, so that every case reaches
  the parser; each is followed by a good sentence. A decoder must never raise, must advance past the hostile
  sentence (the good one comes out) and must hold no bytes afterwards.
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
from protocols.host_text import HostTextFormat
from protocols.imu_frame import FpgaFrameFormat, ImuFrame, ImuFrameFormat
from protocols.monitor import MonitorFormat
from protocols.nmea import NMEA_RX_MAX_LEN, NmeaFormat
from protocols.psns import PsnsFormat
from protocols.stim import Stim210Format
from protocols.stream import StreamDecoder
from protocols.ubx import NavPvt, UbxFormat, encode_nav_pvt

from ..firmware_model.synth import SensorErrors, StaticTruth, StreamConfig, static_stream

UART_HOST, UART_IMU, UART_PSNS, UART_GNSS = 0, 1, 2, 3
HOSTILE_TOKENS = ["nan", "NaN", "inf", "-inf", "Infinity", "1e300", "-1e300", "1e-320", "", "-", ".", "9" * 40,
                  "-0", "0x1A", "1_000", "+5", " 5", "99999.99999", "-99999", "361", "-1", "9100.0", "18100.0",
                  "-0.0", "1e30", "9" * 400, "1" + "0" * 30, "-" + "9" * 40, "2147483648", "18446744073709551616",
                  "\u00e9", "\u00ff\u00fe", "\u00b5b", "0.", ".5", "1e", "e5", "--1", "0" * 40, "6o", "\u0661\u0662"]
#: How a hostile token replaces a field: whole, after a kept prefix of the field (``hhmm`` + ``inf``), or before it.
_TOKEN_PLACES = ("replace", "after_prefix", "before")

#: Bodies of valid sentences of every type the NMEA parser knows, the quoted receiver forms of issue 37 and
#: proprietary ones (checksums are computed when a case is built). Times, dates and positions are ordinary.
NMEA_TEMPLATES = [
    "GPGGA,123519.00,4807.038,N,01131.000,E,1,08,0.9,545.4,M,46.9,M,,",
    "GPGGA,130711,5012.790800,N,00806.879600,W,2,,,,,,,",
    "GNGNS,123519.00,4807.038,N,01131.000,E,AAN,08,0.9,545.4,46.9,,,V",
    "GPRMC,123519.00,A,4807.038,N,01131.000,E,022.4,084.4,230394,003.1,W,A",
    "GNRMC,123519.00,A,4807.038,N,01131.000,E,022.4,084.4,230394,,,A,V",
    "GPVTG,054.7,T,034.4,M,005.5,N,010.2,K,A",
    "GPGSA,A,3,04,05,,09,12,,,24,,,,,2.5,1.3,2.1",
    "GNGSA,A,3,04,05,,09,12,,,24,,,,,2.5,1.3,2.1,1",
    "GPGSV,3,1,11,03,03,111,00,04,15,270,00,06,01,010,00,13,06,292,00",
    "GPGSV,3,1,00,,,,,,,,,,,,,,,,",
    "GPZDA,201530.00,04,07,2002,00,00",
    "GPGLL,4807.038,N,01131.000,E,123519.00,A,A",
    "PSNSPOS,12.345,48.1173000,11.5166667,545.40,0002,1,0",
    "PUBX,00,081350.00,4717.113210,N,00833.915187,E,546.589,G3,2.1,2.0,0.007,77.52,0.007,,0.92,1.19,0.77,9,0,0",
]
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
    """A sentence whose fields are replaced by (or extended with) hostile tokens, re-checksummed so it reaches the
    parser: the hostile-field-token mutator. Non-ASCII tokens go on the wire as UTF-8 bytes."""
    try:
        body = sentence[1 : sentence.index(b"*")].decode("ascii")
    except (ValueError, UnicodeDecodeError):
        return sentence
    f = body.split(",")
    for _ in range(rng.randint(1, 3)):
        i = rng.randrange(1, len(f)) if len(f) > 1 else 0
        tok = rng.choice(HOSTILE_TOKENS) if rng.random() < 0.8 else repr(rng.uniform(-1e6, 1e6))
        place = rng.choice(_TOKEN_PLACES)
        if i == 0:  # the address field: a token after it (a six-letter or odd address)
            f[0] = f[0] + tok.replace(",", "")
        elif place == "replace":
            f[i] = tok
        elif place == "after_prefix":
            f[i] = f[i][: rng.randint(0, len(f[i]))] + tok
        else:
            f[i] = tok + f[i]
    if rng.random() < 0.1:  # fields cut short or added
        f = f[: rng.randint(1, len(f))] if rng.random() < 0.5 else f + [rng.choice(HOSTILE_TOKENS)] * rng.randint(1, 8)
    raw = ",".join(f).encode("utf-8")
    return b"$" + raw + f"*{nmea_checksum(raw):02X}\r\n".encode()


def nmea_field_seeds(seeds: list[bytes]) -> list[bytes]:
    """One sentence per line: the templates and every NMEA sentence of the synthetic stream."""
    out = [f"${b}*{nmea_checksum(b.encode()):02X}\r\n".encode() for b in NMEA_TEMPLATES]
    for d in seeds:
        if d.startswith(b"$"):
            out += [x + b"\r\n" for x in d.split(b"\r\n") if x]
    return out


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

#: The decoders that read NMEA sentences: the firmware's and the monitor's GNSS port (long lines), NMEA alone (the
#: single-format fast paths), the host port's text sentences, and every format together.
NMEA_DECODER_SETS: dict[str, Callable[[], list[object]]] = {
    "gnss_rx": lambda: [NmeaFormat(NMEA_RX_MAX_LEN), UbxFormat()], "nmea": lambda: [NmeaFormat(NMEA_RX_MAX_LEN)],
    "nmea_82": lambda: [NmeaFormat()], "host_text": lambda: [HostTextFormat()],
    "all": DECODER_SETS["all"],
}

#: The sets whose every format is NMEA-framed: after a hostile sentence and a good one nothing may stay buffered
#: and the good one must come out (in the others a hostile byte may open another format's candidate).
NMEA_ONLY = ("nmea", "nmea_82", "host_text")


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


def field_case(rng: random.Random, sentences: list[bytes]) -> tuple[bytes, bytes]:
    """One case of the field fuzz: (a hostile sentence, the good sentence that follows it)."""
    return hostile_nmea(rng, rng.choice(sentences)), rng.choice(sentences)


def feed_field_case(dec: StreamDecoder, hostile: bytes, good: bytes, rng: random.Random | None = None,
                    nmea_only: bool = False) -> None:
    """Feed ``hostile`` then ``good`` (in random chunks when ``rng`` is given); raise AssertionError when the decoder
    did not advance past the hostile sentence (``nmea_only``: the good sentence must come out last, nothing held)."""
    data = hostile + good
    out: list[object] = []
    if rng is None:
        out = dec.feed(data)
    else:
        p = 0
        while p < len(data):
            q = p + rng.randint(1, 64)
            out += dec.feed(data[p:q])
            p = q
    if dec.pending() > 1 << 16:
        raise AssertionError(f"buffer grew to {dec.pending()}")
    if nmea_only:
        if dec.pending():
            raise AssertionError(f"{dec.pending()} bytes held after {hostile!r} + {good!r}")
        want = StreamDecoder(dec.formats).feed(good)  # type: ignore[arg-type]
        if len(want) == 1 and (not out or out[-1] != want[0]):
            raise AssertionError(f"the good sentence after {hostile!r} did not come out: {out!r}")


def fuzz_fields(n: int, seed: int, seeds: list[bytes], failures: list[bytes] | None = None) -> tuple[int, int]:
    """``n`` cases of the hostile-field-token mutator over every NMEA-reading decoder set; the hostile sentences of
    failed cases are appended to ``failures`` (the regression corpus is built from them)."""
    rng = random.Random(seed)
    sentences = nmea_field_seeds(seeds)
    names = list(NMEA_DECODER_SETS)
    decs = {k: StreamDecoder(NMEA_DECODER_SETS[k]()) for k in names}  # type: ignore[arg-type]
    cases = errors = 0
    while cases < n:
        k = names[cases % len(names)]
        hostile, good = field_case(rng, sentences)
        try:
            feed_field_case(decs[k], hostile, good, rng if rng.random() < 0.5 else None, k in NMEA_ONLY)
        except Exception:
            errors += 1
            if failures is not None:
                failures.append(hostile)
            if errors <= 5:
                traceback.print_exc()
            decs[k] = StreamDecoder(NMEA_DECODER_SETS[k]())  # type: ignore[arg-type]
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
                            fr = dataclasses.replace(imu_seed, t_trigger_us=fw.clock._t_last_us or 0)
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
    ap.add_argument("--field-cases", type=int, default=100_000)
    ap.add_argument("--firmware-cases", type=int, default=100_000)
    ap.add_argument("--seed", type=int, default=20260118)
    ap.add_argument("--seeds", type=int, default=1, help="run K seeds: S, S+1, ..., S+K-1")
    a = ap.parse_args(argv)
    seeds = seed_frames()
    flat = [d for v in seeds.values() for d in v]
    total_cases = total_failures = 0
    for seed in range(a.seed, a.seed + a.seeds):
        t0 = time.time()
        dc, de = fuzz_decoders(a.decoder_cases, seed, flat)
        t1 = time.time()
        print(f"decoders: {dc} cases, {de} exceptions ({t1 - t0:.0f} s, seed {seed})", flush=True)
        nc, ne = fuzz_fields(a.field_cases, seed, flat)
        t2 = time.time()
        print(f"decoder fields (hostile tokens, valid checksums): {nc} cases, {ne} exceptions or stuck decoders "
              f"({t2 - t1:.0f} s, seed {seed})", flush=True)
        fc, fe = fuzz_firmware(a.firmware_cases, seed + 1, seeds)
        t3 = time.time()
        print(f"firmware input path: {fc} cases over {len(FILTER_VARIANTS)} filter variants, {fe} exceptions or "
              f"non-finite states ({t3 - t2:.0f} s, seed {seed + 1})", flush=True)
        total_cases += dc + nc + fc
        total_failures += de + ne + fe
    print(f"total: {total_cases} cases, {total_failures} failures")
    return 1 if total_failures else 0


if __name__ == "__main__":
    sys.exit(main())
