"""A foreign firmware in the virtual DSP's place, stepped in lockstep with the emulator's clock
(``dsp.external.lockstep``; the contract is docs/icd.md section 10, the C declaration ``firmware_abi/psns_fw.h``).

:class:`LockstepFirmware` implements the firmware interface the virtual DSP hosts
(:class:`firmware_model.registry.FirmwareProtocol`), so the DSP's UARTs, their FIFOs and rings, the cycles turned
into time, deadline misses, the watchdog and the cycle table apply to a foreign firmware exactly as to the built-in
one (:mod:`emulator.dsp.host`): ``receive`` passes each UART chunk on (``psns_fw_rx``), ``service`` runs one step
(``psns_fw_step``) and hands the DSP one tick of the reported cycles with the bytes written per UART, leaving at
the end of the step.

Two transports carry the calls:

* :class:`InProcessTransport`: the shared library loaded with :mod:`ctypes` (from a private copy in the run
  directory, so that two runs in one process never share the library's globals). Fast; a crash inside the
  library takes the emulator with it: **the in-process transport trades containment for speed**.
* :class:`ProcessTransport`: a child process in any language, the messages framed on its stdin/stdout
  (section 10.3); the clock waits for each reply, at most ``step_timeout_s`` of wall-clock time. A firmware that
  crashes, hangs, answers garbage or floods is stopped, the reason counted and reported (``summary.json``
  section ``lockstep``, event ``lockstep_failed``), and the run goes on with a silent DSP to its end.

Nothing here runs unless the run was given ``--allow-firmware`` (:data:`ALLOW_FIRMWARE_ENV`): opening or
validating a scenario never loads or starts code.
"""

from __future__ import annotations

import contextlib
import ctypes
import os
import select
import shutil
import signal
import struct
import subprocess
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Protocol

from firmware_model.c674x import CycleMeter
from firmware_model.registry import FirmwareSnapshot, TickResult
from protocols.host import HostFormat
from protocols.stream import StreamDecoder

from ..devices.base import EventSink, NullEvents
from ..errors import EmulatorError

__all__ = [
    "ABI_VERSION",
    "ALLOW_FIRMWARE_ENV",
    "CONFIG_STRUCT",
    "FirmwareNotAllowed",
    "InProcessTransport",
    "LockstepConfig",
    "LockstepError",
    "LockstepFirmware",
    "ProcessTransport",
    "firmware_allowed",
]

#: the interface version (docs/icd.md section 10; ``PSNS_FW_ABI_VERSION`` in psns_fw.h)
ABI_VERSION = 1
#: the four DSP UARTs
UARTS = 4
#: output bytes per UART per step the emulator accepts (``tx_cap``)
TX_CAP = 65536
#: largest reply payload of the out-of-process framing, bytes (section 10.3)
MAX_REPLY_BYTES = 1 << 20
#: cycles of one step above this many seconds at the DSP clock are a protocol violation, not a slow tick
MAX_STEP_S = 60.0
#: ``psns-hil run --allow-firmware`` sets this for the run: loading native code or starting a firmware process
ALLOW_FIRMWARE_ENV = "PSNS_HIL_ALLOW_FIRMWARE"
#: ``psns_fw_config`` (section 10.2): 4 x u32, 6 x f64, little-endian, 64 bytes
CONFIG_STRUCT = struct.Struct("<4I6d")
#: message header (section 10.3): type, version, reserved, payload length
HEADER = struct.Struct("<BBHI")
_RX = struct.Struct("<IIQ")
_STEP = struct.Struct("<QII")
_STEP_REPLY = struct.Struct("<iIQ4I")
_INIT_REPLY = struct.Struct("<Ii")
#: return codes (psns_fw.h)
FW_OK, FW_IDLE = 0, 1
#: config flag bit 0: the IMU frame's gyro words are incremental angles
FLAG_GYRO_INCREMENTAL = 0x1


class LockstepError(EmulatorError):
    """A lockstep firmware could not be loaded or started, or broke the contract (the message says which)."""


class FirmwareNotAllowed(LockstepError):
    """The scenario names a lockstep firmware and the run was not given ``--allow-firmware``."""


def firmware_allowed() -> bool:
    """True when a lockstep firmware may be loaded or started (``psns-hil run --allow-firmware``)."""
    return os.environ.get(ALLOW_FIRMWARE_ENV, "") not in ("", "0")


