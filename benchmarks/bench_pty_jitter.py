"""Realtime mode on ptys: frame-period jitter at the UART0 and UART1 taps, dropped frames, CPU.

Two measurements.

1. **The whole emulator in realtime mode** (the realtime target): the reference scenario
   (``scenarios/bench_vehicle_loop_10min.yaml``: IMU 200 Hz, GNSS, camera PSNS 5 Hz, base filter)
   with the host port on ``pty://host`` (DSP UART0's navigation frames, 100 Hz, through the FPGA)
   and the FPGA MONITOR port on ``pty://monitor`` (3 Mbaud) mirroring the ``uart1`` channel (the
   FPGA's IMU frames to DSP UART1, 200 Hz). The emulator runs in its own process; a reader
   process opens both pty slaves with ``os.open`` (raw mode), as a serial tool would, blocks in
   ``select`` and time-stamps every read (``CLOCK_MONOTONIC``). Per tap: the period between
   successive frames' arrivals minus the nominal period (|jitter| p50 / p99 / max), and dropped
   frames (gaps in the frames' sequence numbers after the first one read). The emulator process's
   CPU (``/proc/PID/stat`` utime + stime over the measured wall time, start-up excluded) against the
   target of 30 % of one core. The emulator's own part: how late each tap's chunk was written to its
   pty against the instant its scenario time stands for (the paced writer of D-10.E6, or without a
   lead the loop's callback), and how late the loop ran against its own schedule (what the lead
   absorbs). ``PSNS_BENCH_RT_S`` sets the duration (wall s; default 600, the issue's 10 min;
   ``make bench-quick``: 30); ``PSNS_BENCH_RT_LEAD_S`` the lead (``0``: none); ``PSNS_PACED_WRITER``
   (``process`` | ``thread``) the paced writer's backend (D-10.E11; the emulator's CPU includes its writer
   process's), ``PSNS_PACED_WRITER_CPUS`` pins that process;
   ``PSNS_BENCH_RT_EMU_CPUS`` / ``PSNS_BENCH_RT_READER_CPUS`` pin the two processes (``1`` / ``0``);
   ``PSNS_BENCH_RT_FIFO`` / ``PSNS_BENCH_RT_IDLE`` (``emu``, ``reader``, ``emu+reader``) start those processes at
   ``SCHED_FIFO`` 1 / ``SCHED_IDLE``; ``PSNS_BENCH_RT_SESSION`` (``own`` | ``shared``) starts each in a
   session of its own or both in the benchmark's (D-10.E13); ``PSNS_BENCH_RT_WQ_CPUS`` (root) confines the
   kernel's unbound workqueues, where a pty's flip-buffer work runs, to these CPUs for the run, and
   ``PSNS_BENCH_RT_POLL_CPUS`` (root) makes these CPUs poll instead of halting when idle (:func:`host_tuning`,
   D-10.E14); the note says what was run. As root on two or more CPUs the rows are measured once more with
   the reader on a core of its own (:data:`DEDICATED_CORE_ENV`; ``PSNS_BENCH_RT_CORE=0`` skips them).
2. **One pty link alone** (the floor): a :class:`~emulator.links.pty.PtyLink` at 460 800 baud (8N1)
   on a realtime :class:`~emulator.clock.EmulatorLoop` with the session's lead (its bytes written by
   the paced writer) sends a 109-byte host frame every 10 ms,
   each paced by the line model (2.37 ms on the wire, written in 1 ms slices). A pyserial reader
   time-stamps every read. For each frame the *lateness* is the arrival of its last byte minus the
   instant the line model says its last stop bit ends: median, p99 and max over 300 frames,
   against the raw-pty latency measured without the emulator (``docs/reference/wire-formats.md``
   5.2: paced 40-byte frames, median 16 us, p99 121 us).
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import os
import statistics
import subprocess
import sys
import tempfile
from collections.abc import Iterator
from pathlib import Path
from unittest import mock

N_FRAMES = 300
PERIOD_S = 0.01
BAUD = 460800
RAW_PTY_P99_US = 121.0  # docs/reference/wire-formats.md 5.2, paced frames, reader on the event loop
RAW_PTY_MEDIAN_US = 16.0


_READER = r"""
import sys, time, serial
from protocols.host import HostFormat
from protocols.stream import StreamDecoder
ser = serial.Serial(sys.argv[1], int(sys.argv[2]), timeout=0.2)
dec = StreamDecoder([HostFormat()])
print("ready", flush=True)
idle = 0
while idle < 5:
    try:
        data = ser.read(1)  # blocks until a byte arrives (or the timeout), then takes what is there
    except serial.SerialException:
        break  # the emulator closed the pty
    if not data:
        idle += 1
        continue
    idle = 0
    t = time.monotonic()
    n = ser.in_waiting
    if n:
        data += ser.read(n)
    for f in dec.feed(data):
        print(t, int.from_bytes(f.payload[:4], "little"))
