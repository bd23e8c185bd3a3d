"""Running a campaign's members: one member in this process (:func:`run_member`, what a Dask worker calls), all
of them on a Dask cluster (:func:`execute_members`), and the whole campaign (:func:`run_campaign`: plan, dispatch,
collect, summarise, write)."""

from __future__ import annotations

import datetime as _dt
import json
import time
import traceback
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from .outputs import CampaignResult, write_outputs
from .plan import MemberTask, plan_members
from .spec import CampaignConfig, CampaignError, load_campaign_scenario, validate_variations
from .stats import NAV_METRICS, PSNS_METRICS, PSNS_STATS, campaign_statistics

__all__ = ["execute_members", "run_campaign", "run_member", "warm_up"]

#: a member's files that are deleted after the run unless ``keep_all``
_BIG_FILES = ("capture.psnscap", "nav.csv", "truth.csv")


def _flat_summary(s: dict[str, Any]) -> dict[str, Any]:
    row: dict[str, Any] = {}
    for m in NAV_METRICS:
        e = s.get("nav_error", {}).get(m, {})
        row[f"{m}_rms"] = e.get("rms")
        row[f"{m}_max"] = e.get("max")
    psns = s.get("psns") or {}
    for m in PSNS_METRICS:
        e = psns.get(m) or {}
        for st in PSNS_STATS:
            row[f"{m}_{st}"] = e.get(st)
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
        from ...assembly.session import run_scenario
        from ...scenario.loader import validate_scenario_data

        base = Path(task.base_dir) if task.base_dir is not None else None
        scn = validate_scenario_data(task.data, {}, f"{task.source_file} (campaign member {task.index})", base)
        summary = run_scenario(scn, Path(task.run_dir), mode="fast", seed=task.seed)
        row.update(_flat_summary(summary))
        env = summary.get("envelope")
        if env:
            from ...world.envelope import flat_draws

            row["envelope"] = flat_draws(env.get("draws") or {})
        row["expectations"] = [{"index": e["index"], "description": e["description"], "value": e["value"],
                                "passed": bool(e["passed"]), "applicable": e.get("applicable") is not False}
                               for e in summary.get("expectations", [])]
        row["passed"] = bool(summary.get("passed"))
        if task.consistency:
            from .consistency import member_consistency

            row["consistency"] = member_consistency(Path(task.run_dir), summary, task.consistency_after_s)
        row["ok"] = not summary.get("interrupted", False)
        if not row["ok"]:
            row["error"] = "run interrupted"
        if not task.keep_all:
            for name in _BIG_FILES:
                p = Path(task.run_dir) / name
                if p.exists():
                    p.unlink()
        else:  # a kept member opens in Foxglove like a single run (issue 39)
            from ...postrun.mcap_out import write_run_mcap

            write_run_mcap(Path(task.run_dir))
    except BaseException as exc:  # a member's failure is data, never lost
        if isinstance(exc, (KeyboardInterrupt, SystemExit)):
            raise
        row["error"] = f"{type(exc).__name__}: {exc}"
        row["traceback"] = traceback.format_exc()
    row["wall_s"] = time.perf_counter() - t0
    return row


def warm_up() -> bool:
    """Import what a member needs (run on every worker with ``client.run(warm_up)`` before timing)."""
    from ...assembly import session  # noqa: F401
    from ...scenario import loader  # noqa: F401

    return True


# -- on a cluster ---------------------------------------------------------------------------------------
def _dask() -> Any:
    """The ``distributed`` package (it has no type information: used as ``Any``)."""
    try:
        import distributed
    except ImportError as exc:
        raise CampaignError(f"campaigns need dask[distributed]: {exc}") from exc
    return distributed


def _connect(cfg: CampaignConfig) -> tuple[Any, Any]:
    dd = _dask()
    if cfg.scheduler:
        try:
            return dd.Client(cfg.scheduler, timeout="10s"), None
        except (OSError, TimeoutError) as exc:
            raise CampaignError(f"cannot reach the Dask scheduler at {cfg.scheduler}: {exc}") from exc
    if cfg.workers < 1:
        raise CampaignError("--workers must be >= 1")
    return local_cluster(cfg.workers, dashboard=cfg.dashboard)


def local_cluster(workers: int, dashboard: bool = False) -> tuple[Any, Any]:
    """``(client, cluster)``: the campaign's own cluster on 127.0.0.1, secured (docs/distributed.md "Security").

    * TLS with mutual authentication: certificates generated for this cluster only
      (``distributed.security.Security.temporary``), so no other process, local or not, can submit work to it or
      read from it (a plain ``tcp://`` or a certificate-less ``tls://`` client is refused);
    * no dashboard unless ``dashboard``; without it the scheduler's HTTP server (which dask always starts) serves
      no route and listens on a random port of 127.0.0.1 instead of 8787.
    """
    import dask

    dd = _dask()
    from distributed.security import Security

    try:
        sec = Security.temporary()
    except ImportError as exc:
        raise CampaignError(f"the campaign's TLS certificates need the cryptography package: {exc}") from exc
    http: dict[str, Any] = {} if dashboard else {"distributed.scheduler.http.routes": [],
                                                 "distributed.worker.http.routes": []}
    with dask.config.set(http):
        cluster = dd.LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  protocol="tls://", security=sec, worker_dashboard_address=None,
                                  dashboard_address="127.0.0.1:8787" if dashboard else "127.0.0.1:0",
                                  scheduler_kwargs={"dashboard": dashboard})
    return dd.Client(cluster, security=sec), cluster


