"""Where a realtime frame's time goes between its instant and the reader (docs/performance.md 5.9, D-10.E12).

Runs the realtime benchmark's scenario (:func:`benchmarks.bench_pty_jitter._rt_scenario`: the reference on
``pty://host`` and the MONITOR pty mirroring ``uart1``) with the reader process of
:mod:`benchmarks.bench_pty_jitter`, and records per frame, on the ``CLOCK_MONOTONIC`` clock:

* its **deadline**: the wall instant the loop handed its last chunk to the paced writer for
  (``PacedWriter.put_bytes``; the frame's bytes decoded from the chunks as they are put);
* the writer process's **lateness** for each MONITOR chunk (one chunk per IMU frame; ``PacedWriter.on_late``);
* its **arrival** at the reader (after ``os.read``).

It prints, per tap, the frame-period jitter |period - nominal| (p50 / p99 / p99.9) at the reader, of the
deadlines alone, of arrival - deadline, and (MONITOR) of arrival - deadline - the writer's lateness: what the
emulator's model puts into the cadence, against what happens after the write.

``--ftrace`` (Linux, root, tracefs mounted at ``/sys/kernel/tracing``: ``mount -t tracefs nodev
/sys/kernel/tracing`` where it is not) also records the scheduler and the
workqueue events of the run (``sched_switch``, ``sched_wakeup``, ``workqueue_queue_work``,
``workqueue_execute_start``; ``trace_clock`` ``mono``) and splits each MONITOR write's path into: the writer's
write (its ``queue_work`` of the pty's ``flush_to_ldisc``) -> the kernel worker starting it -> the reader woken ->
the reader running -> its ``os.read`` returned; for the writes whose kernel worker or reader waited more than
0.3 ms, it lists what ran on that CPU meanwhile (the emulator's loop thread, its writer process, other processes).
The tracing settings are restored afterwards.

Usage: ``python -m studies.scripts.trace_pty_path SECONDS [--ftrace] [--out FILE.json]``; the environment of
:mod:`benchmarks.bench_pty_jitter` applies (the sessions, pinning and ``PSNS_BENCH_RT_FIFO`` / ``PSNS_BENCH_RT_IDLE``
of its :func:`~benchmarks.bench_pty_jitter.start_emulator_and_reader`, the host settings of its
:func:`~benchmarks.bench_pty_jitter.host_tuning`; ``PSNS_BENCH_RT_LEAD_S``, ``PSNS_PACED_WRITER``).
"""

from __future__ import annotations

import bisect
import collections
import itertools
import json
import os
import re
import sys
import tempfile
import time
from pathlib import Path

import yaml

from benchmarks.bench_pty_jitter import (
    TAP_PERIOD_S,
    _children,
    _quantile,
    _rt_scenario,
    host_tuning,
    start_emulator_and_reader,
)

TRACEFS = Path("/sys/kernel/tracing")
_EVENTS = ("sched/sched_switch", "sched/sched_wakeup", "workqueue/workqueue_queue_work",
           "workqueue/workqueue_execute_start")
SLOW_S = 3e-4  # a step that took longer is listed with what ran on its CPU meanwhile

