"""The virtual Spartan-3E FPGA: acquisition, time stamps, IMU-frame assembly and UART routing.

* A free-running 1 MHz time-stamp counter (``t_us = floor(t * 1e6)`` mod 2^32).
* The IMU trigger: every ``1/imu_rate_hz`` s the FPGA strobes the STIM ExtTrig line and latches
  the accelerometer ADC (boxcar average of its oversampled conversions since the previous
  trigger). When the gyro datagram for that trigger arrives on the GYRO port it packs one
  :mod:`protocols.imu_frame` frame and sends it to DSP UART1. No datagram within
  ``gyro_timeout_s`` gives a frame flagged ``GYRO_MISSING`` that repeats the last gyro words.
* PPS rising edges latch the counter (``t_pps_us``, ``pps_count``), carried in every IMU frame.
* A magnetometer (when the scenario has one) is sampled on every ``imu_rate / mag_rate_hz``-th
  trigger (100 Hz by default, the ICD's budget); its MAG frame
  (:class:`protocols.imu_frame.MagFrame`, docs/icd.md: sequence, trigger time stamp, field in
  0.1 nT, status) follows that trigger's IMU frame on UART1 and is mirrored on the MONITOR
  port's ``mag`` channel.
* Byte routing (the crossbar, scenario ``fpga.routing``): each external serial port is
  forwarded to its DSP UART and back, cut-through (a byte leaves as soon as it has arrived and
  the output line is free). Baud conversion happens because the two sides are separate links
  with their own line models; each output has its own FIFO (the TX queue of that side), which
  overflows, counted, when the output is slower than the input for long enough.
* The MONITOR port (``links.monitor``): every chunk on every channel (external ports and DSP
  UARTs, both directions) is mirrored as a :class:`protocols.monitor.MonitorRecord` (channel id,
  direction 0 = towards the DSP / 1 = away from it, FPGA time stamp in us, the bytes),
  COBS-framed by :func:`protocols.monitor.encode_monitor` (docs/icd.md). A monitor line slower
  than the traffic overflows and counts, like any other.
* Two host ports on one UART (``fpga.routing`` ``host: uart0`` and ``host_nmea: uart0``, the default when
  ``links.host_nmea`` is given without a route): the firmware writes its binary frames and its NMEA sentences on
  UART0, and the FPGA demultiplexes them, frame by frame, store and forward (:class:`HostDemux`): binary host
  frames (NAV_SOLUTION, STATUS, ACK) to ``host``, NMEA sentences to ``host_nmea``. The full box (camera on UART2,
  GNSS on UART3) has no free UART for a second one, and gpsd reads only NMEA. Bytes that are neither (a corrupted
  frame) are dropped and counted (``host_demux_garbage``). ``host_nmea`` is output only; the host's commands go
  to UART0 as before.
"""

from __future__ import annotations

import asyncio
import math
from dataclasses import dataclass, field
from typing import Any

from protocols.host import HostFormat
from protocols.imu_frame import ADC_CODE_MAX, FpgaStatus, MagFrame, build_imu_frame, encode_mag_frame
from protocols.monitor import MONITOR_CHANNELS, MONITOR_MAX_DATA, MonitorRecord, encode_monitor
from protocols.nmea import NmeaFormat
from protocols.stim import gyro_port_format
from protocols.stream import StreamDecoder

from ..links.base import Link
from .base import EventSink, NullEvents
from .imu import AnalogAccelerometers, Stim210Gyro

__all__ = ["DEFAULT_ROUTING", "MONITOR_DIRECTIONS", "FpgaConfig", "HostDemux", "VirtualFpga"]

# the IMU frame's status bits as plain ints: the per-frame flag arithmetic stays in int (an ``int | IntFlag`` builds
# an enum member through the enum machinery, ~1 us per frame); the frame carries ``int(flags)`` either way
_GYRO_MISSING = int(FpgaStatus.GYRO_MISSING)
_GYRO_CRC_ERROR = int(FpgaStatus.GYRO_CRC_ERROR)
_GYRO_COUNTER_JUMP = int(FpgaStatus.GYRO_COUNTER_JUMP)
_ADC_OVERRANGE = int(FpgaStatus.ADC_OVERRANGE)
_PPS_VALID = int(FpgaStatus.PPS_VALID)

#: external port -> DSP UART (docs/architecture.md: PSNS = RS232 -> UART2, GNSS = RS422 -> UART3)
DEFAULT_ROUTING = {"host": "uart0", "psns": "uart2", "gnss": "uart3"}


