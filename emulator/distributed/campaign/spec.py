"""What a campaign runs: its configuration, the ``--vary`` variations and their distributions.

Distributions (``normal``, ``uniform``, ``choice``) and ``KEY=DISTRIBUTION`` are parsed here with clear errors;
:func:`validate_variations` checks every key and a representative value of each distribution against the
scenario before anything is dispatched; :func:`apply_variations` writes drawn values into the scenario data.
"""

from __future__ import annotations

import ast
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ...errors import EmulatorError

__all__ = [
    "CampaignConfig",
    "CampaignError",
    "Distribution",
    "Variation",
    "apply_variations",
    "load_campaign_scenario",
    "parse_distribution",
    "parse_vary",
    "validate_variations",
]


class CampaignError(EmulatorError):
    """A campaign that cannot start (bad --vary, unknown key, no cluster)."""


# -- distributions ---------------------------------------------------------------------------------
@dataclass(frozen=True)
class Distribution:
    """A parameter distribution: ``kind`` in normal / uniform / choice and its arguments."""

    kind: str
    args: tuple[Any, ...]

    def sample(self, rng: np.random.Generator) -> Any:
        if self.kind == "normal":
            return float(rng.normal(self.args[0], self.args[1]))
        if self.kind == "uniform":
            return float(rng.uniform(self.args[0], self.args[1]))
        return self.args[int(rng.integers(len(self.args)))]

    def representatives(self) -> list[Any]:
        """Values that any member could plausibly draw, to validate the scenario with before dispatch."""
        if self.kind == "normal":
            return [float(self.args[0])]
        if self.kind == "uniform":
            return [0.5 * (self.args[0] + self.args[1])]
        return list(self.args)

    def __str__(self) -> str:
        return f"{self.kind}({', '.join(_fmt_arg(a) for a in self.args)})"


def _fmt_arg(a: Any) -> str:
    if isinstance(a, float):
        return f"{a:g}"
    return str(a)


_DIST_RE = re.compile(r"^\s*([a-z]+)\s*\((.*)\)\s*$", re.S)
_DIST_FORMS = "normal(MEAN, SIGMA), uniform(LOW, HIGH) or choice(A, B, ...)"


def _scalar(text: str) -> Any:
    import yaml

    t = text.strip()
    if not t:
        raise ValueError("empty argument")
    try:
        v = yaml.safe_load(t)
    except yaml.YAMLError as exc:
        raise ValueError(f"cannot read {t!r}") from exc
    if isinstance(v, (dict, list)) or v is None:
        raise ValueError(f"{t!r} is not a scalar")
    return v


def _number(text: str, what: str, dist: str) -> float:
    try:
        v = ast.literal_eval(text.strip())
    except (ValueError, SyntaxError):
        v = None
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v):
        raise CampaignError(f"{dist}: {what} must be a finite number, got {text.strip()!r}")
    return float(v)


def parse_distribution(text: str) -> Distribution:
    """Parse ``normal(0.15, 0.02)``, ``uniform(1, 2)``, ``choice(base, federated)``; clear errors."""
    m = _DIST_RE.match(text)
    if not m:
        raise CampaignError(f"bad distribution {text!r}; expected {_DIST_FORMS}")
    kind, body = m.group(1), m.group(2)
    parts = [p for p in body.split(",")]
    if kind == "normal":
        if len(parts) != 2:
            raise CampaignError(f"{text!r}: normal takes 2 arguments (MEAN, SIGMA), got {len(parts)}")
        mu, sigma = _number(parts[0], "MEAN", text), _number(parts[1], "SIGMA", text)
        if sigma < 0:
            raise CampaignError(f"{text!r}: SIGMA must be >= 0")
        return Distribution("normal", (mu, sigma))
    if kind == "uniform":
        if len(parts) != 2:
            raise CampaignError(f"{text!r}: uniform takes 2 arguments (LOW, HIGH), got {len(parts)}")
        lo, hi = _number(parts[0], "LOW", text), _number(parts[1], "HIGH", text)
        if not lo < hi:
            raise CampaignError(f"{text!r}: LOW must be < HIGH")
        return Distribution("uniform", (lo, hi))
    if kind == "choice":
        if not body.strip():
            raise CampaignError(f"{text!r}: choice needs at least one value")
        try:
            values = tuple(_scalar(p) for p in parts)
        except ValueError as exc:
            raise CampaignError(f"{text!r}: {exc}") from exc
        return Distribution("choice", values)
    raise CampaignError(f"unknown distribution {kind!r} in {text!r}; expected {_DIST_FORMS}")


@dataclass(frozen=True)
class Variation:
    """``key`` (dotted scenario path) drawn from ``dist`` in every member."""

    key: str
    dist: Distribution

    @property
    def path(self) -> tuple[str | int, ...]:
        return tuple(int(p) if p.isdigit() else p for p in self.key.split("."))


_KEY_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*(\.([A-Za-z_][A-Za-z0-9_]*|[0-9]+))*$")


def parse_vary(spec: str) -> Variation:
    """Parse one ``--vary KEY=DISTRIBUTION``."""
    key, sep, dist = spec.partition("=")
    key = key.strip()
    if not sep or not key or not dist.strip():
        raise CampaignError(f"bad --vary {spec!r}; expected KEY=DISTRIBUTION, e.g. "
                            f"sensors.imu.gyro.arw_deg_rt_h=normal(0.15,0.02)")
    if not _KEY_RE.match(key):
        raise CampaignError(f"bad --vary key {key!r}: a dotted scenario path such as sensors.imu.rate_hz")
    return Variation(key, parse_distribution(dist))