_EMULATOR = r"""
import json, os, sys
from pathlib import Path
from emulator.paced_writer import PacedWriter
from emulator.assembly.session import run_scenario
from emulator.scenario import load_scenario
from protocols.host import HostFormat, NavSolution
from protocols.imu_frame import ImuFrameFormat
from protocols.monitor import MonitorFormat
from protocols.stream import StreamDecoder
if os.environ.get("PSNS_BENCH_RT_LEAD_S"):
    import emulator.assembly.session as _session
    _session.REALTIME_LEAD_S = float(os.environ["PSNS_BENCH_RT_LEAD_S"])
dec = {"host": StreamDecoder([HostFormat()]), "monitor": StreamDecoder([MonitorFormat()])}
imu = ImuFrameFormat()
deadlines = {"uart0": [], "uart1": []}  # (seq, deadline)
late = []  # the writer's lateness of each MONITOR chunk, in order
_put = PacedWriter.put_bytes
def put_bytes(self, at, peer, data, _put=_put):
    d = dec.get(peer.name)
    if d is not None:
        for fr in d.feed(data):
            if peer.name == "host" and isinstance(fr, NavSolution):
                deadlines["uart0"].append((fr.seq, at))
            elif peer.name == "monitor" and fr.direction == 0:
                deadlines["uart1"].append((imu.parse(bytes(fr.data)).seq, at))
    return _put(self, at, peer, data)
PacedWriter.put_bytes = put_bytes
def _on_late(owner, s):
    if getattr(owner, "name", "") == "monitor":
        late.append(s)
PacedWriter.on_late = staticmethod(_on_late)
s = run_scenario(load_scenario(sys.argv[1]), Path(sys.argv[2]), mode="realtime")
Path(sys.argv[3]).write_text(json.dumps({"passed": s["passed"], "paced_writer": s.get("paced_writer"),
                                         "deadlines": deadlines, "late": late}))
"""


def _tracefs(settings: dict[str, str]) -> dict[str, str]:
    """Write ``settings`` (file -> value) under :data:`TRACEFS`, in order; returns the previous values (the one in
    brackets for ``trace_clock``, the size asked for for ``buffer_size_kb``)."""
    old = {}
    for name, value in settings.items():
        p = TRACEFS / name
        text = p.read_text()
        m = re.search(r"\[(\w+)\]", text)
        old[name] = m.group(1) if m else (text.split() or [""])[0]
        p.write_text(value)
    return old


def record(duration_s: float, ftrace: bool) -> dict:
    """One run: the per-frame record (and the raw trace's lines when ``ftrace``)."""
    with tempfile.TemporaryDirectory() as d:
        dp = Path(d)
        scn = dp / "rt.yaml"
        scn.write_text(yaml.safe_dump(_rt_scenario(duration_s), sort_keys=False))
        run_dir, taps, emu_out = dp / "run", dp / "taps.json", dp / "emulator.json"
        old: dict[str, str] = {}
        if ftrace:
            old = _tracefs({"tracing_on": "0", "trace": "", "trace_clock": "mono", "buffer_size_kb": "30000",
                            **{f"events/{e}/enable": "1" for e in _EVENTS}})
            (TRACEFS / "tracing_on").write_text("1")
        try:
            with host_tuning():
                emu, rdr = start_emulator_and_reader(_EMULATOR, scn, run_dir, emu_out, taps, duration_s)
                while not (run_dir / "ports" / "monitor").exists() and emu.poll() is None:
                    time.sleep(0.01)
                time.sleep(0.5)
                kids = _children(emu.pid)
                _so, se = emu.communicate()
                rdr.wait(timeout=60)
        finally:
            if ftrace:
                (TRACEFS / "tracing_on").write_text("0")
        if emu.returncode != 0:
            raise RuntimeError(f"realtime emulator run failed:\n{se[-3000:]}")
        res = json.loads(emu_out.read_text())
        res["seen"] = json.loads(taps.read_text())
        res["pids"] = {"emulator": emu.pid, "reader": rdr.pid, "writer": kids[0] if kids else None}
        res["load"] = os.getloadavg()
        if ftrace:
            res["trace"] = (TRACEFS / "trace").read_text().splitlines()
            for e in _EVENTS:
                (TRACEFS / f"events/{e}/enable").write_text("0")
            _tracefs({"trace": "", "trace_clock": old["trace_clock"], "buffer_size_kb": old["buffer_size_kb"],
                      "tracing_on": old["tracing_on"]})
    return res


def _spread(v: list[float]) -> str:
    v = sorted(v)
    return f"{_quantile(v, 0.5):.3f} / {_quantile(v, 0.99):.3f} / {_quantile(v, 0.999):.2f}" if v else "-"


