"""The module-size table of docs/architecture.md is current (tools/module_sizes.py writes it): every module of the
three packages over 500 lines is listed with its true line count, and each one over 600 lines gives the one concept
that keeps it whole (issue 42)."""

from __future__ import annotations

from tests.conftest import ROOT
from tools import module_sizes


def test_the_table_is_current():
    text = module_sizes.DOC.read_text(encoding="utf-8")
    new, missing = module_sizes.render(text)
    assert not missing, f"give a one-concept reason in docs/architecture.md for: {', '.join(missing)}"
    assert new == text, "the module-size table is stale: run python tools/module_sizes.py"


def test_counts_as_wc_and_a_missing_reason_is_reported(tmp_path):
    pkg = tmp_path / "emulator"
    pkg.mkdir()
    (pkg / "big.py").write_text("x = 1\n" * 601)
    (pkg / "mid.py").write_text("x = 1\n" * 501)
    (pkg / "small.py").write_text("x = 1\n" * 500)
    assert module_sizes.line_counts(tmp_path) == {"emulator/big.py": 601, "emulator/mid.py": 501}
    doc = f"# a page\n\n{module_sizes.BEGIN}\n| `emulator/mid.py` | 3 | one concept |\n{module_sizes.END}\nafter\n"
    new, missing = module_sizes.render(doc, tmp_path)
    assert missing == ["emulator/big.py (601 lines)"]
    assert "| `emulator/mid.py` | 501 | one concept |" in new  # the reason kept, the count refreshed
    assert f"| `emulator/big.py` | 601 | {module_sizes.NO_REASON} |" in new
    assert new.endswith(f"{module_sizes.END}\nafter\n")
    assert module_sizes.render(new.replace(module_sizes.NO_REASON, "the reason"), tmp_path)[1] == []


def test_the_packages_are_the_shipped_ones():
    assert all((ROOT / p / "__init__.py").exists() for p in module_sizes.PACKAGES)
