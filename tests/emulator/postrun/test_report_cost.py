"""The report's cost is bounded by design (issue 41 item 3, docs/hostile-input.md section 8): ``events.jsonl`` is
streamed into per-kind aggregates and a flood of events is drawn as a rate histogram, not one line per event.

Before: one ``axvline`` per event; a 120 s host-command flood (348 156 events) took 4 min and 4.76 GB."""

from __future__ import annotations

import gc
import json
import os
import shutil
import subprocess
import sys
import tracemalloc
from pathlib import Path

import pytest

from emulator.postrun.report import MARKS_PER_KIND, digest_events
from tests.conftest import ROOT

#: host commands per second in the flood: the host port runs at 460 800 baud 8N1 (46 080 bytes/s), a
#: REQUEST_STATUS frame is 10 bytes, so a peer can send up to 4 608 per second; 1 300/s over 120 s, two events
#: each (the command and its STATUS answer, as the firmware reports them), is 312 000 events
FLOOD_COMMANDS_PER_S = 1300
FLOOD_EVENTS_MIN = 300_000


def _flood(events: Path, t0: float, t1: float) -> int:
    """Append a host-command flood over [t0, t1) s to ``events``, in the recorder's own line format."""
    n = int((t1 - t0) * FLOOD_COMMANDS_PER_S)
    with open(events, "a", encoding="utf-8") as f:
        for k in range(n):
            t = t0 + k / FLOOD_COMMANDS_PER_S
            f.write(json.dumps({"t_s": round(t, 9), "source": "firmware", "event": "command",
                                "command": "RequestStatus", "seq": k & 0xFFFF, "t_fpga_s": t, "accepted": True}) + "\n")
            f.write(json.dumps({"t_s": round(t, 9), "source": "firmware", "event": "status_sent", "seq": k & 0xFFFF,
                                "t_fpga_s": t}) + "\n")
    return 2 * n


def test_events_are_streamed_into_per_kind_aggregates(tmp_path):
    ev = tmp_path / "events.jsonl"
    ev.write_text('{"t_s": 1.0, "source": "fault", "event": "fault_start", "index": 0, "fault": "gnss_outage"}\n'
                  '{"t_s": 2.0, "source": "firmware", "event": "gnss_update", "n_meas": 5, "max_norm_innov": 0.5}\n'
                  '{"t_s": 3.0, "source": "fault", "event": "fault_end", "index": 0}\n'
                  '{"t_s": NaN, "source": "dsp", "event": "deadline_miss"}\n'
                  '[1, 2]\n'
                  '{"t_s": 4.0, "source": "firm\n', encoding="utf-8")
    with open(ev, "ab") as f:
        f.write(b'{"t_s": 5.0, "source": "dsp", "event": "\xff\xfe"}\n')
    n = _flood(ev, 10.0, 10.0 + 50_000 / FLOOD_COMMANDS_PER_S / 2)
    gc.collect()
    tracemalloc.start()
    d = digest_events(ev)
    _cur, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    assert len(d.faults) == 2 and list(d.gnss_t) == [2.0] and list(d.gnss_n) == [5.0]
    assert len(d.marks["command"]) + len(d.marks["status_sent"]) == n
    assert d.total == n + 5 and d.skipped == 2  # '[1, 2]' and the truncated line; the NaN time is not marked
    assert "deadline_miss" not in d.marks
    # 8 bytes per event (its time) plus array growth slack: never the events themselves (> 150 bytes each)
    assert peak < 16 * n + 1_000_000, f"peak {peak / 1e6:.1f} MB for {n} events"


def test_a_kind_with_many_events_is_one_histogram_not_one_line_each(monkeypatch):
    import matplotlib

    matplotlib.use("Agg")
    from array import array

    import emulator.postrun.report as rep

    digest = rep.EventDigest(marks={"command": array("d", [0.001 * k for k in range(50_000)]),
                                    "watchdog": array("d", [1.0, 2.0])})
    drawn: list[int] = []
    real_png = rep._png

    def count(fig):
        drawn.append(sum(len(ax.collections) + len(ax.lines) for ax in fig.axes))
        return real_png(fig)

    monkeypatch.setattr(rep, "_png", count)
    class _Nav(dict):  # every other nav.csv column: zeros
        def get(self, key, default=None):
            return super().get(key, [0.0, 0.0, 0.0])

    nav = _Nav(time_s=[0.0, 25.0, 50.0], mode=[1.0, 2.0, 2.0])
    figs = rep._nav_figures(nav, digest)
    titles = [t for t, _ in figs]
    assert titles[-2:] == ["Mode timeline", "Event rate"]
    # the timeline: 5 mode fills + one collection for the 2 watchdog marks; the rate figure: one step line
    assert drawn[-2] <= 5 + 1 and drawn[-1] <= 2
    assert MARKS_PER_KIND < 50_000


def _measure(cmd: list[str]) -> tuple[float, int]:
    """CPU seconds (user + system) and peak RSS (KB) of one child process (``os.wait4``: this child only)."""
    p = subprocess.Popen(cmd, cwd=ROOT, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _pid, status, ru = os.wait4(p.pid, 0)
    p.returncode = os.waitstatus_to_exitcode(status)
    err = p.stderr.read().decode(errors="replace") if p.stderr else ""
    assert p.returncode == 0, err
    return ru.ru_utime + ru.ru_stime, ru.ru_maxrss


@pytest.mark.slow
def test_report_of_a_300k_event_flood_costs_at_most_1_5x_a_clean_run(tmp_path):
    clean = tmp_path / "clean"
    r = subprocess.run([sys.executable, "-m", "emulator", "run", str(ROOT / "scenarios" / "quickstart.yaml"),
                        "--fast", "--quiet", "--no-report", "--out", str(clean)], cwd=ROOT, capture_output=True,
                       text=True)
    assert r.returncode == 0, r.stderr
    flood = tmp_path / "flood"
    shutil.copytree(clean, flood)
    duration = json.loads((clean / "summary.json").read_text())["sim_duration_s"]
    n = _flood(flood / "events.jsonl", 0.0, duration)
    assert n >= FLOOD_EVENTS_MIN
    report = [sys.executable, "-m", "emulator", "report"]
    cpu_clean, rss_clean = _measure([*report, str(clean)])
    cpu_flood, rss_flood = _measure([*report, str(flood)])
    assert cpu_flood <= 1.5 * cpu_clean, f"{n} events: {cpu_flood:.2f} s vs {cpu_clean:.2f} s clean"
    assert rss_flood <= 1.5 * rss_clean, f"{n} events: {rss_flood / 1e3:.0f} MB vs {rss_clean / 1e3:.0f} MB clean"
    assert "Event rate" in (flood / "report.html").read_text()