def cadence(res: dict) -> list[str]:
    """Per tap: the period jitter at the reader, of the deadlines, after the deadline, after the writer's write."""
    out = []
    for tap in ("uart0", "uart1"):
        period = TAP_PERIOD_S[tap]
        dls = res["deadlines"][tap]
        idx = {s: i for i, (s, _at) in enumerate(dls)}
        late = res["late"] if tap == "uart1" and len(res["late"]) == len(dls) else None
        seen = [x for x in res["seen"][tap] if x[1] in idx][50:]  # the first ones: the reader attaching
        j_rd, j_dl, j_post, j_wr = [], [], [], []
        for (t0, s0), (t1, s1) in itertools.pairwise(seen):
            if (s1 - s0) % 65536 != 1:
                continue
            i0, i1 = idx[s0], idx[s1]
            d0, d1 = t0 - dls[i0][1], t1 - dls[i1][1]
            j_rd.append(abs(t1 - t0 - period) * 1e3)
            j_dl.append(abs(dls[i1][1] - dls[i0][1] - period) * 1e3)
            j_post.append(abs(d1 - d0) * 1e3)
            if late is not None:
                j_wr.append(abs((d1 - late[i1]) - (d0 - late[i0])) * 1e3)
        off = sum(abs(x) > 1e-3 for x in j_dl)
        out.append(f"{tap}: |period - {period * 1e3:g} ms| p50 / p99 / p99.9 (ms): at the reader {_spread(j_rd)}; "
                   f"the deadlines alone {_spread(j_dl)} ({off} of {len(j_dl)} periods off by > 1 us); "
                   f"after the deadline {_spread(j_post)}; after the writer's write {_spread(j_wr)}")
    return out


_LINE = re.compile(r"^\s*(.+?)-(\d+)\s+\[(\d+)\]\s+\S+\s+([\d.]+): (\w+): (.*)$")
_SWITCH = re.compile(r"prev_pid=(\d+) .*==> next_comm=(.*) next_pid=(\d+) next_prio=(-?\d+)")


