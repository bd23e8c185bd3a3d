"""Scenario sections owned by the runtime: links per port, FPGA routing and UARTs, DSP UARTs,
clock and watchdog. ``docs/runtime.md`` describes every field."""

from __future__ import annotations

from typing import Literal

from pydantic import AliasChoices, Field, field_validator, model_validator

from .base import Model

__all__ = [
    "DEFAULT_UART_BAUD",
    "DSP_UARTS",
    "EXTERNAL_PORTS",
    "DspSpec",
    "DspUartSpec",
    "ExternalDspSpec",
    "FpgaSpec",
    "LinkSpec",
    "Links",
    "LockstepSpec",
    "UartSpec",
    "WatchdogSpec",
]

#: External ports of the box (FPGA connectors) that can be routed to a DSP UART.
EXTERNAL_PORTS = ("host", "gnss", "psns", "host_nmea")
_MODE = r"^[5-8][NEO](1|1\.5|2)$"


class LinkSpec(Model):
    """One external port's link: where it goes and its serial line settings (FPGA side)."""

    url: str = Field(description="mem://NAME, pty://NAME, serial:///dev/ttyXXX, zenoh://RUN/PORT, "
                                 "can://virtual/CH or can://socketcan/IF")
    baud: int | None = Field(None, gt=0, le=20_000_000, description="FPGA port's baud (default per port)")
    mode: str = Field("8N1", pattern=_MODE)
    queue_bytes: int = Field(4096, ge=1, le=1 << 24, description="TX queue / FIFO of the FPGA port, bytes")
    device_baud: int | None = Field(None, gt=0, le=20_000_000,
                                    description="the device's own UART baud (mem://, or direction out/tee); "
                                                "default = baud")
    device_mode: str | None = Field(None, pattern=_MODE, description="the device's own frame format; default = mode")
    direction: Literal["in", "out", "tee"] = Field(
        "in", description="sensor ports (gyro, gnss, psns) with a pty://, serial:// or zenoh:// URL: 'in' the port "
                          "replaces the modelled sensor (an outside device feeds the FPGA), 'out' the modelled "
                          "sensor drives the port instead of the FPGA, 'tee' it drives both (docs/runtime.md)")

    @property
    def modelled(self) -> bool:
        """Whether the modelled sensor drives this port (a ``mem://`` URL, or direction ``out`` / ``tee``)."""
        from ..links import parse_link_url

        return parse_link_url(self.url).scheme == "mem" or self.direction != "in"

    @field_validator("url")
    @classmethod
    def _url(cls, v: str) -> str:
        from ..links import parse_link_url

        parse_link_url(v)  # raises LinkConfigError (a ValueError) with the accepted form
        return v


class Links(Model):
    gyro: LinkSpec = LinkSpec(url="mem://gyro", baud=460800)
    gnss: LinkSpec = LinkSpec(url="mem://gnss", baud=9600)
    psns: LinkSpec | None = None
    host: LinkSpec = LinkSpec(url="mem://host", baud=460800)
    host_nmea: LinkSpec | None = Field(
        None, description="a second host port carrying only the firmware's NMEA output (firmware.nmea): on UART0 "
                          "with the host port, demultiplexed by the FPGA (the default), or on a free DSP UART of "
                          "its own in fpga.routing (e.g. uart2 without a PSNS port)")
    monitor: LinkSpec | None = Field(None, description="FPGA MONITOR port: every channel, tagged and time-stamped")


#: serial-line baud of each FPGA -> DSP UART when a scenario gives none
DEFAULT_UART_BAUD = {"uart0": 460800, "uart1": 460800, "uart2": 115200, "uart3": 115200}


class UartSpec(Model):
    """The FPGA side of one FPGA -> DSP UART (``fpga.uarts.uartN``)."""

    bus: Literal["serial", "emifa"] | None = Field(
        None, description="serial: a UART line to a DSP on-chip UART; emifa: the FPGA's UART core, whose FIFO the "
        "DSP reads over EMIFA (default for uart3 unless a baud is given, serial otherwise)")
    baud: int | None = Field(None, gt=0, le=3_000_000, description="serial line baud (default per UART)")
    mode: str = Field("8N1", pattern=_MODE)
    fifo_bytes: int = Field(2048, ge=1, le=1 << 24, validation_alias=AliasChoices("fifo_bytes", "queue_bytes"),
                            description="FPGA FIFO towards the DSP, bytes (Spartan-3E block RAM: 2 KiB)")

    def effective_bus(self, name: str) -> str:
        if self.bus is not None:
            return self.bus
        return "emifa" if name == "uart3" and "baud" not in self.model_fields_set else "serial"

    def effective_baud(self, name: str) -> int:
        return self.baud or DEFAULT_UART_BAUD[name]