"""


def _measure() -> list[float]:
    from emulator.assembly.session import REALTIME_LEAD_S
    from emulator.clock import EmulatorLoop
    from emulator.links import LineConfig
    from emulator.links.pty import PtyLink
    from protocols.host import build_host_frame

    loop = EmulatorLoop("realtime")
    lead = float(os.environ.get("PSNS_BENCH_RT_LEAD_S") or REALTIME_LEAD_S)
    if lead > 0:
        loop.set_lead(lead)
    asyncio.set_event_loop(loop)
    expected: dict[int, float] = {}  # seq -> CLOCK_MONOTONIC time its last stop bit ends
    out: list[str] = []

    async def main() -> None:
        with tempfile.TemporaryDirectory() as d:
            link = PtyLink("host", "pty://host", LineConfig(baud=BAUD), loop, target="host", run_dir=Path(d) / "ports")
            await link.open()
            # the reader is another process, as a real tool would be (CLOCK_MONOTONIC is system-wide)
            proc = await asyncio.create_subprocess_exec(sys.executable, "-c", _READER, str(link.link_path), str(BAUD),
                                                        stdout=asyncio.subprocess.PIPE)
            assert proc.stdout is not None
            await proc.stdout.readline()
            while not link.attached:
                await asyncio.sleep(0.005)
            t0 = loop.time() + 0.05
            for k in range(N_FRAMES):
                await asyncio.sleep(max(0.0, t0 + k * PERIOD_S - loop.time()))
                link.send(build_host_frame(0x7F, k.to_bytes(4, "little") + bytes(98)))
                expected[k] = loop.wall_at(link.busy_until())
            await asyncio.sleep(0.05)
            await link.close()
            text, _ = await proc.communicate()
            out.extend(text.decode().splitlines())

    try:
        loop.run_until_complete(main())
    finally:
        asyncio.set_event_loop(None)
        loop.close()
    late = []
    for ln in out:
        t, seq = ln.split()
        if int(seq) in expected:
            late.append((float(t) - expected[int(seq)]) * 1e6)
    return late


def _link_rows() -> list[dict]:
    late = sorted(_measure())
    if not late:
        return [{"name": "pty frame lateness", "value": float("nan"), "unit": "us", "baseline": RAW_PTY_P99_US,
                 "ratio": None, "note": "no frame arrived"}]
    p = lambda q: late[min(len(late) - 1, int(q * len(late)))]  # noqa: E731
    med = statistics.median(late)
    return [
        {"name": "pty frame lateness, median", "value": med, "unit": "us", "baseline": RAW_PTY_MEDIAN_US,
         "ratio": med / RAW_PTY_MEDIAN_US, "note": f"{len(late)} frames of 109 B at 460800 baud, 100 Hz, realtime"},
        {"name": "pty frame lateness, p99", "value": p(0.99), "unit": "us", "baseline": RAW_PTY_P99_US,
         "ratio": p(0.99) / RAW_PTY_P99_US,
         "note": "baseline: raw pty without the emulator (docs/reference/wire-formats.md 5.2)"},
        {"name": "pty frame lateness, max", "value": late[-1], "unit": "us", "baseline": None, "ratio": None,
         "note": f"min {late[0]:.0f} us (negative = before the modelled end: a read woke mid-frame)"},
    ]


# -- 1. the whole emulator in realtime mode ----------------------------------------------------------
RT_TARGET_CPU_PCT = 30.0
RT_TARGET_P99_US = 1000.0
TAP_PERIOD_S = {"uart0": 0.01, "uart1": 0.005}

_TAP_READER = r"""
import json, os, select, sys, time, tty
from protocols.host import HostFormat, NavSolution
from protocols.imu_frame import ImuFrameFormat
from protocols.monitor import MONITOR_CHANNELS, MonitorFormat
from protocols.stream import StreamDecoder
host_path, mon_path, out_path, limit = sys.argv[1], sys.argv[2], sys.argv[3], float(sys.argv[4])
while not (os.path.exists(host_path) and os.path.exists(mon_path)):
    time.sleep(0.01)
