"""The host port's task: commands (RESET_FILTER, SELECT_VARIANT, SET_OUTPUT_RATE, REQUEST_STATUS), one ACK each,
and STATUS at 1 Hz (protocols/host.py, docs/decisions/protocols.md D-3.2)."""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from typing import Any

from protocols.host import (
    FILTER_VARIANT_NAMES,
    OUTPUT_RATE_MIN_HZ,
    Ack,
    AckResult,
    HostFrame,
    HostStatus,
    RequestStatus,
    ResetFilter,
    SelectVariant,
    SetOutputRate,
    encode_ack,
    encode_status,
)

from .. import c674x
from ..config import FILTER_VARIANTS, UART_HOST, FirmwareConfig
from .alignment import AlignmentTask
from .navigation import NavCore
from .output import OutputTask
from .state import CpuLoad, LoopStatus, TickResult

__all__ = ["FW_VERSION", "HostTask"]

#: Firmware version in STATUS (major << 8 | minor).
FW_VERSION = 0x0105


class HostTask:
    """Host commands and STATUS.

    A task object of the cyclic executive: its state (the queue of commands, the STATUS schedule and sequence) is
    its own; collaborators ``cfg`` (its ``filter`` is set by SELECT_VARIANT), ``meter``, ``counters`` (the loop's
    table, shared), ``core`` (the filter it resets or replaces), ``alignment`` (restarted by RESET_FILTER scope 0),
    ``output`` (its rate), ``status`` (mode, heading sigma), ``load`` (CPU load, deadline misses) and
    ``uart_counts`` (the executive's UART1-3 decoders' frames and errors, for STATUS)."""

    def __init__(self, cfg: FirmwareConfig, meter: c674x.CycleMeter, counters: dict[str, int], core: NavCore,
                 alignment: AlignmentTask, output: OutputTask, status: LoopStatus, load: CpuLoad,
                 uart_counts: Callable[[], tuple[int, int, int, int, int, int]]) -> None:
        self.cfg = cfg
        self.meter = meter
        self.counters = counters
        self.core = core
        self.alignment = alignment
        self.output = output
        self.status = status
        self.load = load
        self._uart_counts = uart_counts
        self._pending_cmd: deque[Any] = deque(maxlen=16)
        self._next_status_t = 1.0
        self._status_seq = 0

    def queue(self, c: Any) -> None:
        """A frame decoded on the host UART, for the next run (the oldest dropped, counted, when 16 wait)."""
        if len(self._pending_cmd) == self._pending_cmd.maxlen:
            self.counters["commands_dropped"] += 1
        self._pending_cmd.append(c)

    def due(self, t: float) -> bool:
        """Whether a command waits or STATUS is due at tick time ``t`` (s)."""
        return bool(self._pending_cmd) or t >= self._next_status_t

    def run(self, t: float, res: TickResult) -> None:
        """Execute pending host commands (one ACK each) and send STATUS at 1 Hz (protocols/host.py, D-3.2)."""
        m = self.meter
        while self._pending_cmd:
            c = self._pending_cmd.popleft()
            m.charge("host_command", 40 * 4 + c674x.CALL_OVERHEAD)  # CRC + dispatch [E]
            reply = self._command(c)
            if reply is None:
                continue
            cmd_id, token, result = reply
            if result == AckResult.ACCEPTED:
                self.counters["commands_accepted"] += 1
            else:
                self.counters["commands_rejected"] += 1
            res.outputs.append((UART_HOST, encode_ack(Ack(cmd_id, token, int(result))), m.elapsed))
            res.events.append({"event": "host_command", "t_fpga_s": t, "command": type(c).__name__,
                               "result": AckResult(result).name})
            if isinstance(c, RequestStatus) and result == AckResult.ACCEPTED:
                res.outputs.append((UART_HOST, self._status_frame(t), m.elapsed))
        if t >= self._next_status_t:
            self._next_status_t = math.floor(t) + 1.0
            res.outputs.append((UART_HOST, self._status_frame(t), m.elapsed))

    def _command(self, c: Any) -> tuple[int, int, int] | None:
        """Apply one command; ``(command_id, token, AckResult)``, or None for frames that are not commands."""
        from protocols.host import CMD_REQUEST_STATUS, CMD_RESET_FILTER, CMD_SELECT_VARIANT, CMD_SET_OUTPUT_RATE

        if isinstance(c, ResetFilter):
            if c.scope == 0:
                self.alignment.restart()
                return CMD_RESET_FILTER, c.token, AckResult.ACCEPTED
            if c.scope == 1:
                if self.core.nav is None:
                    return CMD_RESET_FILTER, c.token, AckResult.NOT_ALLOWED
                self.core.filter.initialise(self.core.nav, self.status.heading_sigma0)
                return CMD_RESET_FILTER, c.token, AckResult.ACCEPTED
            return CMD_RESET_FILTER, c.token, AckResult.BAD_ARGUMENT
        if isinstance(c, SelectVariant):
            names = {int(v): k for k, v in FILTER_VARIANT_NAMES.items()}
            name = names.get(c.variant)
            if name is None:
                return CMD_SELECT_VARIANT, c.token, AckResult.BAD_ARGUMENT
            if name not in FILTER_VARIANTS:
                return CMD_SELECT_VARIANT, c.token, AckResult.NOT_ALLOWED  # not in this firmware build
            self.core.filter = self.core.new_filter(name)
            self.cfg.filter = name
            if self.core.nav is not None:  # the new filter starts from the current navigation state
                self.core.filter.initialise(self.core.nav, self.status.heading_sigma0)
            return CMD_SELECT_VARIANT, c.token, AckResult.ACCEPTED
        if isinstance(c, SetOutputRate):
            r = float(c.rate_hz)
            if r == 0.0:
                self.output.set_every(0)
                return CMD_SET_OUTPUT_RATE, c.token, AckResult.ACCEPTED
            # the declared range (OUTPUT_RATE_MIN_HZ .. the IMU rate, D-3.11), then a divisor of the IMU rate:
            # 1e-30 Hz was a divisor of 2e32 ticks (an output that never comes) and was accepted before issue 41
            # (the rate arrives as a float32: 0.1 Hz is 0.10000000149, so both tests allow 1e-6 relative)
            ok = math.isfinite(r) and OUTPUT_RATE_MIN_HZ * (1.0 - 1e-6) <= r <= self.cfg.imu_rate_hz * (1.0 + 1e-6)
            k = self.cfg.imu_rate_hz / r if ok else 0.0
            if not ok or abs(k - round(k)) > 1e-6 * k:
                self.counters["commands_rejected_output_rate"] += 1
                return CMD_SET_OUTPUT_RATE, c.token, AckResult.BAD_ARGUMENT
            self.output.set_every(round(k))
            return CMD_SET_OUTPUT_RATE, c.token, AckResult.ACCEPTED
        if isinstance(c, RequestStatus):
            return CMD_REQUEST_STATUS, c.token, AckResult.ACCEPTED
        if isinstance(c, HostFrame) and c.msg_id >= 0x80:
            return c.msg_id, c.payload[0] if c.payload else 0, AckResult.UNKNOWN_COMMAND
        return None  # our own outputs echoed back, or host frames that need no answer

    def _status_frame(self, t: float) -> bytes:
        self.counters["status_frames"] += 1
        vs = self.core.filter.variant_status()
        if vs is not None:
            self.counters.update(self.core.filter.counters)
        self.meter.charge("status", 64 * 2 + 71 * 4 + c674x.CALL_OVERHEAD)  # pack + CRC-16 by table [E]

        u1_frames, u1_errors, u2_frames, u2_errors, u3_frames, u3_errors = self._uart_counts()
        st = HostStatus(
            seq=self._status_seq, time_s=t, filter_variant=self.core.filter.variant_id, mode=int(self.status.mode),
            output_rate_hz=self.output.rate_hz(), gnss_status=self.output.gnss_status_byte(),
            psns_status=self.status.psns_status(t), cpu_load_pct=self.load.load_pct(),
            cpu_load_max_pct=self.load.max_pct(), fw_version=FW_VERSION, deadline_misses=self.load.deadline_misses,
            uart1_frames=u1_frames, uart1_errors=u1_errors, uart2_frames=u2_frames, uart2_errors=u2_errors,
            uart3_frames=u3_frames, uart3_errors=u3_errors,
            commands_accepted=self.counters["commands_accepted"], commands_rejected=self.counters["commands_rejected"],
            variant_mode=vs[0] if vs is not None else 0,
        )
        self._status_seq += 1
        return encode_status(st)