# -- scenario data plumbing -------------------------------------------------------------------------
def _check_key(dumped: Any, path: tuple[str | int, ...], key: str) -> None:
    import difflib

    node = dumped
    for i, part in enumerate(path):
        where = ".".join(str(p) for p in path[:i]) or "the scenario"
        if isinstance(node, dict):
            if part not in node:
                close = difflib.get_close_matches(str(part), [str(k) for k in node], n=1, cutoff=0.6)
                hint = f"; did you mean {close[0]!r}?" if close else f"; keys there: {', '.join(map(str, node))}"
                raise CampaignError(f"--vary {key}: {where} has no key {part!r}{hint}")
        elif isinstance(node, (list, tuple)):
            if not isinstance(part, int) or not 0 <= part < len(node):
                raise CampaignError(f"--vary {key}: {where} is a list of {len(node)} items; {part!r} is not an index")
        else:
            raise CampaignError(f"--vary {key}: {where} is a value, not a section")
        node = node[part]
    if isinstance(node, (dict, list)) and node:
        raise CampaignError(f"--vary {key}: that is a section, not a value")


def _set_path(data: dict[str, Any], path: tuple[str | int, ...], value: Any, key: str) -> None:
    node: Any = data
    for part in path[:-1]:
        if isinstance(node, dict):
            if node.get(part) is None:
                node[part] = {}
            node = node[part]
        elif isinstance(node, list) and isinstance(part, int) and part < len(node):
            node = node[part]
        else:
            raise CampaignError(f"--vary {key}: cannot reach {part!r} in the scenario file's data")
    last = path[-1]
    if isinstance(node, dict):  # noqa: SIM114 - one branch per container type: a list takes an int index only
        node[last] = value
    elif isinstance(node, list) and isinstance(last, int) and last < len(node):
        node[last] = value
    else:
        raise CampaignError(f"--vary {key}: cannot set {last!r} in the scenario file's data")


def apply_variations(data: dict[str, Any], values: dict[str, Any]) -> dict[str, Any]:
    """A deep copy of scenario ``data`` with ``values`` (dotted key -> value) written in."""
    import copy

    out = copy.deepcopy(data)
    for key, v in values.items():
        _set_path(out, tuple(int(p) if p.isdigit() else p for p in key.split(".")), v, key)
    return out


# -- the configuration ---------------------------------------------------------------------------
@dataclass
class CampaignConfig:
    """What to run: scenario file, member count, variations, cluster, output directory."""

    scenario: Path
    runs: int
    variations: list[Variation] = field(default_factory=list)
    seed: int | None = None
    scheduler: str | None = None
    workers: int = 2
    out_dir: Path | None = None
    keep_all: bool = False
    plots: bool = True
    #: serve the Dask dashboard of the campaign's own cluster (off by default; docs/distributed.md "Security")
    dashboard: bool = False
    #: the filter-consistency check (NEES / NIS with chi-square bounds, :mod:`.consistency`): consistency.json
    consistency: bool = False
    #: explicit run seeds of the members (``--seeds``; then ``runs`` = their number), else derived from ``seed``
    seeds: list[int] | None = None
    #: start of the consistency evaluation, s (None: the scenario's consistency: expectation, else 0)
    consistency_after_s: float | None = None
    #: the world drawn per member from this envelope preset (``--envelope``; docs/sensors.md "The envelope"), only
    #: ``envelope_groups`` of it when given
    envelope: str | None = None
    envelope_groups: list[str] | None = None
    #: the state groups / measurement types that decide the consistency check (None: the scenario's expectation,
    #: else the defaults; the others are shown as informative)
    consistency_groups: list[str] | None = None
    consistency_measurements: list[str] | None = None
    #: ``--set dotted.key=value`` overrides applied to every member before the ``--vary`` draws
    overrides: list[str] = field(default_factory=list)


def load_campaign_scenario(path: Path, overrides: Sequence[str] = ()) -> tuple[dict[str, Any], Any, str, str]:
    """``(data, validated scenario, source name, base directory)`` of a campaign's scenario file, with the
    ``--set dotted.key=value`` ``overrides`` applied to every member (the same rules as ``psns-hil run --set``)."""
    from ...scenario.loader import apply_overrides, load_yaml_with_marks, read_scenario_text, scenario_from_text

    # one bounded read (at most MAX_SCENARIO_BYTES, as every scenario), then every problem with file:line:column
    text = read_scenario_text(Path(path), str(path))
    scn = scenario_from_text(text, str(path), Path(path).resolve().parent, tuple(overrides))
    data, marks = load_yaml_with_marks(text, str(path))
    if overrides:
        apply_overrides(data, tuple(overrides), marks)
    return data, scn, str(path), str(Path(path).resolve().parent)


def validate_variations(data: dict[str, Any], scn: Any, variations: Sequence[Variation], source: str,
                        base_dir: str | None) -> None:
    """Check every key exists and every representative value passes the schema (before dispatch)."""
    from ...errors import ScenarioError
    from ...scenario.loader import validate_scenario_data

    dumped = scn.model_dump(mode="python")
    seen = set()
    for v in variations:
        if v.key in seen:
            raise CampaignError(f"--vary {v.key} is given twice")
        seen.add(v.key)
        if v.key == "seed":
            raise CampaignError("--vary seed: member seeds are derived from the campaign seed (use --seed)")
        _check_key(dumped, v.path, v.key)
        for value in v.dist.representatives():
            try:
                validate_scenario_data(apply_variations(data, {v.key: value}), {}, source,
                                       Path(base_dir) if base_dir else None)
            except ScenarioError as exc:
                msgs = "; ".join(f"{i.path}: {i.message}" if i.path else i.message for i in exc.issues)
                raise CampaignError(f"--vary {v.key}={v.dist}: the value {value!r} is not valid there: {msgs}") from exc
            except CampaignError:
                raise
