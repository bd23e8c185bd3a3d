"""Monte-Carlo campaigns on Dask: distributions, planning, a 20-run LocalCluster campaign whose statistics
agree with the members' own summaries, failed members reported, scheduling-independent results."""

from __future__ import annotations

import asyncio
import csv
import json
import statistics
from pathlib import Path

import numpy as np
import pytest

from emulator.distributed.campaign import (
    NAV_METRICS,
    CampaignConfig,
    CampaignError,
    campaign_statistics,
    load_campaign_scenario,
    parse_distribution,
    parse_vary,
    plan_members,
    run_campaign,
    run_member,
    validate_variations,
)

from .conftest import write_short_scenario

distributed = pytest.importorskip("distributed")


@pytest.fixture(scope="module")
def dask_client():
    """One 2-process LocalCluster on 127.0.0.1 for the whole module (start-up is the slow part)."""
    from distributed import Client, LocalCluster

    cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                           dashboard_address=None, worker_dashboard_address=None)
    client = Client(cluster)
    yield client
    client.close()
    cluster.close()


# -- distributions and --vary -------------------------------------------------------------------------
def test_distributions_parse_and_sample_deterministically():
    rng1, rng2 = np.random.default_rng(1), np.random.default_rng(1)
    d = parse_distribution("normal(0.15, 0.02)")
    assert (d.kind, d.args) == ("normal", (0.15, 0.02))
    xs = [d.sample(rng1) for _ in range(2000)]
    assert xs[:5] == [d.sample(rng2) for _ in range(5)]
    assert np.mean(xs) == pytest.approx(0.15, abs=3 * 0.02 / np.sqrt(2000) * 1.5)
    assert np.std(xs) == pytest.approx(0.02, rel=0.1)
    u = parse_distribution("uniform(-1,3)")
    us = [u.sample(rng1) for _ in range(2000)]
    assert min(us) >= -1 and max(us) < 3 and np.mean(us) == pytest.approx(1.0, abs=0.1)
    c = parse_distribution("choice(base, 2, 2.5, true)")
    assert c.args == ("base", 2, 2.5, True)
    assert set(c.sample(rng1) for _ in range(200)) == {"base", 2, 2.5, True}
    assert str(d) == "normal(0.15, 0.02)"


@pytest.mark.parametrize("text, msg", [
    ("gauss(1,2)", "unknown distribution 'gauss'"),
    ("normal(1)", "normal takes 2 arguments"),
    ("normal(1, -0.1)", "SIGMA must be >= 0"),
    ("normal(a, 1)", "MEAN must be a finite number"),
    ("uniform(2, 1)", "LOW must be < HIGH"),
    ("uniform(1, nan)", "HIGH must be a finite number"),
    ("choice()", "at least one value"),
    ("normal 1 2", "expected normal(MEAN, SIGMA)"),
])
def test_bad_distributions_say_what_is_wrong(text, msg):
    with pytest.raises(CampaignError, match=msg.replace("(", r"\(").replace(")", r"\)")):
        parse_distribution(text)


def test_vary_syntax():
    v = parse_vary("sensors.imu.gyro.arw_deg_rt_h=normal(0.15,0.02)")
    assert v.key == "sensors.imu.gyro.arw_deg_rt_h" and v.path == ("sensors", "imu", "gyro", "arw_deg_rt_h")
    assert parse_vary("motion.0.static.duration_s=uniform(1,2)").path == ("motion", 0, "static", "duration_s")
    for bad in ("sensors.imu", "=normal(1,1)", "a..b=normal(1,1)", "a.b=", "9a=normal(1,1)"):
        with pytest.raises(CampaignError):
            parse_vary(bad)


def _csv_rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="") as f:
        return list(csv.DictReader(f))


def _scenario_and_data(tmp_path, duration_s=3.0):
    p = write_short_scenario(tmp_path / "s.yaml", duration_s, name="camp")
    return (p, *load_campaign_scenario(p))


