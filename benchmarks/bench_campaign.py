"""Campaign throughput on a Dask LocalCluster: members per minute with 1 and with 2 worker processes.

The same 8 members (the quickstart scenario cut to 20 s simulated, seeds derived from campaign seed 1)
run on a 1-worker and on a 2-worker LocalCluster (processes, 127.0.0.1). Cluster start-up is measured
separately and excluded from the throughput; every worker imports the emulator before the clock starts.
On a 2-core machine the ideal ratio is 2; other load on the machine lowers it.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
RUNS = 8
DURATION_S = 20.0


def _scenario(d: Path) -> Path:
    data = yaml.safe_load((ROOT / "scenarios" / "quickstart.yaml").read_text())
    data.update(name="bench_campaign", duration_s=DURATION_S, motion=[{"static": {"duration_s": DURATION_S}}])
    data["expectations"] = [e for e in data["expectations"] if "nav_error" not in e]
    p = d / "bench_campaign.yaml"
    p.write_text(yaml.safe_dump(data, sort_keys=False))
    return p


def _measure(workers: int, scenario: Path, out: Path) -> tuple[float, float, int]:
    from distributed import Client, LocalCluster

    from emulator.distributed.campaign import CampaignConfig, run_campaign, warm_up

    t0 = time.perf_counter()
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                           dashboard_address=None, worker_dashboard_address=None)
    client = Client(cluster)
    client.run(warm_up)
    startup = time.perf_counter() - t0
    try:
        res = run_campaign(CampaignConfig(scenario, runs=RUNS, seed=1, out_dir=out, plots=False), client=client)
    finally:
        client.close()
        cluster.close()
    return res.runs_per_min, startup, res.stats["failed"]


def run() -> list[dict]:
    with tempfile.TemporaryDirectory() as d:
        scn = _scenario(Path(d))
        one, start1, f1 = _measure(1, scn, Path(d) / "w1")
        two, start2, f2 = _measure(2, scn, Path(d) / "w2")
    note = f"{RUNS} members x {DURATION_S:g} s simulated; failed members: {f1} / {f2}"
    return [
        {"name": "campaign runs/min, LocalCluster 1 worker", "value": one, "unit": "runs/min", "baseline": None,
         "ratio": None, "note": note},
        {"name": "campaign runs/min, LocalCluster 2 workers", "value": two, "unit": "runs/min", "baseline": one,
         "ratio": two / one if one else None, "note": "baseline = 1 worker; ideal ratio 2 on 2 cores"},
        {"name": "LocalCluster start-up (2 workers, incl. imports)", "value": start2, "unit": "s",
         "baseline": start1, "ratio": start2 / start1 if start1 else None, "note": "baseline = 1 worker"},
    ]


if __name__ == "__main__":
    for r in run():
        print(r)
