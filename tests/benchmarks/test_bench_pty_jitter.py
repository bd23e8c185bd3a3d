"""benchmarks.bench_pty_jitter: the unbound-workqueue confinement writes the mask and always puts the old one back."""

from __future__ import annotations

import pytest

from benchmarks import bench_pty_jitter


def test_workqueue_mask_is_the_cpus_hex_mask_during_the_block_and_the_old_one_after(tmp_path, monkeypatch):
    mask = tmp_path / "cpumask"
    mask.write_text("3\n")
    monkeypatch.setattr(bench_pty_jitter, "WORKQUEUE_CPUMASK", mask)
    monkeypatch.setenv("PSNS_BENCH_RT_WQ_CPUS", "1")
    with bench_pty_jitter.unbound_workqueue_cpus() as note:
        assert mask.read_text() == "2"  # CPU 1 alone: bit 1
        assert note == "unbound workqueues on CPU 1 (mask 3 before)"
    assert mask.read_text() == "3"
    monkeypatch.setenv("PSNS_BENCH_RT_WQ_CPUS", "0,3")
    with pytest.raises(RuntimeError), bench_pty_jitter.unbound_workqueue_cpus():
        assert mask.read_text() == "9"
        raise RuntimeError("the run failed")
    assert mask.read_text() == "3"  # restored when the run raises too


def test_workqueue_mask_is_left_alone_when_unset(tmp_path, monkeypatch):
    mask = tmp_path / "cpumask"
    mask.write_text("3\n")
    monkeypatch.setattr(bench_pty_jitter, "WORKQUEUE_CPUMASK", mask)
    monkeypatch.delenv("PSNS_BENCH_RT_WQ_CPUS", raising=False)
    with bench_pty_jitter.unbound_workqueue_cpus() as note:
        assert note == ""
    assert mask.read_text() == "3\n"  # not even rewritten
