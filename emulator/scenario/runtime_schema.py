"""Scenario sections owned by the runtime: links per port, FPGA routing and UARTs, DSP clock."""

from __future__ import annotations

from typing import Literal

from pydantic import Field, field_validator

from .base import Model

__all__ = ["LinkSpec", "Links", "UartSpec", "FpgaSpec", "DspSpec"]


class LinkSpec(Model):
    url: str = Field(description="mem://NAME, pty://NAME or serial:///dev/ttyXXX")
    baud: int | None = Field(None, gt=0, le=20_000_000)
    mode: str = Field("8N1", pattern=r"^[5-8][NEO](1|1\.5|2)$")
    queue_bytes: int = Field(4096, ge=1, le=1 << 24)

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


class UartSpec(Model):
    baud: int = Field(gt=0, le=3_000_000)
    queue_bytes: int = Field(4096, ge=1, le=1 << 24)


def _default_uarts() -> dict[str, UartSpec]:
    return {
        "uart0": UartSpec(baud=460800),
        "uart1": UartSpec(baud=460800),
        "uart2": UartSpec(baud=115200),
        "uart3": UartSpec(baud=115200),
    }


class FpgaSpec(Model):
    routing: dict[Literal["host", "gnss", "psns"], Literal["uart0", "uart2", "uart3"]] = Field(
        default_factory=lambda: {"host": "uart0", "psns": "uart2", "gnss": "uart3"}
    )
    uarts: dict[Literal["uart0", "uart1", "uart2", "uart3"], UartSpec] = Field(default_factory=_default_uarts)
    gyro_timeout_s: float = Field(0.004, gt=0, lt=0.1)

    @field_validator("uarts")
    @classmethod
    def _fill(cls, v: dict[str, UartSpec]) -> dict[str, UartSpec]:
        out = _default_uarts()
        out.update(v)
        return out


class DspSpec(Model):
    clock_hz: float = Field(300e6, ge=1e6, le=2e9)