def execute_members(client: Any, tasks: Sequence[MemberTask],
                    progress: Callable[[dict[str, Any], int, int], None] | None = None) -> list[dict[str, Any]]:
    """Run ``tasks`` on ``client`` (a :class:`distributed.Client`); every task yields one row, in index order."""
    futures = client.map(run_member, list(tasks), pure=False, retries=0)
    index_of = {f.key: t.index for f, t in zip(futures, tasks)}
    task_of = {t.index: t for t in tasks}
    rows: dict[int, dict[str, Any]] = {}
    for fut in _dask().as_completed(futures):
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
    """Plan, dispatch, collect, summarise and write a campaign (see :mod:`emulator.distributed.campaign`).

    ``client`` reuses an existing :class:`distributed.Client` (tests share one cluster); otherwise one is
    made from ``cfg.scheduler`` / ``cfg.workers`` and closed at the end.
    """
    if cfg.runs < 1:
        raise CampaignError("--runs must be >= 1")
    if cfg.seeds is not None and len(cfg.seeds) != cfg.runs:
        raise CampaignError(f"--seeds gives {len(cfg.seeds)} seeds for {cfg.runs} runs")
    data, scn, source, base_dir = load_campaign_scenario(cfg.scenario, cfg.overrides)
    if cfg.envelope is not None:  # every member draws its world from the envelope with its own seed
        data = {**data, "envelope": {"preset": cfg.envelope,
                                     **({"groups": list(cfg.envelope_groups)} if cfg.envelope_groups else {})}}
        scn = _validated(data, source, base_dir)
    validate_variations(data, scn, cfg.variations, source, base_dir)
    seed = scn.seed if cfg.seed is None else int(cfg.seed)
    stamp = _dt.datetime.now(_dt.UTC).strftime("%Y%m%dT%H%M%SZ")
    out = Path(cfg.out_dir) if cfg.out_dir else Path("runs") / f"campaign-{scn.name}-{stamp}"
    out.mkdir(parents=True, exist_ok=True)
    spec = consistency_spec(scn, cfg.consistency_groups, cfg.consistency_measurements) if cfg.consistency else None
    if spec is not None and cfg.consistency_after_s is not None:
        spec["after_s"] = cfg.consistency_after_s
    tasks = plan_members(data, cfg.runs, seed, cfg.variations, out, source, base_dir, cfg.keep_all,
                         consistency=cfg.consistency, consistency_after_s=spec["after_s"] if spec else 0.0,
                         seeds=cfg.seeds)
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
        "overrides": list(cfg.overrides),
        "scheduler": cfg.scheduler or f"LocalCluster({cfg.workers} processes, 127.0.0.1)",
        "workers": n_workers, "wall_s": wall, "runs_per_min": 60.0 * len(rows) / wall if wall > 0 else None,
        "started_utc": stamp,
        "envelope": {"preset": cfg.envelope, "groups": cfg.envelope_groups} if cfg.envelope is not None else None,
    }
    result = CampaignResult(out, rows, stats, wall, info["runs_per_min"] or 0.0, info)
    if spec is not None:
        from .consistency import campaign_consistency

        result.consistency = campaign_consistency([r.get("consistency") or {} for r in rows if r.get("ok")],
                                                  spec["confidence"], spec["groups"], spec["measurements"],
                                                  spec["upper_only"])
        result.consistency["scenario"] = scn.name
        (out / "consistency.json").write_text(json.dumps(result.consistency, indent=1) + "\n", encoding="utf-8")
    write_outputs(result, cfg.plots)
    return result


def _validated(data: dict[str, Any], source: str, base_dir: str | None) -> Any:
    from ...errors import ScenarioError
    from ...scenario.loader import validate_scenario_data

    try:
        return validate_scenario_data(data, {}, source, Path(base_dir) if base_dir is not None else None)
    except ScenarioError as exc:
        raise CampaignError(f"--envelope: {exc}") from exc


def consistency_spec(scn: Any, groups: list[str] | None = None, measurements: list[str] | None = None
                     ) -> dict[str, Any]:
    """What the consistency check evaluates and which checks decide it: the groups and measurement types the command
    line asks for (``groups`` / ``measurements``), else the scenario's ``consistency:`` expectation's, else the
    default groups (attitude, velocity, position); ``heading`` is added wherever the scenario has a heading source
    (:func:`emulator.scenario.consistency_schema.asked_groups`). Confidence and start time from the expectation (95 %,
    0 s without one). Everything else is evaluated too and shown as informative."""
    from ...scenario.consistency_schema import asked_groups
    from ...scenario.cross_checks import has_heading_source

    heading = has_heading_source(scn)
    for e in getattr(scn, "expectations", []) or []:
        c = getattr(e, "consistency", None)
        if c is not None:
            return {"groups": asked_groups(groups or c.groups, heading, c.include_heading),
                    "measurements": list(c.measurements if measurements is None else measurements),
                    "confidence": c.confidence, "after_s": c.after_s, "upper_only": list(c.upper_only)}
    return {"groups": asked_groups(groups, heading), "measurements": list(measurements or []),
            "confidence": 0.95, "after_s": 0.0, "upper_only": []}