@dataclass
class FpgaConfig:
    imu_rate_hz: float = 200.0
    gyro_timeout_s: float = 0.004
    gyro_format: str = "m"
    #: the IMU on the gyro port (``stim210`` / ``stim300``) and the STIM300's datagram ID
    gyro_device: str = "stim210"
    stim300_ident: int = 0x93
    gyro_counter_step: int = 10
    routing: dict[str, str] = field(default_factory=lambda: dict(DEFAULT_ROUTING))
    #: channels mirrored on the MONITOR port (None = every channel)
    monitor_channels: tuple[str, ...] | None = None
    #: magnetometer sample / MAG frame rate (a divider of the trigger rate)
    mag_rate_hz: float = 100.0


#: (link end held by the FPGA, link direction) -> monitor direction (docs/icd.md: 0 towards the DSP, 1 away)
MONITOR_DIRECTIONS = {("port", "in"): 0, ("port", "out"): 1, ("uart", "out"): 0, ("uart", "in"): 1}


class _MonitorTap:
    """Listener on one FPGA-held link end that mirrors its chunks to the MONITOR port."""

    __slots__ = ("channel", "dirs", "fpga")

    def __init__(self, fpga: VirtualFpga, channel: int, side: str) -> None:
        self.fpga = fpga
        self.channel = channel
        self.dirs = {"in": MONITOR_DIRECTIONS[(side, "in")], "out": MONITOR_DIRECTIONS[(side, "out")]}

    def on_link_bytes(self, link: Link, direction: str, t: float, data: bytes) -> None:
        self.fpga._mirror(self.channel, self.dirs[direction], t, data)

class _Tagged:
    """A frame format whose parse gives ``(port, raw frame bytes)``: the demultiplexer forwards the bytes as they
    came, checked by the format's own CRC / checksum."""

    def __init__(self, fmt: Any, port: str) -> None:
        self.fmt, self.port = fmt, port
        self.name, self.sync = f"{port}:{fmt.name}", fmt.sync

    def frame_length(self, buf: bytes | bytearray, start: int) -> int:
        return int(self.fmt.frame_length(buf, start))

    def check(self, frame: bytes) -> bool:
        return bool(self.fmt.check(frame))

    def parse(self, frame: bytes) -> tuple[str, bytes]:
        return self.port, frame


class HostDemux:
    """UART0's TX stream split into the two host ports (module docstring): ``feed(bytes)`` -> ``[(port, frame)]``
    with ``port`` ``"host"`` (binary host frames, protocols/host.py) or ``"host_nmea"`` (NMEA 0183 sentences)."""

    def __init__(self) -> None:
        self.decoder = StreamDecoder([_Tagged(HostFormat(), "host"), _Tagged(NmeaFormat(), "host_nmea")],
                                     fast_paths=False)

    def feed(self, data: bytes) -> list[tuple[str, bytes]]:
        return list(self.decoder.feed(data))

    @property
    def garbage_bytes(self) -> int:
        return int(self.decoder.stats.garbage_bytes)


