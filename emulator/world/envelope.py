"""The envelope: the world as a distribution over published conditions (docs/sensors.md, "The envelope").

The ``field`` world is one sample of reality: the typical unit in one condition. An envelope (a preset of
``emulator/presets/envelope.yaml``, chosen by the scenario's ``envelope.preset``) is a distribution: each run's seed
draws every parameter of the preset from the range published for that part or condition (the IMU up to its
datasheet limits, the GNSS antenna's surroundings, the sky, the lens and the polarizer, the mounting, the kind of
calibration) and writes the drawn values into the scenario before the world is built. The firmware never sees the
draws; they are recorded in the run's ``summary.json`` (``envelope``) and a campaign's ``runs.csv``.

The draws of a sensor the scenario does not fit (no camera section) or replays from a recording are dropped.
A key the scenario itself sets (in its file, by ``--set`` or by a campaign's ``--vary``) is **pinned**: the
scenario's value wins and the draw is dropped (the run's summary lists it under ``pinned``), so a sweep can vary
one dimension over the envelope of all the others. The envelope's thin cloud joins a scenario's own clouds.

Draws are reproducible per seed: the generator is ``numpy.random.default_rng([seed, ENVELOPE_STREAM])``, its own
stream (the sensors' streams are untouched), and the preset's draws are taken in file order, every draw consumed
whether or not its group is selected (selecting groups never changes another group's values).
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..scenario.presets import preset

__all__ = ["ENVELOPE_STREAM", "EnvelopeDraw", "apply_envelope", "draw_envelope", "envelope_draws", "envelope_scenario",
           "flat_draws", "pinned_keys"]


def pinned_keys(scn: Any) -> list[str]:
    """The keys of ``scn``'s envelope that the scenario sets itself (their draws are dropped)."""
    if scn.envelope.preset is None:
        return []
    given = scn.model_dump(exclude_unset=True)
    return [d.key for d in envelope_draws(scn.envelope.preset) if d.key != "sky.clouds" and _given(given, d.key)]

#: the envelope's random stream beside the run seed (``default_rng([seed, ENVELOPE_STREAM])``)
ENVELOPE_STREAM = 0xE17E


@dataclass(frozen=True)
class EnvelopeDraw:
    """One parameter of an envelope: the scenario key it sets, its group, distribution, arguments and source."""

    key: str
    group: str
    dist: str
    args: tuple[Any, ...]
    source: str

    def sample(self, rng: np.random.Generator) -> Any:
        """One value (plain Python types, as the scenario file would hold them)."""
        a = self.args
        if self.dist == "uniform":
            return float(rng.uniform(a[0], a[1]))
        if self.dist == "uniform_vec":
            return [float(x) for x in rng.uniform(a[0], a[1], int(a[2]))]
        if self.dist == "choice":
            return a[int(rng.integers(len(a)))]
        if self.dist == "bernoulli_cloud":
            p, r0, r1, d0, d1, s0, s1 = (float(x) for x in a)
            u = rng.uniform(size=7)  # always seven numbers: the stream does not depend on the outcome
            if u[0] >= p:
                return []
            return [{"az_deg": float(360.0 * u[1] % 360.0), "el_deg": float(20.0 + 60.0 * u[2]),
                     "radius_deg": float(r0 + (r1 - r0) * u[3]), "dop_scale": float(d0 + (d1 - d0) * u[4]),
                     "aop_sigma_deg": float(s0 + (s1 - s0) * u[5]), "intensity_scale": float(1.0 + 0.3 * u[6])}]
        raise ValueError(f"envelope draw {self.key}: unknown distribution {self.dist!r}")

    def bounds(self) -> tuple[float, float] | None:
        """The numeric range of a ``uniform`` / ``uniform_vec`` draw (None for the others)."""
        if self.dist in ("uniform", "uniform_vec"):
            return float(self.args[0]), float(self.args[1])
        return None


def envelope_draws(name: str) -> list[EnvelopeDraw]:
    """The draws of envelope preset ``name``, in file order (KeyError: no such preset)."""
    p = preset("envelope", name)
    out = []
    for key, d in p["draws"].items():
        out.append(EnvelopeDraw(key, str(d["group"]), str(d["dist"]), tuple(d.get("args", ())), str(d["source"])))
    return out