def test_variation_keys_and_values_are_checked_before_dispatch(tmp_path):
    _p, data, scn, src, base = _scenario_and_data(tmp_path)
    validate_variations(data, scn, [parse_vary("sensors.imu.gyro.arw_deg_rt_h=normal(0.15,0.02)"),
                                    parse_vary("firmware.filter=choice(base)")], src, base)
    with pytest.raises(CampaignError, match="did you mean 'arw_deg_rt_h'"):
        validate_variations(data, scn, [parse_vary("sensors.imu.gyro.arw_deg_rt=normal(1,1)")], src, base)
    with pytest.raises(CampaignError, match="section, not a value"):
        validate_variations(data, scn, [parse_vary("sensors.imu.gyro=normal(1,1)")], src, base)
    with pytest.raises(CampaignError, match="value 'fast' is not valid there"):
        validate_variations(data, scn, [parse_vary("sensors.imu.rate_hz=choice(200, fast)")], src, base)
    with pytest.raises(CampaignError, match=r"not valid there.*greater than 0"):
        validate_variations(data, scn, [parse_vary("duration_s=normal(-5, 1)")], src, base)
    with pytest.raises(CampaignError, match="--seed"):
        validate_variations(data, scn, [parse_vary("seed=choice(1,2)")], src, base)
    with pytest.raises(CampaignError, match="given twice"):
        validate_variations(data, scn, [parse_vary("dsp.clock_hz=choice(3e8)")] * 2, src, base)


def test_plan_is_deterministic_in_the_campaign_seed(tmp_path):
    _p, data, _scn, _src, _base = _scenario_and_data(tmp_path)
    vs = [parse_vary("sensors.imu.gyro.arw_deg_rt_h=normal(0.15,0.02)"), parse_vary("firmware.filter=choice(base)")]
    a = plan_members(data, 8, 7, vs, tmp_path)
    b = plan_members(data, 8, 7, vs, tmp_path)
    c = plan_members(data, 8, 8, vs, tmp_path)
    assert [(t.seed, t.params) for t in a] == [(t.seed, t.params) for t in b]
    assert [t.seed for t in a] != [t.seed for t in c]
    assert len({t.seed for t in a}) == 8
    assert all(t.data["seed"] == t.seed and t.data["sensors"]["imu"]["gyro"]["arw_deg_rt_h"] ==
               t.params["sensors.imu.gyro.arw_deg_rt_h"] for t in a)
    # a longer campaign with the same seed starts with the same members
    assert [t.seed for t in plan_members(data, 12, 7, vs, tmp_path)[:8]] == [t.seed for t in a]
    assert "gyro" not in data["sensors"]["imu"]  # the base data is not modified


# -- on the cluster ---------------------------------------------------------------------------------------
def _describe_ref(xs):
    """Independent reference statistics (the statistics module; 'inclusive' quantiles == numpy's linear)."""
    q = statistics.quantiles(xs, n=20, method="inclusive")
    return {"mean": statistics.fmean(xs), "sigma": statistics.stdev(xs), "p5": q[0], "p50": q[9], "p95": q[18],
            "min": min(xs), "max": max(xs), "n": len(xs)}