fds = {}
for name, path in (("uart0", host_path), ("monitor", mon_path)):
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
    tty.setraw(fd)
    fds[fd] = name
dec = {"uart0": StreamDecoder([HostFormat()]), "monitor": StreamDecoder([MonitorFormat()])}
imu = ImuFrameFormat()
ch_uart1 = MONITOR_CHANNELS["uart1"]
seen = {"uart0": [], "uart1": []}
t_end = time.monotonic() + limit
open_fds = set(fds)
while open_fds and time.monotonic() < t_end:
    ready, _, _ = select.select(list(open_fds), [], [], 1.0)
    for fd in ready:
        try:
            data = os.read(fd, 65536)
        except OSError:  # EIO: the emulator closed the pty
            open_fds.discard(fd)
            continue
        t = time.monotonic()
        if not data:
            open_fds.discard(fd)
            continue
        for fr in dec[fds[fd]].feed(data):
            if fds[fd] == "uart0":
                if isinstance(fr, NavSolution):
                    seen["uart0"].append((t, fr.seq))
            elif fr.channel == ch_uart1 and fr.direction == 0:
                try:
                    seen["uart1"].append((t, imu.parse(bytes(fr.data)).seq))
                except Exception:
                    pass
with open(out_path, "w") as f:
    json.dump(seen, f)
"""

_EMULATOR = r"""
import asyncio, json, os, sys, time
from pathlib import Path
from emulator.paced_writer import PacedWriter
from emulator.links.base import Link
from emulator.assembly.session import run_scenario
from emulator.scenario import load_scenario
TAPS = {"host": "uart0", "monitor": "uart1"}  # the ptys the reader reads
# emulator-side lateness: when each tap's chunk really went out (os.write on its pty) against the instant its
# scenario time stands for. With the loop computing ahead (the paced writer) that is the writer's write; without
# it, the loop's callback handing the chunk on. Loop-side: when that callback ran against its own schedule
# (earlier by the lead when there is one): what the lead has to absorb.
late = {"uart0": [], "uart1": []}
loop_late = {"uart0": [], "uart1": []}
_orig = Link._emit
def _emit(self, data, start, pitch, _orig=_orig, mono=time.monotonic):
    tap = "uart0" if self.name == "host" else "uart1" if self.name == "uart1" else None
    if tap is not None:  # a chunk's last stop bit, run by the loop at its scenario time (time(): its own instant)
        loop = self.loop
        t = mono() - loop.wall_at(loop.time())
        loop_late[tap].append(t + loop.lead_s)
        if loop.writer is None:
            late[tap].append(t)
    return _orig(self, data, start, pitch)
Link._emit = _emit
if os.environ.get("PSNS_BENCH_RT_LEAD_S"):  # the lead of the realtime loop (wall s; 0: none, the loop writes)
    import emulator.assembly.session as _session
    _session.REALTIME_LEAD_S = float(os.environ["PSNS_BENCH_RT_LEAD_S"])
if os.environ.get("PSNS_BENCH_RT_WRITER_PRIO"):  # the writer thread's SCHED_FIFO priority ("none": normal policy)
    _p = os.environ["PSNS_BENCH_RT_WRITER_PRIO"]
    PacedWriter.RT_PRIORITY = None if _p == "none" else int(_p)
def _on_late(owner, late_s):  # either backend: the thread's write, or the writer process's (reported back)
    tap = TAPS.get(getattr(owner, "name", ""))
    if tap is not None:
        late[tap].append(late_s)
PacedWriter.on_late = staticmethod(_on_late)
s = run_scenario(load_scenario(sys.argv[1]), Path(sys.argv[2]), mode="realtime")
Path(sys.argv[3]).write_text(json.dumps({"passed": s["passed"], "deadline_misses": s["dsp"]["deadline_misses"],
                                         "nav_frames": s["nav_frames"], "late": late, "loop_late": loop_late}))
