"""The port table: external ports and FPGA-DSP UARTs, their roles, default lines and stream formats.

Time mode: ``--fast`` / ``--realtime`` on the command line win; else the scenario's ``mode`` if
the file sets one; else ``realtime`` when any port has a real endpoint (``pty://``, ``serial://``:
real peers live in wall time) and ``fast`` otherwise (docs/architecture.md).

Which way a sensor port goes (``links.NAME.direction``, docs/runtime.md "Sensor ports out", decision D-7.12):
``in`` (default) an outside device on the port replaces the modelled sensor; ``out`` the modelled sensor drives
the port and the FPGA's port stays idle; ``tee`` it drives both. Out and tee keep the in-process pair (sensor end,
FPGA end) so that the line model and the link's faults act once, as inside, and a :class:`SensorPortBinding`
copies what arrives at the FPGA end onto the real port and hands what the port's peer sends to the sensor.
"""

from __future__ import annotations

from typing import Any

from firmware_model import UART_GNSS, UART_HOST, UART_IMU, UART_PSNS
from protocols.host import HostFormat
from protocols.imu_frame import FpgaFrameFormat
from protocols.monitor import MonitorFormat
from protocols.nmea import NMEA_RX_MAX_LEN, NmeaFormat
from protocols.psns import PsnsFormat
from protocols.stim import Stim210Format
from protocols.ubx import UbxFormat

from ..links import LineConfig, Link, parse_link_url, parse_mode
from ..scenario.resolved import ResolvedPort, port_specs, resolve_ports, run_mode
from ..scenario.schema import LinkSpec, Scenario

__all__ = [
    "EMIFA_BYTE_TIME_S",
    "PORT_BAUD",
    "PORT_ROLES",
    "UART_NUM",
    "PortInfo",
    "SensorPortBinding",
    "device_line",
    "dsp_uart_baud",
    "port_direction",
    "port_formats",
    "port_line",
    "port_specs",
    "real_time_ports",
    "resolve_mode",
]

UART_NUM = {"uart0": UART_HOST, "uart1": UART_IMU, "uart2": UART_PSNS, "uart3": UART_GNSS}
PORT_ROLES = {
    "gyro": "STIM210 gyro -> FPGA (RS422)",
    "gnss": "GNSS receiver -> FPGA (RS422)",
    "psns": "polarization sensor -> FPGA (RS232)",
    "host": "FPGA HOST (RS422) <-> DSP UART0: navigation out, commands in",
    "host_nmea": "FPGA second host port: the firmware's NMEA 0183 navigation output",
    "monitor": "FPGA MONITOR: every channel, tagged and time-stamped",
}
#: default baud of each external port
PORT_BAUD = {"gyro": 460800, "gnss": 9600, "host": 460800, "psns": 115200, "monitor": 3_000_000, "host_nmea": 115200}
#: One byte read by the DSP from the FPGA UART core over EMIFA, s [E: a few EMIFA async cycles].
EMIFA_BYTE_TIME_S = 1e-7


def port_formats(name: str, nmea_out: bool = False) -> dict[str, list[Any]]:
    """Stream-decoder formats per direction for a port / UART name (recorder, monitor, tests); ``nmea_out``: the
    firmware also writes NMEA sentences on the host port (``firmware.nmea``)."""
    host = {"out": [HostFormat(), NmeaFormat()] if nmea_out else [HostFormat()], "in": [HostFormat()]}
    table: dict[str, dict[str, list[Any]]] = {
        "gyro": {"in": [Stim210Format("m")]},
        "gnss": {"in": [NmeaFormat(NMEA_RX_MAX_LEN), UbxFormat()]},  # UBX may follow; real receivers: long lines
        "psns": {"in": [PsnsFormat()]},
        "host": host,
        "monitor": {"out": [MonitorFormat()]},
        "host_nmea": {"out": [NmeaFormat()]},
        "uart0": host,
        "uart1": {"in": [FpgaFrameFormat()]},  # IMU frames and MAG frames (docs/icd.md)
        "uart2": {"in": [PsnsFormat()]},
        "uart3": {"in": [NmeaFormat(NMEA_RX_MAX_LEN), UbxFormat()]},
    }
    return {d: list(f) for d, f in table.get(name, {}).items()}


class PortInfo(dict[str, Any]):
    """One row of the port map printed at start: name, role, url, baud, mode, path, direction."""