@pytest.mark.parametrize("duration_s", [6.0, pytest.param(20.0, marks=pytest.mark.slow)])
def test_twenty_run_campaign_statistics_agree_with_the_members_summaries(tmp_path, dask_client, duration_s):
    path = write_short_scenario(tmp_path / "c20.yaml", duration_s, name="c20",
                                expectations=[{"nav_error": {"metric": "position_m", "stat": "rms", "max": 12.0,
                                                             "after_s": 3}},
                                              {"dsp": {"field": "deadline_misses", "max": 0}}])
    cfg = CampaignConfig(path, runs=20, seed=2024, out_dir=tmp_path / "out",
                         variations=[parse_vary("sensors.imu.gyro.arw_deg_rt_h=normal(0.15,0.02)")])
    res = run_campaign(cfg, client=dask_client)
    assert res.stats["runs"] == 20 and res.stats["completed"] == 20 and res.stats["failed"] == 0
    assert res.info["workers"] == 2 and res.runs_per_min > 0
    summaries = [json.loads((tmp_path / "out" / "runs" / f"{i:04d}" / "summary.json").read_text()) for i in range(20)]
    assert [s["seed"] for s in summaries] == [r["seed"] for r in res.rows]
    assert len({s["seed"] for s in summaries}) == 20
    for m in NAV_METRICS:
        for stat in ("rms", "max"):
            ref = _describe_ref([s["nav_error"][m][stat] for s in summaries])
            got = res.stats["metrics"][f"{m}_{stat}"]
            for k, v in ref.items():
                assert got[k] == pytest.approx(v, rel=1e-12, abs=1e-15), (m, stat, k)
    # the position errors do differ between members (different seeds): the statistics are not trivial
    assert res.stats["metrics"]["position_m_rms"]["sigma"] > 0.05
    # pass rates from the members' own expectation results
    for e in res.stats["expectations"]:
        own = [s["expectations"][e["index"]]["passed"] for s in summaries]
        assert e["passed"] == sum(own) and e["runs"] == 20
    assert res.stats["passed"] == sum(s["passed"] for s in summaries)
    assert res.stats["pass_rate"] == pytest.approx(sum(s["passed"] for s in summaries) / 20)
    # files: the table has one row per member with the same numbers; statistics and plots exist
    rows = list(_csv_rows(tmp_path / "out" / "runs.csv"))
    assert [int(r["index"]) for r in rows] == list(range(20))
    assert [float(r["position_m_rms"]) for r in rows] == [s["nav_error"]["position_m"]["rms"] for s in summaries]
    assert [float(r["param:sensors.imu.gyro.arw_deg_rt_h"]) for r in rows] == \
        [r["params"]["sensors.imu.gyro.arw_deg_rt_h"] for r in res.rows]
    stats_rows = {r["quantity"]: r for r in _csv_rows(tmp_path / "out" / "stats.csv")}
    assert float(stats_rows["heading_deg_rms"]["mean"]) == res.stats["metrics"]["heading_deg_rms"]["mean"]
    doc = json.loads((tmp_path / "out" / "campaign.json").read_text())
    assert doc["statistics"]["completed"] == 20 and doc["failures"] == []
    assert (tmp_path / "out" / "campaign.png").stat().st_size > 10_000
    assert (tmp_path / "out" / "sensitivity.png").exists()
    assert not (tmp_path / "out" / "runs" / "0000" / "capture.psnscap").exists()  # big files dropped by default
    # campaign.mcap (issue 39 item 5), read back with the mcap reader: one message per member at its index (s),
    # the same numbers as the members' summaries
    from mcap.reader import make_reader

    with open(tmp_path / "out" / "campaign.mcap", "rb") as f:
        msgs = [(ch.topic, m.log_time, json.loads(m.data)) for _s, ch, m in make_reader(f).iter_messages()]
    assert [t for t, _lt, _d in msgs] == ["/campaign/members"] * 20
    assert [lt for _t, lt, _d in msgs] == [i * 1_000_000_000 for i in range(20)]
    assert [d["metrics"]["position_m_rms"] for _t, _lt, d in msgs] == \
        [s["nav_error"]["position_m"]["rms"] for s in summaries]
    assert [d["seed"] for _t, _lt, d in msgs] == [s["seed"] for s in summaries]
    assert [d["params"]["sensors.imu.gyro.arw_deg_rt_h"] for _t, _lt, d in msgs] == \
        [r["params"]["sensors.imu.gyro.arw_deg_rt_h"] for r in res.rows]