"""


def _rt_scenario(duration_s: float) -> dict:
    import yaml

    from benchmarks.bench_scaling import scenario_for

    data = scenario_for(max(duration_s, 60.0))
    data.update(name="bench_pty_realtime", mode="realtime", duration_s=float(duration_s))
    data["links"] = dict(data["links"], host={"url": "pty://host", "baud": 460800},
                         monitor={"url": "pty://monitor", "baud": 3000000})
    data["fpga"] = {"monitor_channels": ["uart1"]}
    # the reader attaches a few ms into the run: no expectation on the host and monitor ports
    data["expectations"] = [e for e in data["expectations"]
                            if "dsp" in e or ("nav_error" in e and duration_s >= 60)
                            or ("link" in e and e["link"]["name"] in ("gyro", "gnss", "psns", "uart1", "uart2"))]
    return yaml.safe_load(yaml.safe_dump(data))


def _cpus(var: str) -> set[int]:
    """CPU numbers from the environment variable ``var`` (``"1"``, ``"0,1"``; unset or empty: no pinning)."""
    return {int(x) for x in os.environ.get(var, "").split(",") if x.strip()}


def _cpu_s(pid: int) -> float | None:
    try:
        with open(f"/proc/{pid}/stat") as f:
            parts = f.read().rsplit(")", 1)[1].split()
    except OSError:
        return None
    return (int(parts[11]) + int(parts[12])) / os.sysconf("SC_CLK_TCK")


def _children(pid: int) -> list[int]:
    """The child processes of ``pid`` (``/proc/PID/task/*/children``, Linux), recursively."""
    kids: list[int] = []
    try:
        tasks = os.listdir(f"/proc/{pid}/task")
    except OSError:
        return kids
    for t in tasks:
        try:
            with open(f"/proc/{pid}/task/{t}/children") as f:
                kids.extend(int(x) for x in f.read().split())
        except OSError:
            pass
    return kids + [g for k in kids for g in _children(k)]


def _tree_cpu_s(pid: int) -> tuple[float | None, float]:
    """CPU seconds of ``pid`` and its live children (the paced writer's process), and the children's part."""
    own = _cpu_s(pid)
    kids = sum(c for c in (_cpu_s(k) for k in _children(pid)) if c is not None)
    return (None if own is None else own + kids), kids


def _quantile(ordered: list[float], q: float) -> float:
    """The q-quantile (0..1) of an ascending list by the nearest-rank rule; NaN for an empty list."""
    return ordered[min(len(ordered) - 1, int(q * len(ordered)))] if ordered else float("nan")


def _tap_stats(samples: list, period: float) -> dict:
    jit = []
    dropped = 0
    for (t0, s0), (t1, s1) in itertools.pairwise(samples):
        gap = (s1 - s0) % 65536
        if gap == 1:
            jit.append(abs((t1 - t0) - period) * 1e6)
        elif gap > 1:
            dropped += gap - 1
    jit.sort()
    q = lambda x: jit[min(len(jit) - 1, int(x * len(jit)))] if jit else float("nan")  # noqa: E731
    return {"frames": len(samples), "dropped": dropped, "p50": q(0.5), "p99": q(0.99),
            "max": jit[-1] if jit else float("nan")}


WORKQUEUE_CPUMASK = Path("/sys/devices/virtual/workqueue/cpumask")
CPU_SYSFS = Path("/sys/devices/system/cpu")


@contextlib.contextmanager
def host_tuning() -> Iterator[str]:
    """Set the host for the realtime run as the environment asks, and put every setting back after the block, also
    when it raises (root: sysfs files; unset or empty variables change nothing). Yields the description for the
    benchmark's note (``""`` when nothing was set). D-10.E14.

    * ``PSNS_BENCH_RT_WQ_CPUS`` (``"1"``, ``"0,1"``): the kernel's unbound workqueues run on these CPUs only. A pty
      write queues its flip-buffer work (``flush_to_ldisc``, which hands the bytes to the reader's line discipline
      and wakes it) on ``system_unbound_wq`` (Linux ``drivers/tty/tty_buffer.c``), so this decides whether the
      hand-over runs on the reader's CPU or on the one the emulator's loop computes on.
    * ``PSNS_BENCH_RT_POLL_CPUS``: these CPUs poll instead of halting when idle (their PM QoS resume latency
      ``n/a``, i.e. 0 us: ``/sys/devices/system/cpu/cpuN/power/pm_qos_resume_latency_us``; the per-CPU form of
      what ``cyclictest`` does with ``/dev/cpu_dma_latency``). In a VM a halted vCPU leaves the guest, and a task
      woken on it waits until the host runs the vCPU again (up to 6.5 ms seen here, D-10.E14); a polling vCPU runs
      it at once, at the price of a busy core.
    """
    writes: list[tuple[Path, str, str]] = []
    wq = _cpus("PSNS_BENCH_RT_WQ_CPUS")
    if wq:
        writes.append((WORKQUEUE_CPUMASK, format(sum(1 << c for c in wq), "x"),
                       f"unbound workqueues on CPU {','.join(map(str, sorted(wq)))}"))
    for c in sorted(_cpus("PSNS_BENCH_RT_POLL_CPUS")):
        writes.append((CPU_SYSFS / f"cpu{c}" / "power" / "pm_qos_resume_latency_us", "n/a", f"CPU {c} polls when idle"))
    done: list[tuple[Path, str]] = []
    try:
        for path, value, _what in writes:
            before = path.read_text().strip()
            path.write_text(value)
            done.append((path, before))
        yield "; ".join(what for _p, _v, what in writes)
    finally:
        for path, before in reversed(done):
            path.write_text(before)


def _own_sessions() -> bool:
    """Whether the emulator and the reader each run in a session of their own (``PSNS_BENCH_RT_SESSION``: ``own``,
    the default, as when a user starts ``psns-hil run`` in one terminal and the serial tool in another;
    ``shared``: both in the benchmark's session, as before D-10.E13). With ``kernel.sched_autogroup_enabled`` a
    session is a scheduling group, so this decides whether the woken reader competes with the emulator's loop
    inside one group or as a group of its own."""
    mode = os.environ.get("PSNS_BENCH_RT_SESSION", "own")
    if mode not in ("own", "shared"):
        raise ValueError(f"PSNS_BENCH_RT_SESSION must be 'own' or 'shared', not {mode!r}")
    return mode == "own"


def start_emulator_and_reader(emulator_script: str, scn: Path, run_dir: Path, emu_out: Path, taps_out: Path,
                              duration_s: float) -> tuple[subprocess.Popen[str], subprocess.Popen[bytes]]:
    """Start the realtime emulator (``python -c emulator_script SCENARIO RUN_DIR EMU_OUT``) and the tap reader
    (:data:`_TAP_READER`, writing ``taps_out``) as the environment asks: each in a session of its own or both in
    this one (:func:`_own_sessions`, D-10.E13), pinned (``PSNS_BENCH_RT_EMU_CPUS`` / ``PSNS_BENCH_RT_READER_CPUS``)
    and at ``SCHED_FIFO`` 1 / ``SCHED_IDLE`` (``PSNS_BENCH_RT_FIFO`` / ``PSNS_BENCH_RT_IDLE``: ``emu``, ``reader``,
    ``emu+reader``). One place for the benchmark and :mod:`studies.scripts.trace_pty_path`."""
    own = _own_sessions()
    emu = subprocess.Popen([sys.executable, "-c", emulator_script, str(scn), str(run_dir), str(emu_out)],
                           stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=own)
    rdr = subprocess.Popen([sys.executable, "-c", _TAP_READER, str(run_dir / "ports" / "host"),
                            str(run_dir / "ports" / "monitor"), str(taps_out), str(duration_s + 120)],
                           start_new_session=own)
    fifo, idle = (set(os.environ.get(v, "").replace("+", ",").split(",")) for v in ("PSNS_BENCH_RT_FIFO",
                                                                                     "PSNS_BENCH_RT_IDLE"))
    for proc, var, who in ((emu, "PSNS_BENCH_RT_EMU_CPUS", "emu"), (rdr, "PSNS_BENCH_RT_READER_CPUS", "reader")):
        cpus = _cpus(var)
        if cpus:
            os.sched_setaffinity(proc.pid, cpus)  # before the interpreter starts its threads: they inherit it
        if who in fifo:  # the stand-in for a core of its own: no ordinary process can take the CPU from it
            os.sched_setscheduler(proc.pid, os.SCHED_FIFO, os.sched_param(1))
        elif who in idle:  # any woken task preempts it at once (its writer process raises itself to FIFO)
            os.sched_setscheduler(proc.pid, os.SCHED_IDLE, os.sched_param(0))
    return emu, rdr


def _measure_emulator(duration_s: float) -> tuple[dict, dict, float, str]:
    import json
    import time

    import yaml

    with tempfile.TemporaryDirectory() as d, host_tuning() as tuned:
        dp = Path(d)
        scn = dp / "rt.yaml"
        scn.write_text(yaml.safe_dump(_rt_scenario(duration_s), sort_keys=False))
        run_dir = dp / "run"
        out = dp / "taps.json"
        emu_out = dp / "emulator.json"
        emu, rdr = start_emulator_and_reader(_EMULATOR, scn, run_dir, emu_out, out, duration_s)
        try:
            while not (run_dir / "ports" / "monitor").exists() and emu.poll() is None:
                time.sleep(0.01)
            if emu.poll() is not None:
                rdr.kill()  # the emulator failed at start-up: the reader would wait for its ports in vain
            time.sleep(0.5)  # start-up done, the reader attached
            (c0, k0), w0 = _tree_cpu_s(emu.pid), time.monotonic()
            c1, k1, w1 = c0, k0, w0
            while emu.poll() is None:
                time.sleep(0.5)
                (c, k), w = _tree_cpu_s(emu.pid), time.monotonic()
                if c is not None and emu.poll() is None:
                    c1, k1, w1 = c, k, w
            _so, se = emu.communicate()
            rdr.wait(timeout=60)
        except BaseException:  # interrupted: in sessions of their own, no terminal signal reaches them
            for proc in (emu, rdr):
                if proc.poll() is None:
                    proc.kill()
            raise
        if emu.returncode != 0:
            raise RuntimeError(f"realtime emulator run failed:\n{se[-3000:]}")
        seen = json.loads(out.read_text())
        res = json.loads(emu_out.read_text())
    cpu_pct = 100.0 * (c1 - c0) / (w1 - w0) if c0 is not None and c1 is not None and w1 > w0 else float("nan")
    res["writer_process_cpu_pct"] = round(100.0 * (k1 - k0) / (w1 - w0), 1) if w1 > w0 else float("nan")
    late = res.pop("late")
    stats = {}
    for tap in ("uart0", "uart1"):
        st = _tap_stats(seen[tap], TAP_PERIOD_S[tap])
        lt = sorted(x * 1e6 for x in late[tap][20:])  # the first chunks: the reader attaching
        st.update(emu_late_p50=_quantile(lt, 0.5), emu_late_p99=_quantile(lt, 0.99),
                  emu_late_max=lt[-1] if lt else float("nan"))
        ll = sorted(x * 1e6 for x in res["loop_late"][tap][20:])
        st.update(loop_late_p50=_quantile(ll, 0.5), loop_late_p99=_quantile(ll, 0.99),
                  loop_late_max=ll[-1] if ll else float("nan"))
        stats[tap] = st
    res.pop("loop_late")
    if tuned:
        res["host"] = tuned
    return stats["uart0"], stats["uart1"], cpu_pct, ", ".join(f"{k} {v}" for k, v in res.items())


def _emulator_rows() -> list[dict]:
    from benchmarks.common import load_avg, number
    from emulator.assembly.session import REALTIME_LEAD_S

    dur = number("PSNS_BENCH_RT_S")
    u0, u1, cpu, result = _measure_emulator(dur)
    lead = os.environ.get("PSNS_BENCH_RT_LEAD_S") or str(REALTIME_LEAD_S)
    from emulator.paced_writer import default_writer_backend

    how = (f"the paced writer ({default_writer_backend()} backend), the loop {float(lead) * 1e3:g} ms ahead"
           if float(lead) > 0 else "no lead: the loop's callback writes")
    pins = ", ".join(f"{v} {os.environ[v]}" for v in ("PSNS_BENCH_RT_EMU_CPUS", "PSNS_BENCH_RT_READER_CPUS",
                                                      "PSNS_PACED_WRITER_CPUS")
                     if os.environ.get(v))
    if pins:  # the host settings (workqueue, polling) are named by host_tuning in the emulator's result
        how += f"; pinned: {pins}"
    how += ("; emulator and reader each in a session of its own" if _own_sessions()
            else "; emulator and reader in the benchmark's session")
    for var, policy in (("PSNS_BENCH_RT_FIFO", "SCHED_FIFO"), ("PSNS_BENCH_RT_IDLE", "SCHED_IDLE")):
        if os.environ.get(var):
            how += f"; {policy}: {os.environ[var]}"
    rows = []
    for tap, st in (("uart0", u0), ("uart1", u1)):
        period_ms = TAP_PERIOD_S[tap] * 1e3
        what = "nav frames via pty://host" if tap == "uart0" else "IMU frames via the MONITOR pty"
        rows.append({"name": f"realtime {tap} frame-period jitter, p99", "value": st["p99"], "unit": "us",
                     "baseline": RT_TARGET_P99_US, "ratio": st["p99"] / RT_TARGET_P99_US,
                     "note": f"{what}, {period_ms:g} ms period, {st['frames']} frames in {dur:g} s realtime; "
                             f"p50 {st['p50']:.0f} us, max {st['max']:.0f} us; target p99 < 1 ms",
                     **{f"{k}": v for k, v in st.items()}})
        rows.append({"name": f"realtime {tap} emulator-side lateness, p99", "value": st["emu_late_p99"], "unit": "us",
                     "baseline": RT_TARGET_P99_US, "ratio": st["emu_late_p99"] / RT_TARGET_P99_US,
                     "note": f"the emulator's own part: each {tap} chunk was written to its pty this late against "
                             f"its instant (p50 {st['emu_late_p50']:.0f} us, max {st['emu_late_max']:.0f} us; {how}); "
                             f"the loop ran {st['loop_late_p99']:.0f} us late at p99 "
                             f"(max {st['loop_late_max']:.0f} us) against its own schedule; the rest of the jitter "
                             f"above is the kernel's pty hand-over and the reader's wake-up on a shared machine"})
        rows.append({"name": f"realtime {tap} dropped frames", "value": float(st["dropped"]), "unit": "frames",
                     "baseline": 0.0, "ratio": None,
                     "note": f"sequence gaps after the first frame read, {dur:g} s; target 0"})
    rows.append({"name": "realtime emulator CPU", "value": cpu, "unit": "% of one core",
                 "baseline": RT_TARGET_CPU_PCT, "ratio": cpu / RT_TARGET_CPU_PCT,
                 "note": f"reference scenario on ptys, {dur:g} s, start-up excluded, the paced writer's process "
                         f"(if any) included; {how}; load avg {load_avg()}; "
                         f"emulator: {result}"})
    return rows



#: the host set-up of the rows "..., reader on a core of its own" (D-10.E14): the emulator on CPU 0 at ``SCHED_FIFO``
#: 1; the reader (``SCHED_FIFO`` 1), the paced writer's process (``SCHED_FIFO`` 2 by itself) and the unbound
#: workqueue that runs the ptys' ``flush_to_ldisc`` on CPU 1, which polls instead of halting when idle (unconfined,
#: the pty worker lands on the emulator's CPU, which halts between its bursts on a quiet VM)
DEDICATED_CORE_ENV = {
    "PSNS_BENCH_RT_EMU_CPUS": "0", "PSNS_BENCH_RT_READER_CPUS": "1", "PSNS_PACED_WRITER_CPUS": "1",
    "PSNS_BENCH_RT_FIFO": "emu+reader", "PSNS_BENCH_RT_WQ_CPUS": "1", "PSNS_BENCH_RT_POLL_CPUS": "1",
}
DEDICATED_CORE_SUFFIX = ", reader on a core of its own"


def _dedicated_core_rows() -> list[dict]:
    """The realtime rows once more with :data:`DEDICATED_CORE_ENV` (what a core of its own gives the reader; issue 20
    asks for it beside the shared machine's figure). Needs root (``SCHED_FIFO``, the sysfs settings) and two CPUs;
    ``PSNS_BENCH_RT_CORE=0`` skips them."""
    if os.environ.get("PSNS_BENCH_RT_CORE", "1") == "0":
        return []
    if not (hasattr(os, "geteuid") and os.geteuid() == 0 and (os.cpu_count() or 1) >= 2):
        print("bench_pty_jitter: the rows with a core of its own for the reader need root and two CPUs: skipped",
              file=sys.stderr)
        return []
    with mock.patch.dict(os.environ, DEDICATED_CORE_ENV):  # the environment as it was afterwards
        rows = _emulator_rows()
    for row in rows:
        row["name"] += DEDICATED_CORE_SUFFIX
    return rows


def run() -> list[dict]:
    return _emulator_rows() + _dedicated_core_rows() + _link_rows()


if __name__ == "__main__":  # pragma: no cover
    for row in run():
        print({k: v for k, v in row.items() if k not in ("periods_ms",)})