def port_direction(port: str, rp: ResolvedPort | None) -> str:
    """The port map's ``direction`` of an external port: for a sensor port ``model`` (in-process, the modelled
    sensor feeds the FPGA), ``in`` (an outside device feeds the FPGA), ``out`` or ``tee`` (the modelled sensor's
    stream goes out on the real port; with tee also to the FPGA); ``in/out`` for the host port, ``out`` for the
    monitor."""
    if port == "host":
        return "in/out"
    if port in ("monitor", "host_nmea"):
        return "out"
    if rp is None:
        return ""
    if rp.spec.direction == "in" and rp.scheme == "mem":
        return "model"
    return rp.spec.direction


class SensorPortBinding:
    """A modelled sensor's stream bound to a real port (``direction: out | tee``; see the module docstring).

    ``fpga_end`` is the FPGA end of the sensor's in-process pair: every chunk that arrives there (paced by the
    sensor's line, after the link's faults) is relayed to ``port`` at that moment (:meth:`Link.relay`), so the
    peer sees the bytes the FPGA sees, at the same times. Bytes the peer writes (a host polling a u-blox receiver)
    go back through ``fpga_end`` (cut-through, the line's pace) to the sensor's own link, where the device reads
    them as it reads the FPGA's. With ``out`` the FPGA is given an idle port instead of ``fpga_end``.
    """

    def __init__(self, name: str, direction: str, fpga_end: Link, port: Link) -> None:
        self.name = name
        self.direction = direction
        self.fpga_end = fpga_end
        self.port = port
        #: bytes the peer sent towards the sensor
        self.peer_bytes = 0
        fpga_end.listeners.insert(0, self)
        port.on_receive = self._from_peer

    def on_link_bytes(self, link: Link, direction: str, t: float, data: bytes) -> None:  # LinkListener
        if direction == "in":  # the sensor's bytes, as they reach the FPGA end
            pitch = link.last_rx_pitch
            self.port.relay(data, t - len(data) * pitch, pitch)

    def _from_peer(self, data: bytes) -> None:
        self.peer_bytes += len(data)
        self.fpga_end.forward(data, self.port)



def resolve_mode(scn: Scenario, requested: str | None = None) -> str:
    """The time mode of a run (see module docstring; a run reads it from its resolved scenario,
    :attr:`emulator.scenario.resolved.ResolvedScenario.mode`, decided by the same rule)."""
    return run_mode(scn, resolve_ports(scn), requested)


def real_time_ports(scn: Scenario) -> list[str]:
    """``links.NAME (URL)`` of each port with a real peer (``pty://``, ``serial://``): in fast mode virtual time
    races past such a peer, which then sees frames far faster than the line's rate."""
    ext = scn.dsp.external.uarts if scn.dsp.external is not None else {}
    return [f"links.{port} ({spec.url})" for port, spec in port_specs(scn).items()
            if parse_link_url(spec.url).scheme in ("pty", "serial")] + [
        f"dsp.external.uarts.{u} ({url})" for u, url in ext.items() if parse_link_url(url).scheme in ("pty", "serial")]


def dsp_uart_baud(nominal: int, uart_clock_hz: float | None, oversampling: int) -> int:
    """Baud a C6747 UART really runs at: ``clock / (os x divisor)``, divisor rounded (SPRS377 6.24)."""
    if uart_clock_hz is None:
        return nominal
    div = max(1, min(65535, round(uart_clock_hz / (oversampling * nominal))))
    return round(uart_clock_hz / (oversampling * div))


def port_line(spec: LinkSpec, default_baud: int) -> LineConfig:
    """The line of a port's FPGA end (the scenario's baud, mode and queue)."""
    bits, parity, stop = parse_mode(spec.mode)
    return LineConfig(baud=spec.baud or default_baud, data_bits=bits, parity=parity, stop_bits=stop,
                      tx_queue_bytes=spec.queue_bytes)


def device_line(spec: LinkSpec, fpga_line: LineConfig) -> LineConfig:
    """The line of a port's device end: the FPGA end's, unless the scenario sets the device's own."""
    kw: dict[str, Any] = {}
    if spec.device_baud is not None:
        kw["baud"] = spec.device_baud
    if spec.device_mode is not None:
        kw["data_bits"], kw["parity"], kw["stop_bits"] = parse_mode(spec.device_mode)
    return fpga_line.with_(**kw) if kw else fpga_line