def test_failed_members_are_reported_with_their_error_never_lost(tmp_path, dask_client):
    # latency_s >= 0 in the schema; normal(0.05, 0.05) draws a negative value in some members
    path = write_short_scenario(tmp_path / "f.yaml", 2.0, name="fails", expectations=[])
    cfg = CampaignConfig(path, runs=8, seed=11, out_dir=tmp_path / "out",
                         variations=[parse_vary("sensors.gnss.latency_s=normal(0.05,0.05)")], plots=False)
    res = run_campaign(cfg, client=dask_client)
    drawn = [r["params"]["sensors.gnss.latency_s"] for r in res.rows]
    bad = [i for i, v in enumerate(drawn) if v < 0]
    assert 0 < len(bad) < 8, drawn  # the seed was chosen so that both kinds occur
    assert [r["index"] for r in res.failed] == bad
    for r in res.failed:
        assert "latency_s" in r["error"] and "greater than or equal to 0" in r["error"]
    assert res.stats["failed"] == len(bad) and res.stats["completed"] == 8 - len(bad)
    rows = list(_csv_rows(tmp_path / "out" / "runs.csv"))
    assert len(rows) == 8
    assert [int(r["index"]) for r in rows if r["ok"] == "0"] == bad
    assert all("latency_s" in r["error"] for r in rows if r["ok"] == "0")
    doc = json.loads((tmp_path / "out" / "campaign.json").read_text())
    assert [f["index"] for f in doc["failures"]] == bad


def test_results_do_not_depend_on_scheduling(tmp_path, dask_client):
    """Members run on the cluster (any worker, any order) equal the same members run in this process."""
    path = write_short_scenario(tmp_path / "d.yaml", 3.0, name="det", expectations=[])
    cfg = CampaignConfig(path, runs=3, seed=5, out_dir=tmp_path / "a", plots=False,
                         variations=[parse_vary("sensors.imu.gyro.arw_deg_rt_h=uniform(0.1,0.3)")])
    res = run_campaign(cfg, client=dask_client)
    data, _scn, src, base = load_campaign_scenario(path)
    local = [run_member(t) for t in plan_members(data, 3, 5, cfg.variations, tmp_path / "b", src, base)]
    for a, b in zip(res.rows, local):
        assert a["seed"] == b["seed"] and a["params"] == b["params"]
        for m in NAV_METRICS:
            assert a[f"{m}_rms"] == b[f"{m}_rms"] and a[f"{m}_max"] == b[f"{m}_max"]


def test_an_external_scheduler_address_is_used(tmp_path, dask_client):
    path = write_short_scenario(tmp_path / "e.yaml", 1.0, name="ext", expectations=[])
    cfg = CampaignConfig(path, runs=2, seed=1, out_dir=tmp_path / "o", plots=False,
                         scheduler=dask_client.scheduler.address)
    res = run_campaign(cfg)
    assert res.stats["completed"] == 2 and res.info["scheduler"].startswith("tcp://127.0.0.1:")
    assert dask_client.status == "running"  # our own client to it was closed, the cluster was not


def test_statistics_ignore_failed_members_and_handle_empty():
    rows = [{"index": 0, "ok": False, "params": {}, "error": "x"}]
    st = campaign_statistics(rows)
    assert st["completed"] == 0 and st["pass_rate"] is None and st["metrics"]["position_m_rms"]["n"] == 0


def test_cli_campaign_bad_vary_is_a_usage_error(tmp_path, capsys):
    from emulator.cli import main

    p = write_short_scenario(tmp_path / "s.yaml", 1.0)
    assert main(["campaign", str(p), "--runs", "2", "--vary", "sensors.imu.gyro.arw=normal(1,1)"]) == 2
    assert "no key 'arw'; keys there: arw_deg_rt_h" in capsys.readouterr().err
    assert main(["campaign", str(p), "--runs", "2", "--vary", "duration_s=triangular(1,2,3)"]) == 2
    assert "unknown distribution 'triangular'" in capsys.readouterr().err


