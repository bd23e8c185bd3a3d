"""The ``consistency:`` expectation: which state groups and measurement types a Monte-Carlo campaign must find
consistent, at which confidence, over how many runs (``psns-hil campaign SCENARIO --consistency``,
:mod:`emulator.distributed.campaign.consistency`), and the chi-square arithmetic both sides share.

Too few runs for the confidence level: the two-sided interval of the average NEES, per degree of freedom, must be
narrower than the expected value itself (1), or a filter that is overconfident by a factor of two passes unnoticed.
:func:`min_runs` gives the smallest such N for the group with the fewest components (95 %: 16 runs for a 1-dof group
such as ``heading``, 6 for a 3-dof group); ``validate`` refuses fewer, naming file:line:field.
"""

from __future__ import annotations

from functools import lru_cache

from pydantic import Field, model_validator

from .base import Model

__all__ = ["DEFAULT_GROUPS", "MEASUREMENT_TYPES", "STATE_GROUPS", "ConsistencyExpectation", "asked_groups",
           "chi2_bounds", "min_runs"]

#: state group -> number of components (degrees of freedom of one sample); the groups with truth in truth.csv
STATE_GROUPS: dict[str, int] = {"attitude": 3, "heading": 1, "velocity": 3, "position": 3, "horizontal_position": 2}
#: measurement types whose innovation statistics the firmware reports (summary ``firmware.innovation``)
MEASUREMENT_TYPES = ("gnss_position", "gnss_velocity", "solar_vector", "compass")
#: the state groups a check asks for when neither the scenario nor the command line names any (``heading`` is added
#: wherever the scenario has a heading source, :func:`asked_groups`)
DEFAULT_GROUPS = ("attitude", "velocity", "position")


def asked_groups(groups: list[str] | tuple[str, ...] | None, heading_source: bool, include_heading: bool = True
                 ) -> list[str]:
    """The state groups that decide a consistency check: ``groups`` (default :data:`DEFAULT_GROUPS`) plus the 1-dof
    ``heading`` group when the scenario has a heading source (a polarization camera or compass) and
    ``include_heading`` is not switched off (issue 36: a heading the filter keeps from the sky is certified too)."""
    out = list(groups) if groups else list(DEFAULT_GROUPS)
    if heading_source and include_heading and "heading" not in out:
        out.append("heading")
    return out


def chi2_bounds(runs: int, dof: int, confidence: float = 0.95) -> tuple[float, float]:
    """Two-sided ``confidence`` bounds of the average of ``runs`` chi-square(``dof``) samples
    (Bar-Shalom, Li & Kirubarajan 2001, Eq. 5.4.2-8)."""
    from scipy.stats import chi2

    alpha = 1.0 - confidence
    n = runs * dof
    return float(chi2.ppf(alpha / 2.0, n)) / runs, float(chi2.ppf(1.0 - alpha / 2.0, n)) / runs


@lru_cache(maxsize=64)
def min_runs(confidence: float, dof: int = 1, max_width: float = 1.0) -> int:
    """Fewest runs whose two-sided ``confidence`` interval of the average NEES, per dof, is at most ``max_width``."""
    for n in range(2, 10_000):
        lo, hi = chi2_bounds(n, dof, confidence)
        if (hi - lo) / dof <= max_width:
            return n
    return 10_000


class ConsistencyExpectation(Model):
    """A campaign-level check: average NEES per group and NIS per measurement type inside the chi-square bounds."""

    runs: int = Field(ge=2, le=10_000, description="members of the campaign that checks it (psns-hil campaign --runs)")
    confidence: float = Field(0.95, gt=0.5, lt=1.0, description="two-sided confidence level of the bounds")
    groups: list[str] = Field(default_factory=lambda: ["attitude", "velocity", "position"], min_length=1,
                              description="state groups: attitude, heading, velocity, position, horizontal_position")
    measurements: list[str] = Field(
        default_factory=list, description="measurement types: gnss_position, gnss_velocity, solar_vector, compass")
    after_s: float = Field(0.0, ge=0, description="evaluate from this scenario time on, s")
    upper_only: list[str] = Field(
        default_factory=list,
        description="state groups checked against the upper bound only (not overconfident): a sigma wide by design "
                    "where the firmware cannot know its world (docs/spec-sheet.md); how conservative is reported")
    include_heading: bool = Field(
        True, description="add the 1-dof heading group when the scenario has a heading source (camera or compass); "
                          "false: only the groups listed")

    @model_validator(mode="after")
    def _check(self) -> ConsistencyExpectation:
        bad = [g for g in self.groups if g not in STATE_GROUPS]
        if bad:
            raise ValueError(f"unknown state group(s) {bad}: the filter's groups with truth are {list(STATE_GROUPS)} "
                             "(the biases have no truth to compare with)")
        badu = [g for g in self.upper_only if g not in STATE_GROUPS]
        if badu:
            raise ValueError(f"upper_only: unknown state group(s) {badu}: known {list(STATE_GROUPS)}")
        badm = [m for m in self.measurements if m not in MEASUREMENT_TYPES]
        if badm:
            raise ValueError(f"unknown measurement type(s) {badm}: known {list(MEASUREMENT_TYPES)}")
        dof = min(STATE_GROUPS[g] for g in self.groups)
        if self.measurements:
            dof = 1
        need = min_runs(self.confidence, dof)
        if self.runs < need:
            raise ValueError(f"runs: {self.runs} runs are too few for {self.confidence:.0%} confidence on a {dof}-dof "
                             f"average (need >= {need}: the interval must be narrower than the expected value)")
        return self