def draw_envelope(name: str, seed: int, groups: list[str] | None = None) -> dict[str, Any]:
    """The values seed ``seed`` draws from envelope ``name``: ``{scenario key: value}`` (only ``groups``' keys when
    given; every draw is consumed either way)."""
    rng = np.random.default_rng([int(seed), ENVELOPE_STREAM])
    out: dict[str, Any] = {}
    for d in envelope_draws(name):
        v = d.sample(rng)
        if groups is None or d.group in groups:
            out[d.key] = v
    return out


def _set(data: dict[str, Any], key: str, value: Any) -> None:
    node = data
    parts = key.split(".")
    for part in parts[:-1]:
        nxt = node.get(part)
        if not isinstance(nxt, dict):
            nxt = {}
            node[part] = nxt
        node = nxt
    node[parts[-1]] = copy.deepcopy(value)


def apply_envelope(data: dict[str, Any], draws: dict[str, Any]) -> dict[str, Any]:
    """``data`` (a scenario as a mapping) with the drawn values written in; a scenario that already lists clouds
    keeps them, the envelope's thin cloud joins them."""
    out = copy.deepcopy(data)
    for key, value in draws.items():
        if key == "sky.clouds":
            sky = out.setdefault("sky", {})
            sky["clouds"] = list(sky.get("clouds") or []) + copy.deepcopy(value)
            continue
        _set(out, key, value)
    return out


def flat_draws(draws: dict[str, Any]) -> dict[str, float | str]:
    """The draws as scalar columns (a vector ``k`` becomes ``k[0]``, ``k[1]``...; a cloud list its count and the
    first cloud's DOP scale), for a campaign's ``runs.csv``."""
    out: dict[str, float | str] = {}
    for k, v in draws.items():
        if k == "sky.clouds":
            out["sky.thin_clouds"] = float(len(v))
            out["sky.thin_cloud_dop_scale"] = float(v[0]["dop_scale"]) if v else math.nan
        elif isinstance(v, (list, tuple)):
            for i, x in enumerate(v):
                out[f"{k}[{i}]"] = float(x)
        elif isinstance(v, (int, float)):
            out[k] = float(v)
        else:
            out[k] = str(v)
    return out


def _given(data: dict[str, Any], key: str) -> bool:
    node: Any = data
    for part in key.split("."):
        if not isinstance(node, dict) or part not in node:
            return False
        node = node[part]
    return True


def _fitted(scn: Any, key: str) -> bool:
    """False for a draw of a sensor the scenario does not fit (the envelope never adds a camera) or whose model it
    replaces by a recording."""
    parts = key.split(".")
    if parts[0] != "sensors":
        return True
    sensor = getattr(scn.sensors, parts[1], None)
    return sensor is not None and getattr(sensor, "enabled", True) and getattr(sensor, "recorded", None) is None


def envelope_scenario(scn: Any, seed: int) -> tuple[Any, dict[str, Any]]:
    """``scn`` (a validated :class:`~emulator.scenario.schema.Scenario`) with its envelope's draws for ``seed``
    written in, validated again, and the draws applied (the keys the scenario sets itself are pinned: module
    docstring); ``(scn, {})`` when the scenario asks for no envelope. The returned scenario has no envelope."""
    from pathlib import Path

    from ..scenario.loader import validate_scenario_data

    spec = scn.envelope
    if spec.preset is None:
        return scn, {}
    draws = draw_envelope(spec.preset, seed, list(spec.groups) if spec.groups is not None else None)
    given = scn.model_dump(exclude_unset=True)
    draws = {k: v for k, v in draws.items() if (k == "sky.clouds" or not _given(given, k)) and _fitted(scn, k)}
    data = apply_envelope(given, draws)
    data["envelope"] = {}  # the drawn world is a plain scenario: drawing again (a split run's DSP process) is a no-op
    base = Path(scn.base_dir) if scn.base_dir is not None else None
    out = validate_scenario_data(data, {}, f"{scn.source_file} (envelope {spec.preset}, seed {seed})", base,
                                 check_environment=False)
    out._source_file = scn.source_file
    return out, draws
