"""A campaign's result and its files: ``runs.csv``, ``stats.csv``, ``campaign.json``, ``campaign.mcap`` (the
per-member series for Foxglove, :func:`emulator.postrun.mcap_out.write_campaign_mcap`) and the plots
``campaign.png`` (histograms of every error metric) and ``sensitivity.png`` (error against each varied key)."""

from __future__ import annotations

import csv
import json
import shutil
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .stats import NAV_METRICS, PERCENTILES, psns_columns

__all__ = ["CampaignResult", "remove_run_dirs", "write_outputs"]


@dataclass
class CampaignResult:
    """The table, its statistics and where they were written."""

    out_dir: Path
    rows: list[dict[str, Any]]
    stats: dict[str, Any]
    wall_s: float
    runs_per_min: float
    info: dict[str, Any]
    #: the consistency check over the members (``--consistency``), as written to consistency.json
    consistency: dict[str, Any] | None = None

    @property
    def failed(self) -> list[dict[str, Any]]:
        """The members that did not complete (their rows, with ``error``)."""
        return [r for r in self.rows if not r.get("ok")]

    @property
    def all_passed(self) -> bool:
        """Every member completed and passed its expectations."""
        return bool(self.stats["failed"] == 0 and self.stats["passed"] == self.stats["runs"])


def _table_columns(rows: Sequence[dict[str, Any]]) -> tuple[list[str], list[str], list[int]]:
    keys = sorted({k for r in rows for k in r.get("params", {})})
    metric_cols = [f"{m}_{s}" for m in NAV_METRICS for s in ("rms", "max")] + psns_columns(rows)
    exp_idx = sorted({e["index"] for r in rows for e in r.get("expectations", [])})
    return keys, metric_cols, exp_idx


def write_outputs(res: CampaignResult, plots: bool = True) -> None:
    """Write ``runs.csv``, ``stats.csv``, ``campaign.json``, ``campaign.mcap`` and (with ``plots``) the two
    figures."""
    out = res.out_dir
    rows = res.rows
    keys, metric_cols, exp_idx = _table_columns(rows)
    env_keys = list(dict.fromkeys(k for r in rows for k in (r.get("envelope") or {})))  # the envelope's draws
    header = (["index", "seed"] + [f"param:{k}" for k in keys] + [f"envelope:{k}" for k in env_keys]
              + ["ok", "passed"] + metric_cols
              + [f"exp{i}_value" for i in exp_idx] + [f"exp{i}_passed" for i in exp_idx]
              + ["deadline_misses", "cpu_load_pct_max", "nav_frames", "wall_s", "error", "run_dir"])
    with open(out / "runs.csv", "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(header)
        for r in rows:
            ex = {e["index"]: e for e in r.get("expectations", [])}
            w.writerow([r["index"], r["seed"]] + [r["params"].get(k) for k in keys]
                       + [_cell((r.get("envelope") or {}).get(k)) for k in env_keys]
                       + [int(bool(r.get("ok"))), "" if r.get("passed") is None else int(bool(r["passed"]))]
                       + [_cell(r.get(c)) for c in metric_cols]
                       + [_cell(ex[i]["value"]) if i in ex else "" for i in exp_idx]
                       + [("not applied" if ex[i].get("applicable") is False else int(ex[i]["passed"]))
                          if i in ex else "" for i in exp_idx]
                       + [_cell(r.get("deadline_misses")), _cell(r.get("cpu_load_pct_max")),
                          _cell(r.get("nav_frames")), _cell(r.get("wall_s")), r.get("error") or "",
                          r.get("run_dir") or ""])
    stat_cols = ["n", "mean", "sigma", "min"] + [f"p{p}" for p in PERCENTILES] + ["max"]
    with open(out / "stats.csv", "w", newline="", encoding="utf-8") as f:
        w = csv.writer(f)
        w.writerow(["quantity", *stat_cols])
        for name, d in res.stats["metrics"].items():
            w.writerow([name] + [_cell(d[c]) for c in stat_cols])
    doc = {"campaign": res.info, "statistics": res.stats,
           "failures": [{"index": r["index"], "seed": r["seed"], "params": r["params"], "error": r["error"],
                         "traceback": r.get("traceback")} for r in res.failed]}
    (out / "campaign.json").write_text(json.dumps(doc, indent=2, default=str) + "\n", encoding="utf-8")
    from ...postrun.mcap_out import write_campaign_mcap

    write_campaign_mcap(out, rows, res.info, res.consistency, metric_cols)  # the series, beside members' run.mcap
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
