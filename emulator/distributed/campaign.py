"""Monte-Carlo campaigns: many runs of one scenario with derived seeds and varied parameters, on Dask.

``psns-hil campaign SCENARIO --runs N [--vary KEY=DISTRIBUTION ...] [--scheduler tcp://HOST:PORT]
[--workers W] [--out DIR] [--seed S]`` runs ``N`` members of the scenario in fast mode on a Dask
distributed cluster (a :class:`distributed.LocalCluster` of ``W`` worker processes on 127.0.0.1
by default, or an existing scheduler), collects every member's summary into one table and
computes statistics.

Determinism. The campaign seed (``--seed``, default the scenario's ``seed``) is the root of a
:class:`numpy.random.SeedSequence`; member ``i`` gets child ``i`` of it, split into the run's
seed (the scenario ``seed`` of that run: every sensor error draw) and the generator that samples
the member's parameter values. Members are independent of scheduling order and worker count:
the same campaign seed gives the same table on one worker or twenty.

Variations. ``KEY`` is a dotted path in the scenario (``sensors.imu.gyro.arw_deg_rt_h``;
list items by index, ``motion.0.static.duration_s``) that must exist in the validated scenario
(defaults included). ``DISTRIBUTION`` is one of::

    normal(MEAN, SIGMA)      Gaussian, SIGMA >= 0
    uniform(LOW, HIGH)       uniform on [LOW, HIGH), LOW < HIGH
    choice(A, B, ...)        one of the listed values with equal probability (YAML scalars:
                             numbers, true/false, words)

The value is written into the scenario data and the member's scenario is validated like a file
(a drawn value the schema rejects makes that member fail with the schema's message). Before
anything is dispatched, every variation is checked on a representative value (the mean, the
interval's middle, each choice), so a misspelt key or a wrong type is an error at once.

Failures. A member that raises (bad draw, firmware error, a worker that died) is a row with
``ok = false`` and its error text; it is counted and listed, never dropped. Statistics are over
the members that completed.

Outputs in ``--out`` (default ``runs/campaign-<scenario>-<UTC time>``):

``runs.csv``        one row per member: index, seed, drawn parameters, ok, error, passed, the
                    summary's nav errors (``<metric>_rms``, ``<metric>_max``), expectation results,
                    DSP load and deadline misses, wall time
``stats.csv``       per numeric column: n, mean, sigma (ddof 1), min, p5, p50, p95, max
``campaign.json``   configuration, statistics, expectation pass rates, failures, throughput
``campaign.png``    histograms of every error metric; ``sensitivity.png`` error vs each varied key
``runs/NNNN/``      each member's run directory (summary.json, events.jsonl; ``--keep-all`` keeps
                    the captures, nav.csv and truth.csv too)
"""

from __future__ import annotations

import ast
import csv
import datetime as _dt
import json
import math
import re
import shutil
import time
import traceback
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Sequence

import numpy as np

from ..errors import EmulatorError

__all__ = [
    "CampaignError",
    "Distribution",
    "Variation",
    "parse_distribution",
    "parse_vary",
    "MemberTask",
    "CampaignConfig",
    "CampaignResult",
    "plan_members",
    "run_member",
    "run_campaign",
    "campaign_statistics",
    "NAV_METRICS",
]

NAV_METRICS = ("attitude_deg", "heading_deg", "position_m", "velocity_mps")
_BIG_FILES = ("capture.psnscap", "nav.csv", "truth.csv")


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
    if isinstance(node, dict):
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


# -- members -------------------------------------------------------------------------------------------
@dataclass
class MemberTask:
    """Everything a worker needs for one member (picklable; no shared file system assumed)."""

    index: int
    seed: int
    params: dict[str, Any]
    data: dict[str, Any]
    source_file: str
    base_dir: str | None
    run_dir: str
    keep_all: bool = False


def _seed_of(ss: np.random.SeedSequence) -> int:
    return int(ss.generate_state(1, dtype=np.uint32)[0])