def kernel_path(res: dict) -> list[str]:
    """The MONITOR writes' path through the kernel and the reader, from the trace (``--ftrace``)."""
    pids = res["pids"]
    writer, reader = pids["writer"], pids["reader"]
    queued: dict[str, list[float]] = collections.defaultdict(list)
    started: dict[str, list[tuple[float, int]]] = collections.defaultdict(list)
    wakes: list[float] = []
    runs: list[tuple[float, int]] = []
    switches: dict[int, list[tuple[float, str, int, int]]] = collections.defaultdict(list)
    for ln in res["trace"]:
        m = _LINE.match(ln)
        if not m:
            continue
        pid, cpu, t, ev, rest = int(m.group(2)), int(m.group(3)), float(m.group(4)), m.group(5), m.group(6)
        if ev == "workqueue_queue_work" and "flush_to_ldisc" in rest and pid == writer:
            queued[re.search(r"work struct=(\w+)", rest).group(1)].append(t)  # type: ignore[union-attr]
        elif ev == "workqueue_execute_start" and "flush_to_ldisc" in rest:
            started[re.search(r"work struct (\w+):", rest).group(1)].append((t, cpu))  # type: ignore[union-attr]
        elif ev == "sched_wakeup" and f"pid={reader} " in rest:
            wakes.append(t)
        elif ev == "sched_switch":
            s = _SWITCH.search(rest)
            if s:
                switches[cpu].append((t, s.group(2), int(s.group(3)), int(s.group(4))))
                if int(s.group(3)) == reader:
                    runs.append((t, cpu))
    if not queued:
        return ["no flush_to_ldisc work queued by the writer process in the trace"]
    mon = max(queued, key=lambda k: len(queued[k]))  # 200 Hz: the MONITOR pty's buffer (the host's is 100 Hz)
    dl = sorted(at for _s, at in res["deadlines"]["uart1"])
    arrivals = sorted(t for t, _s in res["seen"]["uart1"])
    st = sorted(started[mon])
    st_t = [x[0] for x in st]
    run_t = [x[0] for x in runs]

    def after(ts: list[float], t: float) -> int | None:
        i = bisect.bisect_left(ts, t)
        return i if i < len(ts) else None

    rows = []
    for tq in queued[mon][100:]:
        i = after(st_t, tq)
        j = None if i is None else after(wakes, st_t[i])
        k = None if j is None else after(run_t, wakes[j])
        a = None if k is None else after(arrivals, run_t[k])
        n = bisect.bisect_right(dl, tq + 1e-9) - 1
        if None in (i, j, k, a) or n < 0:
            continue
        assert i is not None and j is not None and k is not None and a is not None
        rows.append({"write": tq - dl[n], "worker": st_t[i] - tq, "wake": wakes[j] - st_t[i],
                     "run": run_t[k] - wakes[j], "read": arrivals[a] - run_t[k], "total": arrivals[a] - dl[n],
                     "worker_cpu": st[i][1], "run_cpu": runs[k][1], "t_queued": tq, "t_started": st_t[i],
                     "t_woken": wakes[j], "t_run": run_t[k]})
    names = {"write": "the writer's write after the deadline", "worker": "the kernel worker starting after it",
             "wake": "the reader woken after that", "run": "the reader running after its wake-up",
             "read": "its read returned after that", "total": "arrival after the deadline"}
    out = [f"{len(rows)} MONITOR writes, ms p50 / p99 / max:"]
    for key, what in names.items():
        v = sorted(r[key] * 1e3 for r in rows)
        out.append(f"  {what}: {_quantile(v, 0.5):.3f} / {_quantile(v, 0.99):.3f} / {v[-1]:.2f}")
    tags = {pids["emulator"]: "the emulator's loop thread", writer: "the writer process", reader: "the reader"}
    steps = (("worker", ("t_queued", "t_started", "worker_cpu")), ("run", ("t_woken", "t_run", "run_cpu")))
    for key, (t0_key, t1_key, cpu_key) in steps:
        slow = [r for r in rows if r[key] > SLOW_S]
        busy: collections.Counter[tuple[str, int, int]] = collections.Counter()
        for r in slow:
            sw = switches[r[cpu_key]]
            ts = [s[0] for s in sw]
            x = max(0, bisect.bisect_right(ts, r[t0_key]) - 1)
            while x < len(sw) and sw[x][0] < r[t1_key]:
                lo, hi = max(sw[x][0], r[t0_key]), min(sw[x + 1][0] if x + 1 < len(sw) else r[t1_key], r[t1_key])
                if hi > lo:
                    busy[(sw[x][1], sw[x][2], sw[x][3])] += hi - lo
                x += 1
        top = ", ".join(f"{tags.get(pid, f'{comm} (pid {pid}, prio {prio})')} {s * 1e3:.0f} ms"
                        for (comm, pid, prio), s in busy.most_common(5))
        out.append(f"  {names[key]} > {SLOW_S * 1e3:g} ms: {len(slow)} writes ({100 * len(slow) / len(rows):.1f} %); "
                   f"on that CPU meanwhile: {top}")
    return out


def main(argv: list[str]) -> int:
    if not argv or argv[0].startswith("-"):
        print(__doc__)
        return 2
    dur = float(argv[0])
    ftrace = "--ftrace" in argv
    res = record(dur, ftrace)
    print(f"{dur:g} s, load {', '.join(f'{x:.2f}' for x in res['load'])}, paced writer {res['paced_writer']}")
    for ln in cadence(res):
        print(ln)
    if ftrace:
        for ln in kernel_path(res):
            print(ln)
    if "--out" in argv:
        Path(argv[argv.index("--out") + 1]).write_text(json.dumps(res))
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main(sys.argv[1:]))