# -- security of the campaign's own cluster (docs/distributed.md "Security") -----------------------------------
def test_own_cluster_is_tls_authenticated_and_serves_no_dashboard():
    """Before: a plain tcp:// scheduler that any local process could submit code to, and an HTTP server on 8787."""
    import urllib.error
    import urllib.request

    from emulator.distributed.campaign.execute import local_cluster

    client, cluster = local_cluster(1)
    try:
        addr = cluster.scheduler_address
        assert addr.startswith("tls://127.0.0.1:")
        assert client.submit(lambda: 41 + 1).result(timeout=60) == 42
        # the scheduler refuses a peer holding another cluster's certificate, and a plain TCP peer; the same
        # connect with this cluster's own certificate succeeds (so the refusals are the server's, not the client's).
        # Low-level comms on a loop of the test's own: a refused distributed.Client needs an IO-loop thread whose
        # start dask bounds at 10 s of wall time, which a loaded CI machine once exceeded.
        from distributed.comm import connect
        from distributed.security import Security

        async def connect_and_close(address: str, connection_args: dict) -> None:
            comm = await connect(address, timeout=10, **connection_args)
            await comm.close()

        asyncio.run(connect_and_close(addr, client.security.get_connection_args("client")))
        foreign = Security.temporary().get_connection_args("client")
        with pytest.raises(OSError, match="certificate"):
            asyncio.run(connect_and_close(addr, foreign))
        with pytest.raises(OSError):
            asyncio.run(connect_and_close(addr.replace("tls://", "tcp://"), {}))
        # the HTTP server dask always starts: not on 8787, and no route (no dashboard, no metrics)
        ports = [s.getsockname()[1] for s in cluster.scheduler.http_server._sockets.values()]
        assert ports and 8787 not in ports
        for path in ("/status", "/metrics", "/health", "/info/main/workers.html"):
            with pytest.raises(urllib.error.HTTPError) as ei:
                urllib.request.urlopen(f"http://127.0.0.1:{ports[0]}{path}", timeout=5)
            assert ei.value.code == 404
    finally:
        client.close()
        cluster.close()


def test_campaign_on_its_own_secured_cluster(tmp_path):
    path = write_short_scenario(tmp_path / "s.yaml", 1.0, name="sec", expectations=[])
    res = run_campaign(CampaignConfig(path, runs=1, seed=1, out_dir=tmp_path / "o", plots=False, workers=1))
    assert res.stats["completed"] == 1


def test_a_member_with_a_camera_carries_the_solar_vector_error_into_the_table(tmp_path):
    """run_member (what a worker runs) copies the summary's psns statistics into its row; the statistics and
    runs.csv carry them; a campaign without a polarization sensor gets no such columns."""
    from emulator.distributed.campaign import PSNS_METRICS, PSNS_STATS, write_outputs
    from emulator.distributed.campaign.outputs import CampaignResult

    root = Path(__file__).resolve().parents[3]
    import yaml

    data = yaml.safe_load((root / "scenarios" / "quickstart.yaml").read_text())
    data["duration_s"] = 5.0
    data["motion"] = [{"static": {"duration_s": 5.0}}]
    data["expectations"] = []
    scn_path = tmp_path / "cam.yaml"
    scn_path.write_text(yaml.safe_dump(data, sort_keys=False))
    data, _scn, source, base_dir = load_campaign_scenario(scn_path)
    tasks = plan_members(data, 1, 7, [], tmp_path / "out", source, base_dir, seeds=[7])
    row = run_member(tasks[0])
    assert row["ok"], row["error"]
    summary = json.loads((Path(tasks[0].run_dir) / "summary.json").read_text())
    assert summary["psns"]["solves"] > 0
    for m in PSNS_METRICS:
        for st in PSNS_STATS:
            assert row[f"{m}_{st}"] == summary["psns"][m][st]
    stats = campaign_statistics([row, dict(row, index=1, seed=8)])
    assert stats["metrics"]["solar_vector_error_deg_p95"]["mean"] == summary["psns"]["solar_vector_error_deg"]["p95"]
    res = CampaignResult(tmp_path / "out", [row], stats, 1.0, 1.0, {"scenario": "cam"})
    write_outputs(res, plots=False)
    got = _csv_rows(tmp_path / "out" / "runs.csv")[0]
    assert float(got["azimuth_error_deg_median"]) == summary["psns"]["azimuth_error_deg"]["median"]
    # no camera: no solar-vector columns at all
    no_cam = {k: v for k, v in row.items() if not k.startswith(PSNS_METRICS)}
    assert not any(k.startswith(PSNS_METRICS) for k in campaign_statistics([no_cam])["metrics"])


