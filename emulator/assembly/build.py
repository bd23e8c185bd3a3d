"""Assembly: the scenario resolved once (:func:`resolve_run`), then turned into the FPGA-DSP UARTs, the FPGA
configuration, the virtual DSP with its firmware, and the port map printed at start. The session
(:mod:`.session`) calls these in order."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, cast

from firmware_model.calibration import Calibration

from ..devices.fpga import FpgaConfig
from ..dsp.firmware_setup import build_firmware
from ..dsp.host import UartRxConfig, VirtualDsp, WatchdogConfig
from ..links import LineConfig, Link, MemHub, parse_mode
from ..scenario.resolved import (
    ResolvedPort,
    ResolvedScenario,
    ResolvedSensors,
    effective_routing,
    resolve_ports,
    resolve_scenario,
)
from ..scenario.schema import Scenario
from ..world.envelope import envelope_scenario, pinned_keys
from .ports import (
    EMIFA_BYTE_TIME_S,
    PORT_BAUD,
    PORT_ROLES,
    UART_NUM,
    PortInfo,
    dsp_uart_baud,
    port_direction,
    port_line,
    port_specs,
)

__all__ = ["build_dsp", "build_uarts", "effective_routing", "fpga_config", "port_map", "resolve_run"]


def resolve_run(scn: Scenario, seed: int | None = None, mode: str | None = None) -> ResolvedScenario:
    """The configuration one run is built from, resolved once (:mod:`emulator.scenario.resolved`): the envelope's
    draw for ``seed`` (default: the scenario's) written into the scenario first (docs/sensors.md "The envelope"),
    then every preset merged and every URL parsed; ``mode``: the command line's (None: the scenario's rule).
    ``psns-hil validate --effective`` prints what this returns."""
    seed = scn.seed if seed is None else seed
    pinned = pinned_keys(scn)
    drawn, draws = envelope_scenario(scn, seed)
    return resolve_scenario(drawn, seed, mode, envelope_draws=draws if scn.envelope.preset is not None else None,
                            envelope_pinned=tuple(pinned))


def _routed_from(scn: Scenario) -> dict[str, str]:
    """DSP UART -> the port routed to it (the host port where host_nmea shares its UART)."""
    out: dict[str, str] = {}
    for p, u in effective_routing(scn).items():
        if p != "host_nmea" or u not in out:
            out[u] = p
    return out


def fpga_config(scn: Scenario) -> FpgaConfig:
    """The virtual FPGA's configuration from the scenario's ``fpga`` and IMU sections."""
    return FpgaConfig(imu_rate_hz=scn.sensors.imu.rate_hz, gyro_timeout_s=scn.fpga.gyro_timeout_s,
                      gyro_format=scn.sensors.imu.format, gyro_device=scn.sensors.imu.device,
                      stim300_ident=int(scn.sensors.imu.stim300_datagram, 16),
                      gyro_counter_step=round(2000 / scn.sensors.imu.rate_hz),
                      routing=effective_routing(scn),
                      monitor_channels=tuple(scn.fpga.monitor_channels) if scn.fpga.monitor_channels else None,
                      mag_rate_hz=scn.fpga.mag_rate_hz)


def build_uarts(scn: Scenario, hub: MemHub, loop: Any
                ) -> tuple[dict[str, Link], dict[str, Link], dict[int, Link], dict[int, UartRxConfig]]:
    """The FPGA-DSP UART links: ``(FPGA ends by name, DSP ends by name, DSP ends by UART number, RX models)``.

    A UART is either a 16550 on the DSP (its real baud from the UART clock) or the FPGA's UART core read
    over EMIFA (``uart3`` by default: the C6747 has three UARTs).
    """
    uart_fpga: dict[str, Link] = {}
    dsp_ends: dict[str, Link] = {}
    uart_dsp: dict[int, Link] = {}
    rx_cfg: dict[int, UartRxConfig] = {}
    routed_from = _routed_from(scn)
    for uname, uspec in scn.fpga.uarts.items():
        dspec = scn.dsp.uarts[uname]
        bits, parity, stop = parse_mode(uspec.mode)
        emifa = uspec.effective_bus(uname) == "emifa"
        if emifa:  # the FPGA's UART core, read by the DSP over EMIFA
            f_line = LineConfig(baud=round(10 / EMIFA_BYTE_TIME_S), tx_queue_bytes=uspec.fifo_bytes)
            d_line = f_line.with_(tx_queue_bytes=dspec.tx_ring_bytes)
        else:
            f_line = LineConfig(baud=uspec.effective_baud(uname), data_bits=bits, parity=parity, stop_bits=stop,
                                tx_queue_bytes=uspec.fifo_bytes)
            d_baud = dspec.baud or f_line.baud
            if uname != "uart3":
                d_baud = dsp_uart_baud(d_baud, scn.dsp.uart_clock_hz, dspec.oversampling)
            d_line = f_line.with_(baud=d_baud, tx_queue_bytes=dspec.tx_ring_bytes)
            if dspec.mode is not None:
                db, dp, ds = parse_mode(dspec.mode)
                d_line = d_line.with_(data_bits=db, parity=dp, stop_bits=ds)
        a, b = hub.pair(uname, f_line, loop, line_b=d_line)
        uart_fpga[uname], uart_dsp[UART_NUM[uname]] = a, b
        dsp_ends[uname] = b
        # fastest byte arrival: the DSP line, or the routed port's line feeding an EMIFA core
        # (from the scenario, so that a replay, which has no such port, decides the same)
        min_pitch = d_line.byte_time
        src = routed_from.get(uname)
        src_spec = port_specs(scn).get(src) if src is not None else None
        if emifa and src is not None and src_spec is not None:
            min_pitch = max(min_pitch, port_line(src_spec, PORT_BAUD[src]).byte_time)
        rx_cfg[UART_NUM[uname]] = UartRxConfig(
            fifo_bytes=dspec.fifo_bytes, trigger_level=dspec.trigger_level, service=dspec.service,
            service_latency_s=dspec.latency_s, rx_ring_bytes=dspec.rx_ring_bytes, min_pitch_s=min_pitch)
    return uart_fpga, dsp_ends, uart_dsp, rx_cfg


def build_dsp(scn: Scenario, loop: Any, uart_dsp: dict[int, Link], rx_cfg: dict[int, UartRxConfig], events: Any,
              calibration: Calibration | None = None, sensors: ResolvedSensors | None = None) -> VirtualDsp:
    """The virtual DSP hosting the scenario's firmware on ``uart_dsp`` (a watchdog reset builds a new one);
    ``sensors``: the run's merged presets (the firmware's configuration reads the fitted units' ranges)."""
    wd = scn.dsp.watchdog
    return VirtualDsp(loop, build_firmware(scn, calibration, sensors), uart_dsp, scn.dsp.clock_hz, events,
                      tick_period_s=1.0 / scn.sensors.imu.rate_hz, rx=rx_cfg,
                      watchdog=WatchdogConfig(wd.enabled, wd.overrun_multiple, wd.action, wd.reset_time_s),
                      firmware_factory=lambda: build_firmware(scn, calibration, sensors))


