"""pytest collects every scenario file here as a test: the scenario library is the regression suite.

Each ``*.yaml`` gives two tests that share one run (fast mode, the scenario's seed, a temporary
run directory):

``<name>``
    passes when the run was valid (every scheduled fault took effect), was not interrupted, and
    every one of the scenario's own expectations passed. The failure text lists each failed
    expectation with its measured value, each fault that never fired with its evidence, and the
    run directory, which is kept (with ``report.html``) when anything failed.
``<name>[seeds]``
    seed robustness (issue 15): the scenario's expectations hold for every one of :data:`SEEDS` (seeds 1-10,
    ``slow``: ``make test-all``); short scenarios (at most :data:`FAST_SEEDS_MAX_S` simulated seconds and not
    tagged ``slow``) also get ``<name>[seeds-fast]`` with :data:`FAST_SEEDS` in ``make test``. A bound that holds
    for the scenario's own seed only is a defect: re-derive it from the measured distribution. A ``consistency:``
    expectation is checked there too: the average NEES of its groups (and NIS of its measurements) over its first
    ``runs`` seeds (seeds after 10 are added when it asks for more) must lie inside the chi-square bounds.
``<name>[golden]``
    the change indicator (``emulator.postrun.golden``): the captured input bytes must match
    ``tests/golden/<name>.inputs.txt`` exactly and the estimator's state history
    ``tests/golden/<name>.state.csv`` within float noise. Regenerate on purpose with ``make golden``.

Scenarios tagged ``slow`` get the ``slow`` marker (excluded from the default ``make test``;
``make test-all`` runs them). A library file that does not validate is a collection error with
every problem, file:line:column. The terminal summary lists each scenario's wall time.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import time
from pathlib import Path
from typing import Any

import pytest

# the library's scenarios are trusted: their Python expectation hooks run (psns-hil run --allow-hooks)
os.environ.setdefault("PSNS_HIL_ALLOW_HOOKS", "1")

_WALL: list[tuple[str, float, float, bool]] = []

#: the seeds every library scenario's expectations must hold for (``make test-all``)
SEEDS = tuple(range(1, 11))
#: the fast subset (``make test``) for short scenarios
FAST_SEEDS = (1, 2)
FAST_SEEDS_MAX_S = 45.0


def pytest_collect_file(parent: pytest.Collector, file_path: Path):
    if file_path.suffix in (".yaml", ".yml") and "spec_sheets" not in file_path.parts:  # spec sheets are data
        return ScenarioFile.from_parent(parent, path=file_path)
    return None


class _Run:
    """One run of a scenario, shared by its two tests."""

    def __init__(self, path: Path, scenario: Any) -> None:
        self.path = path
        self.scenario = scenario
        self.summary: dict[str, Any] | None = None
        self.golden_diffs: list[str] = []
        self.run_dir: Path | None = None
        self.kept = False
        self.error: BaseException | None = None

    def get(self) -> _Run:
        if self.summary is not None or self.error is not None:
            return self
        from emulator.assembly.session import run_scenario
        from emulator.postrun.golden import compare_golden

        scn = self.scenario
        base = Path(tempfile.mkdtemp(prefix=f"scn-{scn.name}-"))
        self.run_dir = base / "run"
        t0 = time.perf_counter()
        try:
            self.summary = run_scenario(scn, self.run_dir, mode="fast")
            self.golden_diffs = compare_golden(self.run_dir, scn.name, scn.seed, scn.duration_s)
        except BaseException as exc:
            self.error = exc
        wall = time.perf_counter() - t0
        s = self.summary or {}
        ok = bool(s.get("passed")) and s.get("valid", True) is not False and not self.golden_diffs and not self.error
        _WALL.append((scn.name, wall, scn.duration_s, "slow" in scn.tags))
        if ok:
            shutil.rmtree(base, ignore_errors=True)
        else:
            self.kept = True
            if self.summary is not None:
                try:
                    from emulator.postrun.report import write_report

                    write_report(self.run_dir)
                except Exception:
                    pass
        return self


class ScenarioFile(pytest.File):
    def collect(self):
        from emulator.errors import ScenarioError
        from emulator.scenario import load_scenario

        try:
            scn = load_scenario(self.path)
        except ScenarioError as exc:  # every problem, file:line:column
            raise self.CollectError(f"scenario file does not validate:\n{exc}") from None
        run = _Run(self.path, scn)
        for cls, name in ((ScenarioItem, scn.name), (GoldenItem, f"{scn.name}[golden]")):
            item = cls.from_parent(self, name=name, scenario=scn, run=run)
            if "slow" in scn.tags:
                item.add_marker(pytest.mark.slow)
            yield item
        seeds_item = SeedsItem.from_parent(self, name=f"{scn.name}[seeds]", scenario=scn, run=run, seeds=SEEDS)
        seeds_item.add_marker(pytest.mark.slow)
        # ten runs of a long scenario (and the extra seeds a consistency: expectation asks for) outlast the
        # per-test timeout of pyproject.toml (a run takes ~1/20 of its simulated time here; 3 s per simulated second
        # for all seeds together leaves room for a loaded machine)
        seeds_item.add_marker(pytest.mark.timeout(max(600, int(3 * scn.duration_s))))
        yield seeds_item
        if scn.duration_s <= FAST_SEEDS_MAX_S and "slow" not in scn.tags:
            yield SeedsItem.from_parent(self, name=f"{scn.name}[seeds-fast]", scenario=scn, run=run, seeds=FAST_SEEDS)


class ScenarioFailed(Exception):
    pass


class _Item(pytest.Item):
    def __init__(self, *, scenario: Any, run: _Run, **kw: Any) -> None:
        super().__init__(**kw)
        self.scenario = scenario
        self.run = run

    def _kept(self) -> str:
        r = self.run
        return f"  run directory kept: {r.run_dir} (summary.json, report.html, events.jsonl)" if r.kept else ""

    def reportinfo(self):
        return self.path, 0, f"scenario: {self.name}"

    def repr_failure(self, excinfo, style=None):
        if isinstance(excinfo.value, ScenarioFailed):
            return "\n".join(excinfo.value.args[0])
        return super().repr_failure(excinfo, style=style)


class ScenarioItem(_Item):
    """The scenario's own expectations (and the validity of its faults)."""

    def runtest(self) -> None:
        r = self.run.get()
        if r.error is not None:
            raise r.error
        s = r.summary or {}
        self.user_properties.append(("summary", {k: s.get(k) for k in ("nav_error", "dsp", "passed", "valid")}))
        lines = []
        for e in s.get("expectations", []):
            if not e["passed"]:
                note = f" ({e['message']})" if e.get("message") else ""
                lines.append(f"  expectation #{e['index']} {e['kind']}: {e['description']}: "
                             f"measured {e['value']}{note}")
        for f in s.get("faults", []):
            if f.get("fired") is False:
                ev = ", ".join(f"{k} {v}" for k, v in f.get("evidence", {}).items()) or "none"
                lines.append(f"  run invalid: fault #{f['index']} {f['kind']} on {f['target']} never took effect "
                             f"while active {f.get('active_from_s')}-{f.get('active_until_s')} s (evidence: {ev})")
        if s.get("interrupted"):
            lines.append("  the run was interrupted")
        if lines or not s.get("passed", False):
            if not lines:
                lines.append("  the run did not pass")
            head = f"scenario {self.scenario.name} ({self.path}) failed:"
            raise ScenarioFailed([head, *lines, self._kept()])


