"""pytest collects every scenario file here as a test: the scenario library is the regression suite.

Each ``*.yaml`` runs in fast mode into a temporary run directory and passes when every one of its
own expectations passes (and the run was valid). Scenarios tagged ``slow`` get the ``slow``
marker (excluded from the default ``make test``; ``make test-all`` runs them).
"""

from __future__ import annotations

from pathlib import Path

import pytest


def pytest_collect_file(parent: pytest.Collector, file_path: Path):  # noqa: D103
    if file_path.suffix in (".yaml", ".yml"):
        return ScenarioFile.from_parent(parent, path=file_path)
    return None


class ScenarioFile(pytest.File):
    def collect(self):
        from emulator.scenario import load_scenario

        scn = load_scenario(self.path)  # a broken library file fails collection loudly
        item = ScenarioItem.from_parent(self, name=scn.name, scenario=scn)
        for tag in scn.tags:
            if tag == "slow":
                item.add_marker(pytest.mark.slow)
        yield item


class ScenarioFailed(Exception):
    pass


class ScenarioItem(pytest.Item):
    def __init__(self, *, scenario, **kw):
        super().__init__(**kw)
        self.scenario = scenario

    def runtest(self) -> None:
        import tempfile

        from emulator.runner import run_scenario

        with tempfile.TemporaryDirectory(prefix=f"scn-{self.scenario.name}-") as d:
            summary = run_scenario(self.scenario, Path(d) / "run", mode="fast")
        self.user_properties.append(("summary", {k: summary.get(k) for k in ("nav_error", "dsp", "passed")}))
        failed = [e for e in summary.get("expectations", []) if not e["passed"]]
        if failed or not summary.get("passed", False):
            raise ScenarioFailed(failed)

    def repr_failure(self, excinfo, style=None):  # noqa: D102
        if isinstance(excinfo.value, ScenarioFailed):
            lines = [f"scenario {self.scenario.name} ({self.path}) failed:"]
            for e in excinfo.value.args[0]:
                lines.append(f"  expectation #{e['index']}: {e['description']}: measured {e['value']}")
            if len(lines) == 1:
                lines.append("  the run was invalid or interrupted")
            return "\n".join(lines)
        return super().repr_failure(excinfo, style=style)

    def reportinfo(self):  # noqa: D102
        return self.path, 0, f"scenario: {self.scenario.name}"