def port_map(scn: Scenario, links: dict[str, Link], uart_fpga: dict[str, Link],
             bound: dict[str, Link] | None = None, resolved: Mapping[str, ResolvedPort] | None = None
             ) -> list[PortInfo]:
    """One row per external port, then one per FPGA-DSP UART (``ports.json`` and the table printed at start).

    ``bound``: the real ports that modelled sensors' streams are bound to (``direction: out | tee``), by port; each
    row's ``direction`` says which way the port goes (:func:`.ports.port_direction`); ``resolved``: the run's
    resolved ports (default: resolved here)."""
    ports: list[PortInfo] = []
    bound = bound or {}
    specs = resolved if resolved is not None else resolve_ports(scn)
    for port, link in links.items():
        if port.startswith("uart"):
            continue
        shown = bound.get(port, link)
        ports.append(PortInfo(name=port, role=PORT_ROLES.get(port, port), url=shown.url,
                              baud=link.line.baud, mode=link.line.mode, path=shown.describe(),
                              direction=port_direction(port, specs.get(port))))
    routed_from = _routed_from(scn)
    uarts = cast("dict[str, Any]", scn.fpga.uarts)
    for uname, f_end in uart_fpga.items():
        d_end = links[uname]
        emifa = uarts[uname].effective_bus(uname) == "emifa"
        src = "IMU frames" if uname == "uart1" else routed_from.get(uname, "unrouted")
        role = (f"FPGA UART core on EMIFA -> DSP {uname.upper()} ({src})" if emifa
                else f"FPGA -> DSP {uname.upper()} 16550 ({src})")
        baud = "EMIFA" if emifa else (f"{f_end.line.baud}" if f_end.line.baud == d_end.line.baud
                                      else f"{f_end.line.baud}/{d_end.line.baud}")
        ports.append(PortInfo(name=uname, role=role, url="internal", baud=baud, mode=d_end.line.mode,
                              path="internal", direction="internal"))
    return ports