#: The DSP UARTs, and the FPGA ports the crossbar routes to them.
UartName = Literal["uart0", "uart1", "uart2", "uart3"]
DSP_UARTS: tuple[UartName, ...] = ("uart0", "uart1", "uart2", "uart3")
RoutedPort = Literal["host", "gnss", "psns", "host_nmea"]
RoutedUart = Literal["uart0", "uart2", "uart3"]


def _default_routing() -> dict[RoutedPort, RoutedUart]:
    return {"host": "uart0", "psns": "uart2", "gnss": "uart3"}


def _default_uarts() -> dict[UartName, UartSpec]:
    return {
        "uart0": UartSpec(baud=460800),
        "uart1": UartSpec(baud=460800),
        "uart2": UartSpec(baud=115200),
        "uart3": UartSpec(bus="emifa", baud=115200),  # the baud applies only with bus: serial
    }


class FpgaSpec(Model):
    routing: dict[RoutedPort, RoutedUart] = Field(
        default_factory=_default_routing,
        description="crossbar: external port -> DSP UART (uart1 carries the FPGA's IMU frames)",
    )
    uarts: dict[UartName, UartSpec] = Field(default_factory=_default_uarts)
    gyro_timeout_s: float = Field(0.004, gt=0, lt=0.1)
    mag_rate_hz: float = Field(100.0, gt=0, le=2000,
                               description="magnetometer sample / MAG frame rate; the trigger rate divided by an "
                                           "integer")
    monitor_channels: list[Literal["gyro", "gnss", "psns", "host", "uart0", "uart1", "uart2", "uart3", "mag"]] | None \
        = Field(None, description="channels mirrored on the MONITOR port (default: all)")

    @field_validator("uarts")
    @classmethod
    def _fill(cls, v: dict[UartName, UartSpec]) -> dict[UartName, UartSpec]:
        out = _default_uarts()
        out.update(v)
        return out

    @field_validator("routing")
    @classmethod
    def _one_port_per_uart(cls, v: dict[str, str]) -> dict[str, str]:
        seen: dict[str, str] = {}
        for port, uart in v.items():
            if uart in seen:
                raise ValueError(f"{port} and {seen[uart]} are both routed to {uart}; a DSP UART takes one port")
            seen[uart] = port
        return v


class DspUartSpec(Model):
    """The DSP side of one UART (``dsp.uarts.uartN``): 16550 RX FIFO, its service, the driver rings."""

    baud: int | None = Field(None, gt=0, le=3_000_000, description="DSP UART baud; default = the FPGA side's")
    mode: str | None = Field(None, pattern=_MODE, description="DSP UART frame format; default = the FPGA side's")
    oversampling: Literal[16, 13] = Field(16, description="MDR.OSM_SEL (used with dsp.uart_clock_hz)")
    fifo_bytes: int = Field(16, ge=1, le=4096, description="RX hardware FIFO (16550: 16)")
    trigger_level: Literal[1, 4, 8, 14] = Field(8, description="RX FIFO trigger level, bytes")
    service: Literal["isr", "edma", "poll"] = Field(
        "isr", description="who drains the RX FIFO: an interrupt, an EDMA event, or the main loop once per tick")
    service_latency_s: float | None = Field(
        None, ge=0, lt=0.1, description="trigger -> FIFO drained (default: isr 2 us, edma 0.5 us)")
    rx_ring_bytes: int = Field(4096, ge=16, le=1 << 20, description="firmware RX ring buffer, bytes")
    tx_ring_bytes: int = Field(4096, ge=16, le=1 << 20, description="firmware TX ring buffer, bytes")

    @model_validator(mode="after")
    def _trigger_fits(self) -> DspUartSpec:
        if self.trigger_level > self.fifo_bytes:
            raise ValueError(f"trigger_level {self.trigger_level} exceeds fifo_bytes {self.fifo_bytes}")
        return self

    @property
    def latency_s(self) -> float:
        if self.service_latency_s is not None:
            return self.service_latency_s
        return {"isr": 2e-6, "edma": 0.5e-6, "poll": 0.0}[self.service]


def _default_dsp_uarts() -> dict[UartName, DspUartSpec]:
    return {u: DspUartSpec() for u in DSP_UARTS}


class WatchdogSpec(Model):
    enabled: bool = True
    overrun_multiple: float = Field(4.0, gt=1, le=1000,
                                    description="a tick longer than this many IMU periods trips the watchdog")
    action: Literal["flag", "reset"] = Field("flag", description="flag: event only; reset: restart the firmware")
    reset_time_s: float = Field(0.05, ge=0, le=10, description="DSP busy rebooting after a watchdog reset")