def plan_members(data: dict[str, Any], runs: int, campaign_seed: int, variations: Sequence[Variation],
                 out_dir: Path, source_file: str = "<scenario>", base_dir: str | None = None,
                 keep_all: bool = False) -> list[MemberTask]:
    """The members of a campaign: seeds and drawn parameters (deterministic in ``campaign_seed``)."""
    root = np.random.SeedSequence(campaign_seed)
    tasks = []
    for i, child in enumerate(root.spawn(runs)):
        run_ss, vary_ss = child.spawn(2)
        rng = np.random.default_rng(vary_ss)
        params = {v.key: v.dist.sample(rng) for v in variations}
        member = apply_variations(data, params)
        member["seed"] = _seed_of(run_ss)
        tasks.append(MemberTask(i, member["seed"], params, member, source_file, base_dir,
                                str(Path(out_dir) / "runs" / f"{i:04d}"), keep_all))
    return tasks


def _flat_summary(s: dict[str, Any]) -> dict[str, Any]:
    row: dict[str, Any] = {}
    for m in NAV_METRICS:
        e = s.get("nav_error", {}).get(m, {})
        row[f"{m}_rms"] = e.get("rms")
        row[f"{m}_max"] = e.get("max")
    dsp = s.get("dsp", {})
    row["deadline_misses"] = dsp.get("deadline_misses")
    row["cpu_load_pct_max"] = dsp.get("cpu_load_pct_max")
    row["nav_frames"] = s.get("nav_frames")
    row["sim_duration_s"] = s.get("sim_duration_s")
    return row


def run_member(task: MemberTask) -> dict[str, Any]:
    """Run one member (on a Dask worker or in-process); never raises: errors become the row's ``error``."""
    t0 = time.perf_counter()
    row: dict[str, Any] = {"index": task.index, "seed": task.seed, "params": dict(task.params), "ok": False,
                           "error": None, "traceback": None, "passed": None, "expectations": [],
                           "run_dir": task.run_dir}
    try:
        from ..assembly.runner import run_scenario
        from ..scenario.loader import validate_scenario_data

        base = Path(task.base_dir) if task.base_dir is not None else None
        scn = validate_scenario_data(task.data, {}, f"{task.source_file} (campaign member {task.index})", base)
        summary = run_scenario(scn, Path(task.run_dir), mode="fast", seed=task.seed)
        row.update(_flat_summary(summary))
        row["expectations"] = [{"index": e["index"], "description": e["description"], "value": e["value"],
                                "passed": bool(e["passed"])} for e in summary.get("expectations", [])]
        row["passed"] = bool(summary.get("passed"))
        row["ok"] = not summary.get("interrupted", False)
        if not row["ok"]:
            row["error"] = "run interrupted"
        if not task.keep_all:
            for name in _BIG_FILES:
                p = Path(task.run_dir) / name
                if p.exists():
                    p.unlink()
    except BaseException as exc:  # noqa: BLE001 - a member's failure is data, never lost
        if isinstance(exc, (KeyboardInterrupt, SystemExit)):
            raise
        row["error"] = f"{type(exc).__name__}: {exc}"
        row["traceback"] = traceback.format_exc()
    row["wall_s"] = time.perf_counter() - t0
    return row


def warm_up() -> bool:
    """Import what a member needs (run on every worker with ``client.run(warm_up)`` before timing)."""
    from ..assembly import runner  # noqa: F401
    from ..scenario import loader  # noqa: F401

    return True


# -- statistics -----------------------------------------------------------------------------------------
_PCTS = (5, 50, 95)


def _describe(values: Sequence[float]) -> dict[str, float | int | None]:
    a = np.asarray([v for v in values if v is not None and math.isfinite(v)], dtype=float)
    if a.size == 0:
        return {"n": 0, "mean": None, "sigma": None, "min": None, **{f"p{p}": None for p in _PCTS}, "max": None}
    pct = np.percentile(a, _PCTS)
    return {"n": int(a.size), "mean": float(a.mean()), "sigma": float(a.std(ddof=1)) if a.size > 1 else 0.0,
            "min": float(a.min()), **{f"p{p}": float(v) for p, v in zip(_PCTS, pct)}, "max": float(a.max())}


