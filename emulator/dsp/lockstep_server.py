"""The built-in firmware (:class:`firmware_model.Firmware`) as an out-of-process lockstep firmware: a server of
docs/icd.md section 10.3 on stdin/stdout.

    python -m emulator.dsp.lockstep_server SCENARIO [--seed N] [--set KEY=VALUE] [--perturb FIELD:AFTER:DELTA]

It builds the firmware exactly as the virtual DSP does for ``SCENARIO`` (the calibration made from the same seeded
world, written and read back through a file), then answers ``R`` with ``Firmware.receive`` and ``S`` with
``Firmware.service``: the ticks of one step are summed (cycles) and their outputs concatenated per UART. Run behind
the out-of-process transport, its navigation output equals the built-in firmware's frame for frame: the reference
of the differential check (``psns-hil diff-firmware``). ``--perturb heading_deg:100:0.01`` adds 0.01 to one
NAV_SOLUTION field (docs/icd.md section 7) of every frame after the 100th: a known change the check must find at
its first frame.

The server trusts the scenario it is given (the emulator that starts it validated the same file).
"""

from __future__ import annotations

import argparse
import struct
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import BinaryIO

from protocols.host import MSG_NAV_SOLUTION, NAV_SOLUTION_LEN, build_host_frame

from .lockstep import _INIT_REPLY, _RX, _STEP, _STEP_REPLY, ABI_VERSION, FW_IDLE, FW_OK, HEADER, UARTS

__all__ = ["NAV_FIELDS", "main", "perturber", "serve"]

#: NAV_SOLUTION payload fields that ``--perturb`` may change: offset and struct format (docs/icd.md section 7)
NAV_FIELDS: dict[str, tuple[int, str]] = {
    "lat_deg": (12, "<d"), "lon_deg": (20, "<d"), "height_m": (28, "<f"), "vel_e_mps": (32, "<f"),
    "vel_n_mps": (36, "<f"), "vel_u_mps": (40, "<f"), "roll_deg": (44, "<f"), "pitch_deg": (48, "<f"),
    "heading_deg": (52, "<f"),
}


def perturber(spec: str) -> Callable[[bytes], bytes]:
    """A filter over UART0 output chunks that adds DELTA to FIELD of each NAV_SOLUTION after the AFTER-th one
    (``spec`` = ``FIELD:AFTER:DELTA``); other bytes pass unchanged."""
    field, after_s, delta_s = spec.split(":")
    off, fmt = NAV_FIELDS[field]
    after, delta = int(after_s), float(delta_s)
    count = [0]

    def apply(chunk: bytes) -> bytes:
        out = bytearray()
        i = 0
        while i < len(chunk):
            if chunk[i:i + 3] == bytes((0xA5, 0x5A, MSG_NAV_SOLUTION)) and i + 5 <= len(chunk):
                n = int.from_bytes(chunk[i + 3:i + 5], "little")
                if n >= NAV_SOLUTION_LEN and i + 7 + n <= len(chunk):
                    payload = bytearray(chunk[i + 5:i + 5 + n])
                    count[0] += 1
                    if count[0] > after:
                        (v,) = struct.unpack_from(fmt, payload, off)
                        struct.pack_into(fmt, payload, off, v + delta)
                    out += build_host_frame(MSG_NAV_SOLUTION, bytes(payload))
                    i += 7 + n
                    continue
            out.append(chunk[i])
            i += 1
        return bytes(out)

    return apply


def _read_exact(f: BinaryIO, n: int) -> bytes | None:
    buf = bytearray()
    while len(buf) < n:
        chunk = f.read(n - len(buf))
        if not chunk:
            return None
        buf += chunk
    return bytes(buf)


def serve(scenario: str, seed: int | None, stdin: BinaryIO, stdout: BinaryIO, perturb: str | None = None,
          overrides: list[str] | None = None) -> int:
    """Answer lockstep requests until ``Q`` or the end of ``stdin``; the exit status."""
    from firmware_model.calibration import load_calibration, save_calibration

    from ..scenario import load_scenario
    from .firmware_setup import build_firmware, calibration_for

    scn = load_scenario(scenario, overrides or ())
    seed = scn.seed if seed is None else seed
    with tempfile.TemporaryDirectory(prefix="psns-lockstep-") as tmp:
        path = Path(tmp) / "calibration.json"
        save_calibration(calibration_for(scn, seed), path)  # as the virtual DSP does: the firmware reads the file
        cal = load_calibration(path)
    fw = build_firmware(scn, cal)
    shift = perturber(perturb) if perturb else None
    while True:
        head = _read_exact(stdin, HEADER.size)
        if head is None:
            return 0
        typ, _ver, _res, n = HEADER.unpack(head)
        body = _read_exact(stdin, n) if n else b""
        if body is None:
            return 0
        if typ == ord("I"):
            stdout.write(HEADER.pack(ord("i"), ABI_VERSION, 0, _INIT_REPLY.size) + _INIT_REPLY.pack(ABI_VERSION, 0))
            stdout.flush()
        elif typ == ord("R"):
            uart, _r, t_us = _RX.unpack_from(body)
            fw.receive(uart, body[_RX.size:], t_us * 1e-6)
        elif typ == ord("S"):
            _t_us, cap, _r = _STEP.unpack_from(body)
            ticks = fw.service()
            per: list[bytearray] = [bytearray() for _ in range(UARTS)]
            cycles = 0
            for r in ticks:
                cycles += r.cycles
                for uart, data, _cyc in r.outputs:
                    if 0 <= uart < UARTS:
                        per[uart] += shift(data) if shift is not None and uart == 0 else data
            lens = [min(len(b), cap) for b in per]
            st = FW_OK if ticks else FW_IDLE
            payload = _STEP_REPLY.pack(st, 0, cycles, *lens) + b"".join(bytes(b[:k]) for b, k in zip(per, lens))
            stdout.write(HEADER.pack(ord("s"), ABI_VERSION, 0, len(payload)) + payload)
            stdout.flush()
        elif typ == ord("Q"):
            return 0


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m emulator.dsp.lockstep_server", description=__doc__.split("\n\n")[0])
    p.add_argument("scenario")
    p.add_argument("--seed", type=int, default=None)
    p.add_argument("--perturb", metavar="FIELD:AFTER:DELTA", default=None,
                   help=f"add DELTA to FIELD of each NAV_SOLUTION after the AFTER-th ({', '.join(NAV_FIELDS)})")
    p.add_argument("--set", action="append", metavar="KEY=VALUE", help="override one scenario value, as for run")
    args = p.parse_args(argv)
    return serve(args.scenario, args.seed, sys.stdin.buffer, sys.stdout.buffer, args.perturb, args.set)


if __name__ == "__main__":
    sys.exit(main())