class LockstepSpec(Model):
    """A foreign firmware stepped in lockstep with the emulator's clock (``dsp.external.lockstep``; ICD section 10,
    docs/icd.md section 10): in-process (``library``, a shared library with the psns_fw.h ABI) or out-of-process
    (``command``, a program speaking the framing of section 10.3 on its stdin/stdout). Paths are relative to the
    scenario's directory and must stay inside it; nothing is loaded or started unless the run is given
    ``--allow-firmware``."""

    library: str | None = Field(
        None, min_length=1, max_length=4096, description="shared library (.so) exporting psns_fw_abi_version, "
        "psns_fw_init, psns_fw_rx, psns_fw_step, psns_fw_close; loaded into the emulator's process")
    command: list[str] | None = Field(
        None, min_length=1, max_length=64, description="program and arguments of a lockstep firmware process: "
        "the program is a path inside the scenario's directory, the arguments are passed as they are")
    step_timeout_s: float = Field(
        10.0, gt=0, le=3600, description="out-of-process: wall-clock seconds the emulator waits for one reply "
        "before it counts the firmware as hung and stops it")

    @model_validator(mode="after")
    def _one_transport(self) -> LockstepSpec:
        if (self.library is None) == (self.command is None):
            raise ValueError("give exactly one of library (in-process) or command (out-of-process)")
        for a in [self.library or "", *(self.command or [])]:
            if "\x00" in a:
                raise ValueError("a NUL character in a path or argument")
        return self


class ExternalDspSpec(Model):
    """The DSP outside the emulator (``dsp.external``): the virtual FPGA's DSP-side UARTs are bound to ports, and a
    real C6747 board (over USB-serial adapters) or a firmware process in any language takes the virtual DSP's
    place (``uarts``); or a foreign firmware is stepped in lockstep behind the DSP's UARTs (``lockstep``). FPGA
    timing, routing and monitor are unchanged; the recorder still decodes the host stream."""

    uarts: dict[UartName, str] = Field(
        default_factory=dict, description="DSP UART -> port URL (pty://NAME, serial:///dev/ttyXXX, "
        "zenoh://RUN/PORT); the line is the FPGA side's (fpga.uarts); an unlisted UART's bytes go nowhere")
    silence_s: float = Field(
        2.0, gt=0, le=3600, description="no byte from the external DSP for this long (s, after the first IMU frame "
        "it was sent) is counted as a silence in summary.json's external_dsp section")
    lockstep: LockstepSpec | None = Field(
        None, description="a foreign firmware in lockstep, in the virtual DSP's place (docs/icd.md section 10)")

    @field_validator("uarts")
    @classmethod
    def _urls(cls, v: dict[str, str]) -> dict[str, str]:
        from ..links import parse_link_url

        seen: dict[str, str] = {}
        for uname, url in v.items():
            target = parse_link_url(url).target
            if target in seen:
                raise ValueError(f"{uname} and {seen[target]} are both bound to {url!r}: one port per UART")
            seen[target] = uname
            scheme = parse_link_url(url).scheme  # raises LinkConfigError (a ValueError) with the accepted form
            if scheme in ("mem", "can"):
                raise ValueError(f"{uname}: {url!r}: an external DSP needs a byte port (pty://, serial://, "
                                 f"zenoh://), not {scheme}://")
        return v

    @model_validator(mode="after")
    def _uarts_or_lockstep(self) -> ExternalDspSpec:
        if bool(self.uarts) == (self.lockstep is not None):
            raise ValueError("give either uarts (the DSP on ports) or lockstep (a foreign firmware stepped "
                             "in virtual time), not both and not neither")
        return self


class DspSpec(Model):
    clock_hz: float = Field(300e6, ge=1e6, le=2e9)
    uart_clock_hz: float | None = Field(
        None, gt=0, le=1e9, description="UART input clock (C6747: PLL0_SYSCLK2 = clock_hz / 2); when set, UART0-2 "
        "run at the baud their divisor gives: clock / (oversampling x round(clock / (oversampling x baud)))")
    uarts: dict[UartName, DspUartSpec] = Field(default_factory=_default_dsp_uarts)
    watchdog: WatchdogSpec = WatchdogSpec()
    external: ExternalDspSpec | None = None

    @field_validator("uarts")
    @classmethod
    def _fill(cls, v: dict[UartName, DspUartSpec]) -> dict[UartName, DspUartSpec]:
        out = _default_dsp_uarts()
        out.update(v)
        return out