class LockstepConfig:
    """``psns_fw_config`` (docs/icd.md section 10.2; units in the names)."""

    __slots__ = ("clock_hz", "flags", "heading_deg", "height_m", "imu_rate_hz", "lat_deg", "lon_deg", "pitch_deg",
                 "roll_deg")

    def __init__(self, clock_hz: float, imu_rate_hz: float, lat_deg: float, lon_deg: float, height_m: float,
                 heading_deg: float, pitch_deg: float, roll_deg: float, flags: int = 0) -> None:
        self.clock_hz = round(clock_hz)
        self.imu_rate_hz = round(imu_rate_hz)
        self.flags = flags
        self.lat_deg, self.lon_deg, self.height_m = lat_deg, lon_deg, height_m
        self.heading_deg, self.pitch_deg, self.roll_deg = heading_deg, pitch_deg, roll_deg

    def pack(self) -> bytes:
        """The 64 bytes of ``psns_fw_config``."""
        return CONFIG_STRUCT.pack(ABI_VERSION, self.clock_hz, self.imu_rate_hz, self.flags, self.lat_deg,
                                  self.lon_deg, self.height_m, self.heading_deg, self.pitch_deg, self.roll_deg)

    @classmethod
    def unpack(cls, data: bytes) -> LockstepConfig:
        """The config from its 64 bytes (the out-of-process server's side); :class:`LockstepError` when short."""
        if len(data) < CONFIG_STRUCT.size:
            raise LockstepError(f"a config of {len(data)} bytes, {CONFIG_STRUCT.size} expected")
        _v, clk, rate, flags, lat, lon, h, hdg, pit, rol = CONFIG_STRUCT.unpack_from(data)
        return cls(clk, rate, lat, lon, h, hdg, pit, rol, flags)


class Transport(Protocol):
    """What :class:`LockstepFirmware` needs of a transport (the calls of docs/icd.md section 10.1)."""

    kind: str

    def init(self, config: bytes) -> tuple[int, int]:
        """(abi_version, status) of ``psns_fw_abi_version`` and ``psns_fw_init``."""

    def rx(self, uart: int, data: bytes, t_us: int) -> int:
        """``psns_fw_rx``'s status (0 when the transport defers the call)."""

    def step(self, t_us: int) -> tuple[int, int, list[bytes]]:
        """(status, cycles, bytes written per UART) of ``psns_fw_step``."""

    def close(self) -> dict[str, Any]:
        """Ends the firmware; what there is to say about its end (exit status)."""