class VirtualFpga:
    """See module docstring.

    Parameters
    ----------
    ports : external-side links by port name (``gyro``, ``gnss``, ``psns``, ``host``).
    uarts : FPGA-side ends of the DSP links by name (``uart0`` .. ``uart3``).
    gyro : the internal STIM model to trigger (None when the gyro port is external).
    accel : the accelerometers behind the ADC.
    """

    def __init__(self, loop: asyncio.AbstractEventLoop, cfg: FpgaConfig, ports: dict[str, Link],
                 uarts: dict[str, Link], gyro: Stim210Gyro | None, accel: AnalogAccelerometers | None,
                 events: EventSink | None = None, monitor: Link | None = None, mag: Any = None) -> None:
        self.loop = loop
        self.cfg = cfg
        self.ports = ports
        self.uarts = uarts
        self.gyro = gyro
        self.accel = accel
        self.events = events or NullEvents()
        self.period = 1.0 / cfg.imu_rate_hz
        self._k = 0
        self._pending: tuple[int, int, tuple[int, int, int], asyncio.TimerHandle] | None = None
        self._last_gyro: tuple[tuple[int, int, int], int, int, int] = ((0, 0, 0), 0, 0, 0)
        self._last_counter: int | None = None
        self._flags = 0
        self.t_pps_us = 0
        self.pps_count = 0
        self._t_pps = -1e9
        self.seq = 0
        self.imu_frames = 0
        self.gyro_missing = 0
        self.routes: dict[str, str] = {}
        self._crc_seen = 0
        self._stopped = False
        self._trigger_handle: asyncio.TimerHandle | None = None
        self._gyro_dec: StreamDecoder | None = None
        #: channels stalled by an injected fault (emulator.faults) and what each held back (bytes or frames)
        self.stalled: set[str] = set()
        self.stall_counts: dict[str, int] = {}
        if "gyro" in ports:
            self._gyro_dec = StreamDecoder([gyro_port_format(cfg.gyro_device, cfg.gyro_format, cfg.stim300_ident)])
            ports["gyro"].on_receive = self._on_gyro_bytes
        #: the demultiplexer of UART0's output when host and host_nmea share it, else None
        self.host_demux: HostDemux | None = None
        shared = (cfg.routing.get("host_nmea") is not None and cfg.routing.get("host_nmea") == cfg.routing.get("host")
                  and "host" in ports and "host_nmea" in ports)
        for port, uart in cfg.routing.items():
            if shared and port == "host_nmea":
                continue
            if port in ports and uart in uarts:
                self._route(ports[port], uarts[uart], port)
                self.routes[port] = uart
        if shared:
            uart = cfg.routing["host"]
            self._route_demux(ports["host"], ports["host_nmea"], uarts[uart])
            self.routes["host_nmea"] = uart
        self.mag = mag
        self.mag_frames = 0
        self._mag_seq = 0
        self._mag_api = (MagFrame, encode_mag_frame) if mag is not None else None
        self._mag_pending: bytes | None = None
        self._mag_div = max(1, round(cfg.imu_rate_hz / cfg.mag_rate_hz))
        self._mag_channel: int | None = None
        self.monitor = monitor
        self.monitor_records = 0
        self._mon_record: Any = None
        self._mon_encode: Any = None
        self._mon_max = 1 << 30
        if monitor is not None:
            self._mon_record, self._mon_encode, channels = MonitorRecord, encode_monitor, dict(MONITOR_CHANNELS)
            self._mon_max = int(MONITOR_MAX_DATA)
            wanted = set(cfg.monitor_channels) if cfg.monitor_channels is not None else None
            if "mag" in channels and (wanted is None or "mag" in wanted):
                self._mag_channel = channels["mag"]
            for side, links in (("port", ports), ("uart", uarts)):
                for name, link in links.items():
                    if name in channels and (wanted is None or name in wanted):
                        link.listeners.append(_MonitorTap(self, channels[name], side))

    # -- time stamps ----------------------------------------------------------------------
    @staticmethod
    def counter_us(t: float) -> int:
        """The FPGA's 1 MHz counter at scenario time ``t`` (wraps at 2^32 us)."""
        return math.floor(t * 1e6 + 1e-6) & 0xFFFFFFFF

    def start(self) -> None:
        self._trigger_handle = self.loop.call_at(0.0, self._trigger)

    def stop(self) -> None:
        """Stop the trigger (and so the IMU frames and the triggered sensors)."""
        self._stopped = True
        if self._trigger_handle is not None:
            self._trigger_handle.cancel()
        if self._pending is not None:
            self._pending[3].cancel()
            self._pending = None

    def set_channel_stalled(self, channel: str, stalled: bool) -> None:
        """Stop (or resume) servicing a channel (injected fault): ``gyro`` (datagrams ignored), ``uart1``
        (no IMU/MAG frames sent), ``mag`` (no MAG frames) or a routed port (bytes not forwarded either way).
        ``stall_counts[channel]`` counts what was held back (bytes, or frames for uart1 and mag)."""
        if stalled:
            self.stalled.add(channel)
            self.stall_counts.setdefault(channel, 0)
        else:
            self.stalled.discard(channel)

    def _stall(self, channel: str, n: int) -> None:
        self.stall_counts[channel] = self.stall_counts.get(channel, 0) + n

    def pps_edge(self, t: float) -> None:
        """PPS rising edge (from the GNSS receiver's PPS line)."""
        self.t_pps_us = self.counter_us(t)
        self.pps_count = (self.pps_count + 1) & 0xFF
        self._t_pps = t

    # -- IMU acquisition ------------------------------------------------------------------
    def _trigger(self) -> None:
        t = self._k * self.period
        t_prev = t - self.period
        self._k += 1
        if self._stopped:
            return
        self._trigger_handle = self.loop.call_at(self._k * self.period, self._trigger)
        codes = self.accel.sample(t, t_prev) if self.accel is not None else (0, 0, 0)
        if self._pending is not None:  # previous datagram never came
            self._emit_frame(None)
        if self._mag_api is not None and (self._k - 1) % self._mag_div == 0 and self.stalled \
                and "mag" in self.stalled:
            self._stall("mag", 1)
        elif self._mag_api is not None and (self._k - 1) % self._mag_div == 0:
            words, status = self.mag.sample(t, t_prev)
            mag_frame_cls, encode = self._mag_api
            self._mag_pending = encode(mag_frame_cls(self._mag_seq & 0xFFFF, self.counter_us(t), words, status))
            self._mag_seq += 1
        handle = self.loop.call_at(t + self.cfg.gyro_timeout_s, self._gyro_timeout)
        self._pending = (self.counter_us(t), self.seq, codes, handle)
        if self.gyro is not None:
            self.gyro.trigger(t, t_prev)

    def _gyro_timeout(self) -> None:
        if self._pending is not None:
            self._emit_frame(None)

    def _on_gyro_bytes(self, data: bytes) -> None:
        assert self._gyro_dec is not None
        if self.stalled and "gyro" in self.stalled:
            self._stall("gyro", len(data))
            return
        for d in self._gyro_dec.feed(data):
            self._emit_frame(d)

    def _emit_frame(self, d: object | None) -> None:
        flags = self._flags
        self._flags = 0
        if d is not None:
            gyro = d.gyro  # type: ignore[attr-defined]
            if (self._last_counter is not None and d.counter is not None  # type: ignore[attr-defined]
                    and (d.counter - self._last_counter) % 256 != self.cfg.gyro_counter_step):  # type: ignore[attr-defined]
                flags |= _GYRO_COUNTER_JUMP
            if d.counter is not None:  # type: ignore[attr-defined]
                self._last_counter = d.counter  # type: ignore[attr-defined]
            status = d.status if hasattr(d, "status") else d.gyro_status  # type: ignore[attr-defined]  # STIM300
            self._last_gyro = (gyro, status, d.counter or 0, d.latency_us or 0)  # type: ignore[attr-defined]
        else:
            flags |= _GYRO_MISSING
            self.gyro_missing += 1
        if self._gyro_dec is not None and self._gyro_dec.stats.crc_errors != self._crc_seen:
            flags |= _GYRO_CRC_ERROR
            self._crc_seen = self._gyro_dec.stats.crc_errors
        if self._pending is None:
            t_trig, seq, codes = self.counter_us(self.loop.time()), self.seq, (0, 0, 0)
        else:
            t_trig, seq, codes, handle = self._pending
            handle.cancel()
            self._pending = None
        if codes and max(map(abs, codes)) >= ADC_CODE_MAX:
            flags |= _ADC_OVERRANGE
        if self.loop.time() - self._t_pps < 1.5:
            flags |= _PPS_VALID
        g, status, counter, latency = self._last_gyro
        self.seq += 1
        self.imu_frames += 1
        uart1 = self.uarts.get("uart1")
        if uart1 is not None and self.stalled and "uart1" in self.stalled:
            self._stall("uart1", 1)
            self._mag_pending = None
        elif uart1 is not None:
            # the bytes of ImuFrame(seq, t_trig, ...), built from the fields (no frame object)
            uart1.send(build_imu_frame(seq & 0xFFFF, t_trig, self.t_pps_us, self.pps_count, g, status, counter, latency,
                                       codes, flags))
            if self._mag_pending is not None:  # the trigger's MAG frame follows its IMU frame
                mag_frame = self._mag_pending
                self._mag_pending = None
                uart1.send(mag_frame)
                self.mag_frames += 1
                if self._mag_channel is not None:
                    self._mirror(self._mag_channel, 0, self.loop.time(), mag_frame)

    # -- crossbar ---------------------------------------------------------------------------
    def _route(self, port: Link, uart: Link, name: str) -> None:
        stalled = self.stalled

        def to_dsp(data: bytes) -> None:
            if stalled and name in stalled:
                self._stall(name, len(data))
                return
            uart.forward(data, port)

        def from_dsp(data: bytes) -> None:
            if stalled and name in stalled:
                self._stall(name, len(data))
                return
            port.forward(data, uart)

        port.on_receive = to_dsp
        uart.on_receive = from_dsp

    def _route_demux(self, host: Link, nmea: Link, uart: Link) -> None:
        """UART -> ``host`` / ``host_nmea`` frame by frame (:class:`HostDemux`); ``host`` -> UART as
        :meth:`_route`."""
        stalled = self.stalled
        demux = self.host_demux = HostDemux()
        out = {"host": host, "host_nmea": nmea}

        def from_dsp(data: bytes) -> None:
            if stalled and "host" in stalled:
                self._stall("host", len(data))
                return
            for port, frame in demux.feed(data):
                out[port].forward(frame, uart)

        self._route(host, uart, "host")
        uart.on_receive = from_dsp

    # -- monitor port -------------------------------------------------------------------------
    def _mirror(self, channel: int, direction: int, t: float, data: bytes) -> None:
        mon = self.monitor
        if mon is None:
            return
        t_us = self.counter_us(t)
        step = self._mon_max
        for i in range(0, len(data), step):  # records carry at most MONITOR_MAX_DATA bytes
            rec = self._mon_record(channel=channel, direction=direction, t_us=t_us, data=bytes(data[i:i + step]))
            mon.send(self._mon_encode(rec))
            self.monitor_records += 1
