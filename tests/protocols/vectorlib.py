"""Golden-vector files: reading, writing, and the typed <-> JSON mapping (see tests/vectors/README.md)."""

from __future__ import annotations

import dataclasses
import datetime as dt
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from protocols import host, host_commands, host_text, imu_frame, monitor, nmea, psns, stim, stim300, ubx
from protocols.stream import FrameFormat

VECTORS = Path(__file__).resolve().parents[1] / "vectors"
DAMAGED = VECTORS / "damaged"

_MODULES = (stim, stim300, imu_frame, nmea, ubx, psns, monitor, host, host_commands, host_text)
#: Every frame dataclass of protocols, by class name.
TYPES: dict[str, type] = {
    name: obj
    for mod in _MODULES
    for name, obj in vars(mod).items()
    if isinstance(obj, type) and dataclasses.is_dataclass(obj) and obj.__module__ == mod.__name__
}

#: format key -> factory(config) of the FrameFormat that decodes (and encodes) the vector.
FORMATS: dict[str, Callable[..., Any]] = {
    "stim210": stim.Stim210Format,
    "stim300": stim.Stim300Format,
    "imu": imu_frame.ImuFrameFormat,
    "fpga": imu_frame.FpgaFrameFormat,
    "nmea": nmea.NmeaFormat,
    "host-text": host.HostTextFormat,
    "ubx": ubx.UbxFormat,
    "psns": psns.PsnsFormat,
    "monitor": monitor.MonitorFormat,
    "host": host.HostFormat,
}


def make_format(key: str, config: dict | None = None) -> FrameFormat:
    return FORMATS[key](**(config or {}))


def to_json(v: Any) -> Any:
    """Typed frame objects -> JSON-able values (tagged so that :func:`from_json` inverts it)."""
    if dataclasses.is_dataclass(v) and not isinstance(v, type):
        return {"__type__": type(v).__name__, **{f.name: to_json(getattr(v, f.name)) for f in dataclasses.fields(v)}}
    if isinstance(v, (tuple, list)):
        return [to_json(x) for x in v]
    if isinstance(v, bytes):
        return {"__bytes__": v.hex()}
    if isinstance(v, dt.time):
        return {"__time__": v.isoformat()}
    if isinstance(v, dt.date):
        return {"__date__": v.isoformat()}
    if isinstance(v, bool) or v is None or isinstance(v, str):
        return v
    if isinstance(v, int):
        return int(v)
    if isinstance(v, float):
        return v
    raise TypeError(f"cannot store {type(v).__name__} in a vector")


def from_json(v: Any) -> Any:
    if isinstance(v, list):
        return tuple(from_json(x) for x in v)
    if isinstance(v, dict):
        if "__type__" in v:
            cls = TYPES[v["__type__"]]
            return cls(**{k: from_json(x) for k, x in v.items() if k != "__type__"})
        if "__bytes__" in v:
            return bytes.fromhex(v["__bytes__"])
        if "__time__" in v:
            return dt.time.fromisoformat(v["__time__"])
        if "__date__" in v:
            return dt.date.fromisoformat(v["__date__"])
        return {k: from_json(x) for k, x in v.items()}
    return v


def read_hex(path: Path) -> bytes:
    """The bytes of a ``.hex`` file: ``#`` starts a comment, whitespace is ignored."""
    out = []
    for line in path.read_text().splitlines():
        line = line.split("#", 1)[0]
        out.append("".join(line.split()))
    return bytes.fromhex("".join(out))


def write_hex(path: Path, data: bytes, header: list[str], width: int = 16) -> None:
    lines = [f"# {h}" if h else "#" for h in header]
    for i in range(0, len(data), width):
        lines.append(" ".join(f"{b:02x}" for b in data[i : i + width]))
    path.write_text("\n".join(lines) + "\n")


def load_vector(json_path: Path) -> tuple[dict, bytes]:
    meta = json.loads(json_path.read_text())
    return meta, read_hex(json_path.with_suffix(".hex"))


def vector_names(folder: Path = VECTORS) -> list[str]:
    return sorted(p.stem for p in folder.glob("*.json"))