class InProcessTransport:
    """The shared library (see module docstring), from a private copy in ``work_dir``."""

    kind = "in-process"

    def __init__(self, library: Path, work_dir: Path) -> None:
        work_dir.mkdir(parents=True, exist_ok=True)
        copy = work_dir / f"fw-{os.getpid()}-{time.monotonic_ns()}{library.suffix or '.so'}"
        try:
            shutil.copyfile(library, copy)
            self.lib = ctypes.CDLL(str(copy))
        except OSError as exc:
            raise LockstepError(f"cannot load the lockstep library {library}: {exc}") from exc
        finally:
            with contextlib.suppress(OSError):
                copy.unlink()  # the mapping stays; nothing left behind in the run directory
        lib = self.lib
        u8p = ctypes.POINTER(ctypes.c_uint8)
        sigs: dict[str, tuple[Any, list[Any]]] = {
            "psns_fw_abi_version": (ctypes.c_uint32, []),
            "psns_fw_init": (ctypes.c_int32, [ctypes.c_char_p]),
            "psns_fw_rx": (ctypes.c_int32, [ctypes.c_uint32, ctypes.c_char_p, ctypes.c_uint32, ctypes.c_uint64]),
            "psns_fw_step": (ctypes.c_int32, [ctypes.c_uint64, u8p, ctypes.c_uint32,
                                              ctypes.POINTER(ctypes.c_uint32), ctypes.POINTER(ctypes.c_uint64)]),
            "psns_fw_close": (None, []),
        }
        for name, (res, args) in sigs.items():
            try:
                fn = getattr(lib, name)
            except AttributeError as exc:
                raise LockstepError(f"the lockstep library {library} does not export {name} (firmware_abi/psns_fw.h)"
                                    ) from exc
            fn.restype = res
            fn.argtypes = args
        self._rx = lib.psns_fw_rx
        self._step = lib.psns_fw_step
        self._tx = (ctypes.c_uint8 * (UARTS * TX_CAP))()
        self._tx_ptr = ctypes.cast(self._tx, u8p)
        self._tx_addr = ctypes.addressof(self._tx)
        self._tx_len = (ctypes.c_uint32 * UARTS)()
        self._cycles = ctypes.c_uint64()
        self._closed = False

    def init(self, config: bytes) -> tuple[int, int]:
        abi = int(self.lib.psns_fw_abi_version())
        if abi != ABI_VERSION:
            return abi, -1
        return abi, int(self.lib.psns_fw_init(config))

    def rx(self, uart: int, data: bytes, t_us: int) -> int:
        return int(self._rx(uart, data, len(data), t_us))

    def step(self, t_us: int) -> tuple[int, int, list[bytes]]:
        lens = self._tx_len
        for k in range(UARTS):
            lens[k] = 0
        self._cycles.value = 0
        st = int(self._step(t_us, self._tx_ptr, TX_CAP, lens, ctypes.byref(self._cycles)))
        out: list[bytes] = []
        for k in range(UARTS):
            n = lens[k]
            if n > TX_CAP:
                raise LockstepError(f"psns_fw_step wrote {n} bytes to UART{k}, more than tx_cap {TX_CAP}")
            out.append(ctypes.string_at(self._tx_addr + k * TX_CAP, n) if n else b"")
        return st, int(self._cycles.value), out

    def close(self) -> dict[str, Any]:
        if not self._closed:
            self._closed = True
            self.lib.psns_fw_close()
        return {}