def campaign_statistics(rows: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Statistics over the completed members of a campaign (see module docstring)."""
    ok = [r for r in rows if r.get("ok")]
    cols = [f"{m}_{s}" for m in NAV_METRICS for s in ("rms", "max")]
    cols += ["deadline_misses", "cpu_load_pct_max", "nav_frames", "wall_s"]
    keys = sorted({k for r in rows for k in r.get("params", {})})
    stats = {c: _describe([r.get(c) for r in ok]) for c in cols}
    for k in keys:
        vals = [r["params"][k] for r in rows if isinstance(r["params"].get(k), (int, float))
                and not isinstance(r["params"].get(k), bool)]
        if vals:
            stats[f"param:{k}"] = _describe(vals)
    exp: dict[int, dict[str, Any]] = {}
    for r in ok:
        for e in r.get("expectations", []):
            d = exp.setdefault(e["index"], {"index": e["index"], "description": e["description"], "runs": 0,
                                            "passed": 0})
            d["runs"] += 1
            d["passed"] += int(bool(e["passed"]))
    for d in exp.values():
        d["pass_rate"] = d["passed"] / d["runs"] if d["runs"] else None
    n_pass = sum(1 for r in ok if r.get("passed"))
    return {
        "runs": len(rows),
        "completed": len(ok),
        "failed": len(rows) - len(ok),
        "passed": n_pass,
        "pass_rate": n_pass / len(ok) if ok else None,
        "pass_rate_all_runs": n_pass / len(rows) if rows else None,
        "metrics": stats,
        "expectations": [exp[i] for i in sorted(exp)],
    }


# -- running --------------------------------------------------------------------------------------------
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


@dataclass
class CampaignResult:
    """The table, its statistics and where they were written."""

    out_dir: Path
    rows: list[dict[str, Any]]
    stats: dict[str, Any]
    wall_s: float
    runs_per_min: float
    info: dict[str, Any]

    @property
    def failed(self) -> list[dict[str, Any]]:
        return [r for r in self.rows if not r.get("ok")]


def _load_campaign_scenario(path: Path) -> tuple[dict[str, Any], Any, str, str]:
    from ..scenario.loader import load_scenario, load_yaml_with_marks

    scn = load_scenario(path)  # every problem of the file itself, with file:line:column
    data, _marks = load_yaml_with_marks(Path(path).read_text(encoding="utf-8"), str(path))
    return data, scn, str(path), str(Path(path).resolve().parent)


def validate_variations(data: dict[str, Any], scn: Any, variations: Sequence[Variation], source: str,
                        base_dir: str | None) -> None:
    """Check every key exists and every representative value passes the schema (before dispatch)."""
    from ..errors import ScenarioError
    from ..scenario.loader import validate_scenario_data

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


def _connect(cfg: CampaignConfig) -> tuple[Any, Any]:
    try:
        from distributed import Client, LocalCluster
    except ImportError as exc:
        raise CampaignError(f"campaigns need dask[distributed]: {exc}") from exc
    if cfg.scheduler:
        try:
            return Client(cfg.scheduler, timeout="10s"), None
        except (OSError, TimeoutError) as exc:
            raise CampaignError(f"cannot reach the Dask scheduler at {cfg.scheduler}: {exc}") from exc
    if cfg.workers < 1:
        raise CampaignError("--workers must be >= 1")
    cluster = LocalCluster(n_workers=cfg.workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                           dashboard_address=None, worker_dashboard_address=None)
    return Client(cluster), cluster


def execute_members(client: Any, tasks: Sequence[MemberTask],
                    progress: Callable[[dict[str, Any], int, int], None] | None = None) -> list[dict[str, Any]]:
    """Run ``tasks`` on ``client`` (a :class:`distributed.Client`); every task yields one row, in index order."""
    from distributed import as_completed

    futures = client.map(run_member, list(tasks), pure=False, retries=0)
    index_of = {f.key: t.index for f, t in zip(futures, tasks)}
    task_of = {t.index: t for t in tasks}
    rows: dict[int, dict[str, Any]] = {}
    for fut in as_completed(futures):
        i = index_of[fut.key]
        if fut.status == "finished":
            row = fut.result()
        else:  # the task itself failed outside run_member's guard (worker died, unpicklable result...)
            exc = fut.exception()
            t = task_of[i]
            row = {"index": i, "seed": t.seed, "params": dict(t.params), "ok": False,
                   "error": f"{type(exc).__name__}: {exc}", "traceback": None, "passed": None,
                   "expectations": [], "run_dir": t.run_dir, "wall_s": None}
        rows[i] = row
        fut.release()
        if progress is not None:
            progress(row, len(rows), len(tasks))
    return [rows[t.index] for t in tasks]


def run_campaign(cfg: CampaignConfig, progress: Callable[[dict[str, Any], int, int], None] | None = None,
                 client: Any = None) -> CampaignResult:
    """Plan, dispatch, collect, summarise and write a campaign (see module docstring).

    ``client`` reuses an existing :class:`distributed.Client` (tests share one cluster); otherwise one is
    made from ``cfg.scheduler`` / ``cfg.workers`` and closed at the end.
    """
    if cfg.runs < 1:
        raise CampaignError("--runs must be >= 1")
    data, scn, source, base_dir = _load_campaign_scenario(cfg.scenario)
    validate_variations(data, scn, cfg.variations, source, base_dir)
    seed = scn.seed if cfg.seed is None else int(cfg.seed)
    stamp = _dt.datetime.now(_dt.timezone.utc).strftime("%Y%m%dT%H%M%SZ")
    out = Path(cfg.out_dir) if cfg.out_dir else Path("runs") / f"campaign-{scn.name}-{stamp}"
    out.mkdir(parents=True, exist_ok=True)
    tasks = plan_members(data, cfg.runs, seed, cfg.variations, out, source, base_dir, cfg.keep_all)
    own = client is None
    cluster = None
    if own:
        client, cluster = _connect(cfg)
    try:
        n_workers = len(client.scheduler_info().get("workers", {}))
        t0 = time.perf_counter()
        rows = execute_members(client, tasks, progress)
        wall = time.perf_counter() - t0
    finally:
        if own:
            client.close()
            if cluster is not None:
                cluster.close()
    stats = campaign_statistics(rows)
    info = {
        "scenario": scn.name, "scenario_file": source, "campaign_seed": seed, "runs": cfg.runs,
        "variations": [{"key": v.key, "distribution": str(v.dist)} for v in cfg.variations],
        "scheduler": cfg.scheduler or f"LocalCluster({cfg.workers} processes, 127.0.0.1)",
        "workers": n_workers, "wall_s": wall, "runs_per_min": 60.0 * len(rows) / wall if wall > 0 else None,
        "started_utc": stamp,
    }
    result = CampaignResult(out, rows, stats, wall, info["runs_per_min"] or 0.0, info)
    write_outputs(result, cfg.plots)
    return result


# -- outputs ----------------------------------------------------------------------------------------------
def _table_columns(rows: Sequence[dict[str, Any]]) -> tuple[list[str], list[str], list[int]]:
    keys = sorted({k for r in rows for k in r.get("params", {})})
    metric_cols = [f"{m}_{s}" for m in NAV_METRICS for s in ("rms", "max")]
    exp_idx = sorted({e["index"] for r in rows for e in r.get("expectations", [])})
    return keys, metric_cols, exp_idx


def write_outputs(res: CampaignResult, plots: bool = True) -> None:
    out = res.out_dir
    rows = res.rows
    keys, metric_cols, exp_idx = _table_columns(rows)
    header = (["index", "seed"] + [f"param:{k}" for k in keys] + ["ok", "passed"] + metric_cols
              + [f"exp{i}_value" for i in exp_idx] + [f"exp{i}_passed" for i in exp_idx]
              + ["deadline_misses", "cpu_load_pct_max", "nav_frames", "wall_s", "error", "run_dir"])
    with open(out / "runs.csv", "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(header)
        for r in rows:
            ex = {e["index"]: e for e in r.get("expectations", [])}
            w.writerow([r["index"], r["seed"]] + [r["params"].get(k) for k in keys]
                       + [int(bool(r.get("ok"))), "" if r.get("passed") is None else int(bool(r["passed"]))]
                       + [_cell(r.get(c)) for c in metric_cols]
                       + [_cell(ex[i]["value"]) if i in ex else "" for i in exp_idx]
                       + [int(ex[i]["passed"]) if i in ex else "" for i in exp_idx]
                       + [_cell(r.get("deadline_misses")), _cell(r.get("cpu_load_pct_max")),
                          _cell(r.get("nav_frames")), _cell(r.get("wall_s")), r.get("error") or "",
                          r.get("run_dir") or ""])
    stat_cols = ["n", "mean", "sigma", "min"] + [f"p{p}" for p in _PCTS] + ["max"]
    with open(out / "stats.csv", "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(["quantity"] + stat_cols)
        for name, d in res.stats["metrics"].items():
            w.writerow([name] + [_cell(d[c]) for c in stat_cols])
    doc = {"campaign": res.info, "statistics": res.stats,
           "failures": [{"index": r["index"], "seed": r["seed"], "params": r["params"], "error": r["error"],
                         "traceback": r.get("traceback")} for r in res.failed]}
    (out / "campaign.json").write_text(json.dumps(doc, indent=2, default=str) + "\n", encoding="utf-8")
    if plots:
        _plots(res, keys)


def _cell(v: Any) -> Any:
    if v is None:
        return ""
    if isinstance(v, float):
        return repr(v)
    return v


def _plots(res: CampaignResult, keys: list[str]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = [r for r in res.rows if r.get("ok")]
    if not ok:
        return
    fig, axes = plt.subplots(2, 4, figsize=(14, 6), constrained_layout=True)
    for ax, (m, s) in zip(axes.flat, [(m, s) for s in ("rms", "max") for m in NAV_METRICS]):
        vals = [r[f"{m}_{s}"] for r in ok if r.get(f"{m}_{s}") is not None]
        ax.hist(vals, bins=max(5, min(30, len(vals) // 2 or 1)), color="#4477aa")
        st = res.stats["metrics"][f"{m}_{s}"]
        if st["mean"] is not None:
            ax.axvline(st["mean"], color="k", lw=1)
            ax.axvline(st["p95"], color="#cc6677", lw=1, ls="--")
        ax.set_title(f"{m} {s}")
    n_fail = len(res.rows) - len(ok)
    fig.suptitle(f"{res.info['scenario']}: {len(res.rows)} runs, {n_fail} failed, pass rate "
                 f"{(res.stats['pass_rate'] or 0) * 100:.0f} % (mean solid, p95 dashed)")
    fig.savefig(res.out_dir / "campaign.png", dpi=90)
    plt.close(fig)
    num_keys = [k for k in keys if all(isinstance(r["params"].get(k), (int, float)) for r in ok)]
    if num_keys:
        fig, axes = plt.subplots(len(num_keys), len(NAV_METRICS), figsize=(14, 3 * len(num_keys)),
                                 squeeze=False, constrained_layout=True)
        for i, k in enumerate(num_keys):
            for j, m in enumerate(NAV_METRICS):
                ax = axes[i][j]
                ax.scatter([r["params"][k] for r in ok], [r.get(f"{m}_rms") for r in ok], s=10)
                ax.set_xlabel(k, fontsize=8)
                ax.set_ylabel(f"{m} rms", fontsize=8)
        fig.savefig(res.out_dir / "sensitivity.png", dpi=90)
        plt.close(fig)


def remove_run_dirs(out_dir: Path) -> None:
    """Delete the per-member run directories of a campaign (keeps the table and statistics)."""
    shutil.rmtree(Path(out_dir) / "runs", ignore_errors=True)


# -- command line -------------------------------------------------------------------------------------------
def add_cli_parser(sub: Any) -> Any:
    """Register ``psns-hil campaign`` on an argparse sub-parser collection."""
    c = sub.add_parser("campaign", help="Monte-Carlo campaign of a scenario on a Dask cluster",
                       description="Run N members of SCENARIO (fast mode) with seeds derived from the campaign "
                                   "seed and parameters drawn per --vary; write runs.csv, stats.csv, "
                                   "campaign.json and plots.")
    c.add_argument("scenario", help="scenario YAML file")
    c.add_argument("--runs", type=int, required=True, help="number of members")
    c.add_argument("--vary", action="append", default=[], metavar="KEY=DISTRIBUTION",
                   help="e.g. sensors.imu.gyro.arw_deg_rt_h=normal(0.15,0.02); uniform(a,b); choice(a,b,c)")
    c.add_argument("--seed", type=int, default=None, help="campaign seed (default: the scenario's seed)")
    c.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                   help="a running Dask scheduler (default: a LocalCluster on 127.0.0.1)")
    c.add_argument("--workers", type=int, default=2, help="LocalCluster worker processes (default 2)")
    c.add_argument("--out", default=None, help="output directory (default runs/campaign-<scenario>-<UTC time>)")
    c.add_argument("--keep-all", action="store_true", help="keep every member's captures, nav.csv and truth.csv")
    c.add_argument("--no-plots", action="store_true", help="skip campaign.png / sensitivity.png")
    c.add_argument("--json", action="store_true", help="print campaign.json's statistics as JSON")
    c.add_argument("--quiet", action="store_true", help="no progress bar")
    return c


def cli_main(args: Any) -> int:
    """``psns-hil campaign``: 0 every member completed and passed, 1 some failed or missed an expectation."""
    from rich.console import Console
    from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
    from rich.table import Table

    if args.workers < 1:
        raise CampaignError("--workers must be >= 1")
    cfg = CampaignConfig(scenario=Path(args.scenario), runs=args.runs,
                         variations=[parse_vary(v) for v in args.vary], seed=args.seed, scheduler=args.scheduler,
                         workers=args.workers, out_dir=Path(args.out) if args.out else None,
                         keep_all=args.keep_all, plots=not args.no_plots)
    console = Console(highlight=False)
    if not console.is_terminal:  # a log or a pipe: wide enough for the statistics table
        console = Console(highlight=False, width=140)
    prog = Progress(TextColumn("members"), BarColumn(), MofNCompleteColumn(), TextColumn("{task.fields[failed]} failed"),
                    TimeElapsedColumn(), console=console, transient=True,
                    disable=args.quiet or args.json or not console.is_terminal)
    task = prog.add_task("runs", total=cfg.runs, failed=0)
    failed = [0]

    def on_row(row: dict[str, Any], done: int, total: int) -> None:
        failed[0] += 0 if row.get("ok") else 1
        prog.update(task, completed=done, failed=failed[0])

    with prog:
        res = run_campaign(cfg, progress=on_row)
    if args.json:
        print(json.dumps({"campaign": res.info, "statistics": res.stats}, indent=2, default=str))
    else:
        st = res.stats
        console.print(f"campaign {res.info['scenario']}: {st['runs']} runs on {res.info['workers']} workers "
                      f"({res.info['scheduler']}) in {res.wall_s:.1f} s = {res.runs_per_min:.1f} runs/min -> {res.out_dir}")
        t = Table(title="error statistics over completed runs", title_justify="left")
        for col in ("quantity", "n", "mean", "sigma", "p5", "p50", "p95", "max"):
            t.add_column(col, justify="left" if col == "quantity" else "right", no_wrap=True)
        for name, d in st["metrics"].items():
            if name.endswith("_rms") or name.endswith("_max") or name.startswith("param:"):
                t.add_row(name, str(d["n"]), *("-" if d[k] is None else f"{d[k]:.4g}"
                                              for k in ("mean", "sigma", "p5", "p50", "p95", "max")))
        console.print(t)
        if st["expectations"]:
            e = Table(title="expectations", title_justify="left")
            for col in ("#", "check", "passed", "pass rate"):
                e.add_column(col)
            for d in st["expectations"]:
                e.add_row(str(d["index"]), d["description"], f"{d['passed']}/{d['runs']}",
                          f"{100 * d['pass_rate']:.1f} %" if d["pass_rate"] is not None else "-")
            console.print(e)
        console.print(f"completed {st['completed']}/{st['runs']}, passed {st['passed']}"
                      + (f" ({100 * st['pass_rate']:.1f} % of completed)" if st["pass_rate"] is not None else ""))
        for r in res.failed:
            console.print(f"[bold red]member {r['index']} (seed {r['seed']}) failed:[/] {r['error']}", soft_wrap=True)
    return 0 if st_ok(res) else 1


def st_ok(res: CampaignResult) -> bool:
    return res.stats["failed"] == 0 and res.stats["passed"] == res.stats["runs"]
