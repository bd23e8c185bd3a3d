"""Monte-Carlo campaigns: many runs of one scenario with derived seeds and varied parameters, on Dask.

``psns-hil campaign SCENARIO --runs N [--vary KEY=DISTRIBUTION ...] [--scheduler tcp://HOST:PORT]
[--workers W] [--out DIR] [--seed S]`` (:mod:`emulator.cli.campaign`) runs ``N`` members of the
scenario in fast mode on a Dask distributed cluster (a :class:`distributed.LocalCluster` of ``W``
worker processes on 127.0.0.1 by default, or an existing scheduler), collects every member's
summary into one table and computes statistics.

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

Outputs in ``--out`` (default ``runs/campaign-<scenario>-<UTC time>``)::

    ``runs.csv``        one row per member: index, seed, drawn parameters, ok, error, passed, the
                        summary's nav errors (``<metric>_rms``, ``<metric>_max``), with a polarization sensor
                        the solved solar vector against truth (``solar_vector_error_deg_median``, ``_p95``,
                        ``_max``, and the same of ``azimuth_error_deg``, ``elevation_error_deg``), expectation results,
                        DSP load and deadline misses, wall time
    ``stats.csv``       per numeric column: n, mean, sigma (ddof 1), min, p5, p50, p95, max
    ``campaign.json``   configuration, statistics, expectation pass rates, failures, throughput
    ``campaign.png``    histograms of every error metric; ``sensitivity.png`` error vs each varied key
    ``runs/NNNN/``      each member's run directory (summary.json, events.jsonl; ``--keep-all`` keeps
                        the captures, nav.csv and truth.csv too)

Modules: :mod:`.spec` (what to run: the configuration, its variations and their distributions, checked
against the scenario), :mod:`.plan` (members: seeds and drawn parameters), :mod:`.execute` (running members,
in-process or on a Dask cluster), :mod:`.stats` (statistics over the members), :mod:`.outputs` (the result
and its files).
"""

from .execute import execute_members, run_campaign, run_member, warm_up
from .outputs import CampaignResult, remove_run_dirs, write_outputs
from .plan import MemberTask, plan_members
from .spec import (
    CampaignConfig,
    CampaignError,
    Distribution,
    Variation,
    apply_variations,
    load_campaign_scenario,
    parse_distribution,
    parse_vary,
    validate_variations,
)
from .stats import NAV_METRICS, PSNS_METRICS, PSNS_STATS, campaign_statistics

__all__ = [
    "NAV_METRICS",
    "PSNS_METRICS",
    "PSNS_STATS",
    "CampaignConfig",
    "CampaignError",
    "CampaignResult",
    "Distribution",
    "MemberTask",
    "Variation",
    "apply_variations",
    "campaign_statistics",
    "execute_members",
    "load_campaign_scenario",
    "parse_distribution",
    "parse_vary",
    "plan_members",
    "remove_run_dirs",
    "run_campaign",
    "run_member",
    "validate_variations",
    "warm_up",
    "write_outputs",
]