class ProcessTransport:
    """A lockstep firmware process (see module docstring); its stderr goes to ``stderr_path``."""

    kind = "out-of-process"

    def __init__(self, argv: Sequence[str], stderr_path: Path, step_timeout_s: float,
                 cwd: Path | None = None) -> None:
        self.argv = list(argv)
        self.timeout = step_timeout_s
        stderr_path.parent.mkdir(parents=True, exist_ok=True)
        self._err = stderr_path.open("wb")
        try:
            self.proc = subprocess.Popen(self.argv, stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self._err,
                                         cwd=cwd, close_fds=True, start_new_session=True)
        except OSError as exc:
            self._err.close()
            raise LockstepError(f"cannot start the lockstep firmware {self.argv[0]}: {exc}") from exc
        assert self.proc.stdin is not None and self.proc.stdout is not None
        self._w = self.proc.stdin.fileno()
        self._r = self.proc.stdout.fileno()
        os.set_blocking(self._w, False)
        os.set_blocking(self._r, False)
        self._pending = bytearray()  # rx messages not written yet (they go with the next step)
        self._buf = bytearray()
        self._closed = False

    # -- raw I/O with a wall-clock deadline ------------------------------------------------------------------
    def _write(self, data: bytes | bytearray) -> None:
        view = memoryview(data)
        deadline = time.monotonic() + self.timeout
        while view:
            left = deadline - time.monotonic()
            if left <= 0:
                raise LockstepError(f"hung: did not read its requests within {self.timeout:g} s (wall clock)")
            _r, w, _x = select.select([], [self._w], [], left)
            if not w:
                continue
            try:
                n = os.write(self._w, view)
            except BlockingIOError:
                continue
            except (BrokenPipeError, ConnectionResetError) as exc:
                raise LockstepError(self._ended("closed its stdin")) from exc
            view = view[n:]

    def _read(self, n: int) -> bytes:
        deadline = time.monotonic() + self.timeout
        buf = self._buf
        while len(buf) < n:
            left = deadline - time.monotonic()
            if left <= 0:
                raise LockstepError(f"hung: no reply within {self.timeout:g} s (wall clock)")
            r, _w, _x = select.select([self._r], [], [], left)
            if not r:
                continue
            try:
                chunk = os.read(self._r, max(65536, n - len(buf)))
            except BlockingIOError:
                continue
            if not chunk:
                raise LockstepError(self._ended("ended its stdout"))
            buf.extend(chunk)
        out = bytes(buf[:n])
        del buf[:n]
        return out

    def _ended(self, what: str) -> str:
        """Why the process stopped answering: its exit status or signal, waited for briefly."""
        try:
            rc = self.proc.wait(timeout=min(2.0, self.timeout))
        except subprocess.TimeoutExpired:
            return f"{what} but is still running"
        if rc < 0:
            try:
                name = signal.Signals(-rc).name
            except ValueError:
                name = f"signal {-rc}"
            return f"crashed: killed by {name}"
        return f"exited with status {rc}"

    def _reply(self, want: int, min_len: int) -> bytes:
        head = self._read(HEADER.size)
        typ, ver, _res, n = HEADER.unpack(head)
        if typ != want or ver != ABI_VERSION:
            raise LockstepError(f"protocol violation: a reply of type 0x{typ:02x} version {ver}, expected "
                                f"{chr(want)!r} version {ABI_VERSION} (garbage on its stdout?)")
        if n > MAX_REPLY_BYTES or n < min_len:
            raise LockstepError(f"protocol violation: a {chr(want)!r} reply of {n} bytes (allowed "
                                f"{min_len}..{MAX_REPLY_BYTES})")
        return self._read(n)

    # -- the calls ---------------------------------------------------------------------------------------------
    def init(self, config: bytes) -> tuple[int, int]:
        self._write(HEADER.pack(ord("I"), ABI_VERSION, 0, len(config)) + config)
        abi, st = _INIT_REPLY.unpack_from(self._reply(ord("i"), _INIT_REPLY.size))
        return abi, st

    def rx(self, uart: int, data: bytes, t_us: int) -> int:
        p = self._pending
        p += HEADER.pack(ord("R"), ABI_VERSION, 0, _RX.size + len(data))
        p += _RX.pack(uart, 0, t_us)
        p += data
        if len(p) >= 1 << 16:  # a long stretch without a step: pass it on now
            self._write(p)
            p.clear()
        return 0

    def step(self, t_us: int) -> tuple[int, int, list[bytes]]:
        p = self._pending
        p += HEADER.pack(ord("S"), ABI_VERSION, 0, _STEP.size)
        p += _STEP.pack(t_us, TX_CAP, 0)
        self._write(p)
        p.clear()
        body = self._reply(ord("s"), _STEP_REPLY.size)
        st, _res, cycles, *lens = _STEP_REPLY.unpack_from(body)
        if any(n > TX_CAP for n in lens) or _STEP_REPLY.size + sum(lens) != len(body):
            raise LockstepError(f"protocol violation: tx_len {lens} (tx_cap {TX_CAP}) in a reply of {len(body)} "
                                "bytes")
        out: list[bytes] = []
        off = _STEP_REPLY.size
        for n in lens:
            out.append(body[off:off + n])
            off += n
        return st, cycles, out

    def close(self) -> dict[str, Any]:
        """Quit (section 10.3), then wait for the exit; kill a process that does not go."""
        if self._closed:
            return {"exit": self.proc.returncode}
        self._closed = True
        proc = self.proc
        if proc.poll() is None:
            with contextlib.suppress(LockstepError, OSError):
                self._write(HEADER.pack(ord("Q"), ABI_VERSION, 0, 0))
            try:
                proc.wait(timeout=min(self.timeout, 5.0))
            except subprocess.TimeoutExpired:
                self.kill()
        for f in (proc.stdin, proc.stdout):
            if f is not None:
                with contextlib.suppress(OSError):
                    f.close()
        self._err.close()
        return {"exit": proc.returncode}

    def kill(self) -> None:
        """Stop the process at once (it hung or broke the contract)."""
        if self.proc.poll() is None:
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.killpg(self.proc.pid, signal.SIGKILL)
            with contextlib.suppress(subprocess.TimeoutExpired):
                self.proc.wait(timeout=5.0)


