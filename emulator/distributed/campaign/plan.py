"""The members of a campaign: each one's seed and drawn parameters, deterministic in the campaign seed.

Member ``i`` gets child ``i`` of ``SeedSequence(campaign_seed)``, split into the run's seed and the generator
that draws its parameters, so a member does not depend on how many members there are or where it runs.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .spec import Variation, apply_variations

__all__ = ["MemberTask", "plan_members"]


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
    #: compute the member's NEES samples (:func:`.consistency.member_consistency`) from ``after_s`` on
    consistency: bool = False
    consistency_after_s: float = 0.0


def _seed_of(ss: np.random.SeedSequence) -> int:
    return int(ss.generate_state(1, dtype=np.uint32)[0])


def plan_members(data: dict[str, Any], runs: int, campaign_seed: int, variations: Sequence[Variation],
                 out_dir: Path, source_file: str = "<scenario>", base_dir: str | None = None,
                 keep_all: bool = False, consistency: bool = False,
                 consistency_after_s: float = 0.0, seeds: Sequence[int] | None = None) -> list[MemberTask]:
    """The members of a campaign: seeds and drawn parameters (deterministic in ``campaign_seed``); ``seeds`` gives
    the members' run seeds explicitly (``--seeds 1-10``: the seeds a scenario's bounds were derived with)."""
    root = np.random.SeedSequence(campaign_seed)
    tasks = []
    for i, child in enumerate(root.spawn(runs)):
        run_ss, vary_ss = child.spawn(2)
        rng = np.random.default_rng(vary_ss)
        params = {v.key: v.dist.sample(rng) for v in variations}
        member = apply_variations(data, params)
        member["seed"] = int(seeds[i]) if seeds is not None else _seed_of(run_ss)
        tasks.append(MemberTask(i, member["seed"], params, member, source_file, base_dir,
                                str(Path(out_dir) / "runs" / f"{i:04d}"), keep_all, consistency,
                                consistency_after_s))
    return tasks
