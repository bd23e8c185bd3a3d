"""benchmarks.bench_pty_jitter: the host settings of the realtime run are written as asked and always put back."""

from __future__ import annotations

import os

import pytest

from benchmarks import bench_pty_jitter


@pytest.fixture
def sysfs(tmp_path, monkeypatch):
    """A stand-in for the two sysfs places the settings write (the workqueue mask "3", CPU 0-1's QoS "0")."""
    mask = tmp_path / "cpumask"
    mask.write_text("3\n")
    monkeypatch.setattr(bench_pty_jitter, "WORKQUEUE_CPUMASK", mask)
    for c in (0, 1):
        (tmp_path / f"cpu{c}" / "power").mkdir(parents=True)
        (tmp_path / f"cpu{c}" / "power" / "pm_qos_resume_latency_us").write_text("0\n")
    monkeypatch.setattr(bench_pty_jitter, "CPU_SYSFS", tmp_path)
    for var in ("PSNS_BENCH_RT_WQ_CPUS", "PSNS_BENCH_RT_POLL_CPUS"):
        monkeypatch.delenv(var, raising=False)
    return tmp_path


def _qos(root, cpu):
    return (root / f"cpu{cpu}" / "power" / "pm_qos_resume_latency_us").read_text()


def test_settings_hold_during_the_block_and_the_old_values_come_back(sysfs, monkeypatch):
    monkeypatch.setenv("PSNS_BENCH_RT_WQ_CPUS", "1")
    monkeypatch.setenv("PSNS_BENCH_RT_POLL_CPUS", "1")
    with bench_pty_jitter.host_tuning() as note:
        assert (sysfs / "cpumask").read_text() == "2"  # CPU 1 alone: bit 1
        assert _qos(sysfs, 1) == "n/a" and _qos(sysfs, 0) == "0\n"  # only the CPU asked for polls
        assert note == "unbound workqueues on CPU 1; CPU 1 polls when idle"
    assert (sysfs / "cpumask").read_text() == "3" and _qos(sysfs, 1) == "0"


def test_settings_come_back_when_the_run_raises(sysfs, monkeypatch):
    monkeypatch.setenv("PSNS_BENCH_RT_WQ_CPUS", "0,3")
    monkeypatch.setenv("PSNS_BENCH_RT_POLL_CPUS", "0,1")
    with pytest.raises(RuntimeError), bench_pty_jitter.host_tuning():
        assert (sysfs / "cpumask").read_text() == "9"
        assert _qos(sysfs, 0) == _qos(sysfs, 1) == "n/a"
        raise RuntimeError("the run failed")
    assert (sysfs / "cpumask").read_text() == "3" and _qos(sysfs, 0) == _qos(sysfs, 1) == "0"


def test_a_setting_that_cannot_be_written_undoes_the_ones_before_it(sysfs, monkeypatch):
    monkeypatch.setenv("PSNS_BENCH_RT_WQ_CPUS", "1")
    monkeypatch.setenv("PSNS_BENCH_RT_POLL_CPUS", "7")  # no such CPU: its file is missing
    with pytest.raises(FileNotFoundError), bench_pty_jitter.host_tuning():
        pass
    assert (sysfs / "cpumask").read_text() == "3"


def test_nothing_is_written_when_unset(sysfs):
    with bench_pty_jitter.host_tuning() as note:
        assert note == ""
    assert (sysfs / "cpumask").read_text() == "3\n" and _qos(sysfs, 1) == "0\n"  # not even rewritten


def test_dedicated_core_rows_run_under_their_set_up_and_leave_the_environment_as_it_was(monkeypatch):
    seen = {}

    def rows():
        seen.update({k: os.environ.get(k) for k in bench_pty_jitter.DEDICATED_CORE_ENV})
        return [{"name": "realtime uart0 frame-period jitter, p99", "value": 1.0}]

    monkeypatch.setattr(bench_pty_jitter, "_emulator_rows", rows)
    monkeypatch.setattr(bench_pty_jitter.os, "geteuid", lambda: 0)
    monkeypatch.setattr(bench_pty_jitter.os, "cpu_count", lambda: 2)
    monkeypatch.setenv("PSNS_BENCH_RT_FIFO", "reader")  # the user's own set-up for the first rows
    monkeypatch.delenv("PSNS_BENCH_RT_POLL_CPUS", raising=False)
    monkeypatch.delenv("PSNS_BENCH_RT_CORE", raising=False)
    out = bench_pty_jitter._dedicated_core_rows()
    assert seen == bench_pty_jitter.DEDICATED_CORE_ENV
    assert out == [{"name": "realtime uart0 frame-period jitter, p99, reader on a core of its own", "value": 1.0}]
    assert os.environ["PSNS_BENCH_RT_FIFO"] == "reader" and "PSNS_BENCH_RT_POLL_CPUS" not in os.environ
    monkeypatch.setenv("PSNS_BENCH_RT_CORE", "0")
    assert bench_pty_jitter._dedicated_core_rows() == []
    monkeypatch.delenv("PSNS_BENCH_RT_CORE")
    monkeypatch.setattr(bench_pty_jitter.os, "geteuid", lambda: 1000)  # not root: skipped, said on stderr
    assert bench_pty_jitter._dedicated_core_rows() == []
