"""YAML bounded before it is built (issue 41 item 5): size capped before parsing, depth capped before composing,
merge keys and unknown tags refused with one line naming file and line, exit 2.

Before: 100 KB of ``[`` took 294 s in ``validate`` and ended with a RecursionError traceback (exit 1); a merge key
gave a ConstructorError traceback. The bound is asserted as work done (characters scanned, events read, composer
never called), not as a wall-clock threshold."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

import emulator.scenario.loader as loader
from emulator.errors import ScenarioError
from emulator.scenario import load_scenario, load_yaml_with_marks

ROOT = Path(__file__).resolve().parents[3]


def _validate(path: Path | str) -> tuple[int, list[str]]:
    e = dict(os.environ, PYTHONPATH=str(ROOT))
    r = subprocess.run([sys.executable, "-m", "emulator", "validate", str(path)], capture_output=True, text=True,
                       timeout=120, env=e, cwd=ROOT)
    assert "Traceback" not in r.stderr
    return r.returncode, r.stderr.strip().splitlines()


@pytest.mark.parametrize("text", ["[" * 100_000, "{a: " * 30_000, "".join(" " * i + "a:\n" for i in range(1200))],
                         ids=["flow_sequences", "flow_mappings", "block_mappings"])
def test_deep_nesting_is_refused_after_a_bounded_scan(monkeypatch, text: str) -> None:
    def no_compose(*a, **k):
        raise AssertionError("composed a document nested beyond the cap")

    monkeypatch.setattr(loader.yaml, "compose", no_compose)
    stats: dict[str, int] = {}
    with pytest.raises(ScenarioError, match="nested deeper than 64 levels") as ei:
        loader._screen_events(text, "deep.yaml", stats)
    # the scan stops at the 65th level: a few events, and no more text than the cap plus the scanner's 1024-char
    # simple-key lookahead, whatever the file's length
    assert stats["events"] <= 3 * loader.MAX_YAML_DEPTH + 3  # a key and a collection per level at most
    issue = ei.value.issues[0]
    at = sum(len(ln) + 1 for ln in text.split("\n")[:issue.line - 1]) + issue.column  # where the 65th level opens
    assert stats["chars"] <= at + 1024 + 8
    assert at < 3000 < len(text)
    with pytest.raises(ScenarioError, match="nested deeper"):
        load_yaml_with_marks(text, "deep.yaml")


def test_deep_nesting_exits_2_with_file_and_line(tmp_path: Path) -> None:
    p = tmp_path / "deep.yaml"
    p.write_text("[" * 100_000)
    rc, lines = _validate(p)
    assert rc == 2 and lines == [f"error: {p}:1:65: YAML nested deeper than 64 levels (a scenario needs about 8)"]


def test_size_is_capped_before_the_parser_sees_a_byte(tmp_path: Path, monkeypatch) -> None:
    big = tmp_path / "big.yaml"
    big.write_bytes(b"name: x\n" + b"#" * (loader.MAX_SCENARIO_BYTES + 10))

    def no_parse(*a, **k):
        raise AssertionError("parsed a file over the size cap")

    monkeypatch.setattr(loader.yaml, "SafeLoader", no_parse)
    monkeypatch.setattr(loader.yaml, "compose", no_parse)
    for path in (big, Path("/dev/zero")):  # /dev/zero: endless; the read is one bounded piece
        with pytest.raises(ScenarioError, match=r"larger than 1 MiB"):
            load_scenario(path)
    with pytest.raises(ScenarioError, match=r"larger than 1 MiB"):
        load_yaml_with_marks("a" * (loader.MAX_SCENARIO_BYTES + 1), "text.yaml")
    rc, lines = _validate(big)
    assert rc == 2 and lines == [f"error: {big}: larger than 1 MiB (a scenario is a few KB)"]


def test_merge_keys_are_refused_with_their_line(tmp_path: Path) -> None:
    p = tmp_path / "merge.yaml"
    p.write_text("name: x\nbase: {a: 1}\nother:\n  <<: {a: 1}\n  b: 2\n")
    rc, lines = _validate(p)
    assert rc == 2 and lines == [f"error: {p}:4:3: other: YAML merge keys (<<) are not allowed: write the keys out "
                                 "(decision D-8.9)"]


def test_an_unknown_tag_is_one_line_with_its_place(tmp_path: Path) -> None:
    p = tmp_path / "tag.yaml"
    p.write_text("name: x\nduration_s: !!python/name:os.system\n")
    rc, lines = _validate(p)
    assert rc == 2 and len(lines) == 1 and lines[0].startswith(f"error: {p}:2:13: invalid YAML value: ")