class SeedsItem(_Item):
    """The scenario's expectations over several seeds (module docstring): every failing seed is listed."""

    def __init__(self, *, seeds: tuple[int, ...], **kw: Any) -> None:
        super().__init__(**kw)
        self.seeds = seeds

    def runtest(self) -> None:
        from emulator.assembly.session import run_scenario

        scn = self.scenario
        lines = []
        # a consistency: expectation is a campaign-level check: the full [seeds] item evaluates it over its first
        # `runs` seeds (adding seeds after SEEDS when it asks for more)
        demands = [e.consistency for e in scn.expectations if getattr(e, "consistency", None) is not None] \
            if len(self.seeds) > len(FAST_SEEDS) else []
        seeds = tuple(self.seeds)
        need = max((c.runs for c in demands), default=0)
        if need > len(seeds):
            seeds += tuple(range(max(seeds) + 1, max(seeds) + 1 + need - len(seeds)))
        members: list[list[dict[str, Any]]] = [[] for _ in demands]
        for seed in seeds:
            base = Path(tempfile.mkdtemp(prefix=f"scn-{scn.name}-seed{seed}-"))
            t0 = time.perf_counter()
            s = run_scenario(scn, base / "run", mode="fast", seed=seed)
            if demands:
                from emulator.distributed.campaign.consistency import member_consistency

                for i, c in enumerate(demands):
                    if len(members[i]) < c.runs:
                        members[i].append(member_consistency(base / "run", s, after_s=c.after_s))
            _WALL.append((f"{scn.name}[seed {seed}]", time.perf_counter() - t0, scn.duration_s,
                          len(seeds) > len(FAST_SEEDS)))
            failed = [e for e in s.get("expectations", []) if not e["passed"]]
            bad_faults = [f for f in s.get("faults", []) if f.get("fired") is False]
            if failed or bad_faults or s.get("interrupted") or not s.get("passed", False):
                lines.append(f"  seed {seed}: run directory kept: {base / 'run'}")
                lines += [f"    expectation #{e['index']}: {e['description']}: measured {e['value']}" for e in failed]
                lines += [f"    fault #{f['index']} {f['kind']} never took effect" for f in bad_faults]
            else:
                shutil.rmtree(base, ignore_errors=True)
        for c, mem in zip(demands, members, strict=True):
            from emulator.distributed.campaign.consistency import campaign_consistency
            from emulator.distributed.campaign.execute import consistency_spec

            spec = consistency_spec(scn)  # the asked groups: heading added wherever the scenario has a heading source
            res = campaign_consistency(mem, c.confidence, spec["groups"], c.measurements, spec["upper_only"])
            demanded = [("groups", g, "mean_nees") for g in spec["groups"]]
            demanded += [("measurements", m, "mean_nis") for m in c.measurements]
            for kind, name, key in demanded:
                d = res[kind][name]
                if not d.get("passed"):
                    lines.append(f"  consistency over {len(mem)} seeds: {name}: average {d.get(key)} outside "
                                 f"[{d.get('lower')}, {d.get('upper')}] ({c.confidence:.0%})")
        if lines:
            raise ScenarioFailed([f"scenario {scn.name} ({self.path}) is not seed-robust over seeds "
                                  f"{list(seeds)}:", *lines])


class GoldenItem(_Item):
    """The change indicator: captured inputs exact, estimator state history within float noise."""

    def runtest(self) -> None:
        r = self.run.get()
        if r.error is not None:
            raise r.error
        if r.golden_diffs:
            head = (f"change indicator: scenario {self.scenario.name} differs from tests/golden/{self.scenario.name}.* "
                    f"(if the change is intended, run `make golden` and commit the diff):")
            raise ScenarioFailed([head, *(f"  {d}" for d in r.golden_diffs), self._kept()])


def pytest_terminal_summary(terminalreporter, exitstatus, config):
    if not _WALL:
        return
    tr = terminalreporter
    tr.section("scenario library: wall time (fast mode)")
    for name, wall, sim, slow in sorted(_WALL, key=lambda x: -x[1]):
        tr.write_line(f"{name:32s} {wall:7.1f} s wall for {sim:7.0f} s simulated{'  (slow)' if slow else ''}")