class LockstepFirmware:
    """A foreign firmware behind the virtual DSP (see module docstring).

    Parameters
    ----------
    transport : an open :class:`InProcessTransport` or :class:`ProcessTransport`.
    config : what ``psns_fw_init`` is given.
    events : where ``lockstep_failed`` goes (the recorder).
    name : what the summary calls the firmware (its library or program).
    """

    def __init__(self, transport: Transport, config: LockstepConfig, events: EventSink | None = None,
                 name: str = "") -> None:
        self.transport = transport
        self.config = config
        self.events = events or NullEvents()
        self.name = name
        self.clock_hz = float(config.clock_hz)
        self.meter = CycleMeter(self.clock_hz, float(config.imu_rate_hz))
        self.period_s = 1.0 / config.imu_rate_hz
        #: the DSP hosting it (set by the builder): a step starts when the DSP is free
        self.dsp: Any = None
        self.failed: str | None = None
        self.failed_t_s: float | None = None
        self.exit: dict[str, Any] = {}
        self.steps = 0
        self.idle_steps = 0
        self.deadline_misses = 0
        self.rx_bytes = [0] * UARTS
        self.tx_bytes = [0] * UARTS
        self.host_decoder = StreamDecoder([HostFormat()])
        self.frames_by_kind: dict[str, int] = {}
        self.calls_after_failure = 0
        self._t_last = 0.0
        try:
            abi, st = transport.init(config.pack())
        except LockstepError as exc:
            self._fail(0.0, f"init: {exc}")
            return
        if abi != ABI_VERSION:
            self._fail(0.0, f"built against interface version {abi}, the emulator speaks {ABI_VERSION}")
        elif st != FW_OK:
            self._fail(0.0, f"psns_fw_init returned {st}")

    # -- FirmwareProtocol ---------------------------------------------------------------------------------------
    def receive(self, uart: int, data: bytes, t_rx_s: float | None = None) -> None:
        t = self._t_last if t_rx_s is None else t_rx_s
        self._t_last = t
        if self.failed is not None:
            self.calls_after_failure += 1
            return
        if not 0 <= uart < UARTS:
            return
        self.rx_bytes[uart] += len(data)
        try:
            st = self.transport.rx(uart, data, round(t * 1e6))
        except LockstepError as exc:
            self._fail(t, f"rx: {exc}")
            return
        if st < 0:
            self._fail(t, f"psns_fw_rx returned {st}")

    def service(self) -> list[TickResult]:
        dsp = self.dsp
        now = dsp.loop.time() if dsp is not None else self._t_last
        start = max(now, dsp.busy_until) if dsp is not None else now
        if self.failed is not None:
            self.calls_after_failure += 1
            return []
        t_us = round(start * 1e6)
        try:
            st, cycles, out = self.transport.step(t_us)
        except LockstepError as exc:
            self._fail(start, f"step: {exc}")
            return []
        if st < 0:
            self._fail(start, f"psns_fw_step returned {st}")
            return []
        if st not in (FW_OK, FW_IDLE):
            self._fail(start, f"protocol violation: psns_fw_step returned {st} (0, 1 or negative)")
            return []
        if cycles > MAX_STEP_S * self.clock_hz:
            self._fail(start, f"protocol violation: a step of {cycles} cycles (more than {MAX_STEP_S:g} s)")
            return []
        if st == FW_IDLE:
            if cycles or any(out):
                self._fail(start, "protocol violation: an idle step (1) with cycles or output")
                return []
            self.idle_steps += 1
            return []
        self.steps += 1
        m = self.meter
        m.begin("lockstep_step", self.period_s)
        m.charge("reported_by_firmware", cycles)
        m.end()
        outputs: list[tuple[int, bytes, int]] = []
        for k, data in enumerate(out):
            if data:
                self.tx_bytes[k] += len(data)
                outputs.append((k, data, cycles))
                if k == 0:
                    for fr in self.host_decoder.feed(data):
                        kind = type(fr).__name__
                        self.frames_by_kind[kind] = self.frames_by_kind.get(kind, 0) + 1
        return [TickResult(t_fpga_s=start, cycles=cycles, outputs=outputs)]

    def note_deadline_miss(self) -> None:
        self.deadline_misses += 1

    def snapshot(self) -> FirmwareSnapshot:
        return FirmwareSnapshot(state="failed" if self.failed else "foreign", mode=0, filter="lockstep",
                                precision="foreign", counters=self.counters(),
                                decoders={"host_out": self.host_decoder.stats.as_dict()},
                                cycles=self.meter.table(), tick_budget_cycles=self.meter.tick_budget)

    # -- the rest --------------------------------------------------------------------------------------------
    def counters(self) -> dict[str, int]:
        return {"steps": self.steps, "idle_steps": self.idle_steps, "deadline_misses": self.deadline_misses,
                "rx_bytes": sum(self.rx_bytes), "tx_bytes": sum(self.tx_bytes),
                "failed": int(self.failed is not None), "calls_after_failure": self.calls_after_failure}

    def _fail(self, t: float, reason: str) -> None:
        """Stop the firmware (see module docstring): counted, reported, the DSP silent from now on."""
        if self.failed is not None:
            return
        self.failed = reason
        self.failed_t_s = t
        kill = getattr(self.transport, "kill", None)
        if kill is not None:
            kill()
        self.events.emit(t, "lockstep", "lockstep_failed", reason=reason, transport=self.transport.kind)

    def close(self) -> None:
        """End the firmware (``psns_fw_close`` / quit); idempotent."""
        with contextlib.suppress(LockstepError, OSError):
            self.exit = self.transport.close()

    def section(self) -> dict[str, Any]:
        """The ``lockstep`` section of ``summary.json``."""
        st = self.host_decoder.stats.as_dict()
        return {
            "interface_version": ABI_VERSION,
            "transport": self.transport.kind,
            "firmware": self.name,
            "failed": self.failed is not None,
            "failure": self.failed,
            "failed_at_s": self.failed_t_s,
            "exit": self.exit.get("exit"),
            "steps": self.steps,
            "idle_steps": self.idle_steps,
            "deadline_misses": self.deadline_misses,
            "calls_after_failure": self.calls_after_failure,
            "rx_bytes": {f"uart{k}": n for k, n in enumerate(self.rx_bytes)},
            "tx_bytes": {f"uart{k}": n for k, n in enumerate(self.tx_bytes)},
            "host_frames": dict(self.frames_by_kind),
            "garbage_bytes": st["garbage_bytes"],
            "crc_errors": st["crc_errors"],
            "length_errors": st["length_errors"],
        }