def test_a_kept_member_carries_its_mcap(tmp_path):
    """--keep-all: a member's run directory keeps its files and gets run.mcap (issue 39); without it, neither."""
    import yaml
    from mcap.reader import make_reader

    root = Path(__file__).resolve().parents[3]
    data = yaml.safe_load((root / "scenarios" / "quickstart.yaml").read_text())
    data["duration_s"] = 2.0
    data["motion"] = [{"static": {"duration_s": 2.0}}]
    data["expectations"] = []
    scn_path = tmp_path / "keep.yaml"
    scn_path.write_text(yaml.safe_dump(data, sort_keys=False))
    data, _scn, source, base_dir = load_campaign_scenario(scn_path)
    kept = plan_members(data, 1, 7, [], tmp_path / "k", source, base_dir, keep_all=True, seeds=[7])[0]
    dropped = plan_members(data, 1, 7, [], tmp_path / "d", source, base_dir, seeds=[7])[0]
    assert run_member(kept)["ok"] and run_member(dropped)["ok"]
    with open(Path(kept.run_dir) / "run.mcap", "rb") as f:
        n = sum(1 for _s, ch, _m in make_reader(f).iter_messages() if ch.topic == "/nav/solution")
    assert n == len((Path(kept.run_dir) / "nav.csv").read_text().splitlines()) - 1 > 0
    assert not (Path(dropped.run_dir) / "run.mcap").exists() and not (Path(dropped.run_dir) / "nav.csv").exists()


def test_campaign_mcap_carries_each_members_mean_nees_and_the_consistency_verdict(tmp_path):
    """write_campaign_mcap: a member's mean NEES per group is the mean of its samples; non-finite values become
    null (strict JSON); the consistency check is one message after the last member, without its series."""
    from mcap.reader import make_reader

    from emulator.postrun.mcap_out import write_campaign_mcap

    rows = [{"index": i, "seed": 10 + i, "ok": True, "passed": i != 1, "params": {}, "position_m_rms": 1.5 * i,
             "consistency": {"nees": {"heading": [1.0, 3.0 + i], "attitude": []}, "heading_err_mean_deg": 0.1 * i}}
            for i in range(3)]
    rows[2]["position_m_rms"] = float("nan")
    cons = {"runs": 3, "t": [0.0, 1.0], "passed": False,
            "groups": {"heading": {"nees_mean": 2.5, "status": "pass", "series": list(range(40))}}}
    write_campaign_mcap(tmp_path, rows, {"scenario": "x", "campaign_seed": 1}, cons, ["position_m_rms"])
    with open(tmp_path / "campaign.mcap", "rb") as f:
        reader = make_reader(f)
        msgs = [(ch.topic, m.log_time, json.loads(m.data)) for _s, ch, m in reader.iter_messages()]
    members = [d for t, _lt, d in msgs if t == "/campaign/members"]
    assert [d["nees_mean"]["heading"] for d in members] == [2.0, 2.5, 3.0]
    assert [d["nees_mean"]["attitude"] for d in members] == [None, None, None]
    assert [d["passed"] for d in members] == [True, False, True]
    assert [d["metrics"]["position_m_rms"] for d in members] == [0.0, 1.5, None]
    (_topic, log_time, verdict), = [m for m in msgs if m[0] == "/campaign/consistency"]
    assert log_time == 3_000_000_000 and verdict["consistency"]["passed"] is False
    assert "t" not in verdict["consistency"] and "series" not in verdict["consistency"]["groups"]["heading"]
    assert verdict["consistency"]["groups"]["heading"]["nees_mean"] == 2.5