def open_lockstep(scn: Any, run_dir: Path, events: EventSink | None = None) -> LockstepFirmware:
    """The scenario's lockstep firmware (``dsp.external.lockstep``), loaded or started: only with
    ``--allow-firmware`` (:class:`FirmwareNotAllowed` otherwise); its paths confined to the scenario's directory
    (:mod:`emulator.scenario.paths`)."""
    from ..scenario.paths import PathNotAllowed, confine

    spec = scn.dsp.external.lockstep
    if not firmware_allowed():
        what = f"library {spec.library}" if spec.library is not None else f"program {spec.command[0]}"
        raise FirmwareNotAllowed(f"{scn.source_file or scn.name}: dsp.external.lockstep names a foreign firmware "
                                 f"({what}): it runs native code; pass --allow-firmware to load it (only for a "
                                 "firmware you trust)")
    imu = scn.sensors.imu
    cfg = LockstepConfig(scn.dsp.clock_hz, imu.rate_hz, scn.origin.lat_deg, scn.origin.lon_deg, scn.origin.height_m,
                         scn.attitude.heading_deg, scn.attitude.pitch_deg, scn.attitude.roll_deg,
                         FLAG_GYRO_INCREMENTAL if getattr(imu, "output", "rate") == "angle" else 0)
    transport: Transport
    try:
        if spec.library is not None:
            lib = confine(scn.base_dir, spec.library, "lockstep firmware")
            if not lib.is_file():
                raise LockstepError(f"dsp.external.lockstep.library: no such file: {lib}")
            transport = InProcessTransport(lib, run_dir / "lockstep")
            name = str(lib)
        else:
            prog = confine(scn.base_dir, spec.command[0], "lockstep firmware")
            if not prog.is_file():
                raise LockstepError(f"dsp.external.lockstep.command[0]: no such file: {prog}")
            # started by the name given (a virtual environment's python is a symbolic link that must stay one)
            given = Path(spec.command[0]).expanduser()
            exe = given if given.is_absolute() else Path(scn.base_dir or ".") / given
            transport = ProcessTransport([str(exe), *spec.command[1:]], run_dir / "lockstep_stderr.log",
                                         spec.step_timeout_s)
            name = " ".join([str(exe), *spec.command[1:]])
    except PathNotAllowed as exc:
        raise LockstepError(str(exc)) from exc
    return LockstepFirmware(transport, cfg, events, name)
