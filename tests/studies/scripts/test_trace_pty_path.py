"""studies.scripts.trace_pty_path: the cadence split and the kernel-path split on records whose answers are known."""

from __future__ import annotations

from studies.scripts.trace_pty_path import cadence, kernel_path


def _res(n: int = 400) -> dict:
    """MONITOR frames every 5 ms (frame 200's deadline 0.5 ms late), host frames every 10 ms; every arrival 0.2 ms
    after its deadline (frame 300's 1.0 ms: after the write), the writer 0.05 ms late."""
    mon = [(k, 100.0 + k * 0.005 + (0.0005 if k == 200 else 0.0)) for k in range(n)]
    host = [(k, 100.0 + k * 0.01 + 0.002) for k in range(n // 2)]
    seen_mon = [(at + (0.001 if s == 300 else 0.0002), s) for s, at in mon]
    seen_host = [(at + 0.0002, s) for s, at in host]
    return {"deadlines": {"uart0": host, "uart1": mon}, "late": [5e-5] * n,
            "seen": {"uart0": seen_host, "uart1": seen_mon}}


def test_cadence_puts_a_late_deadline_in_the_deadlines_and_a_late_arrival_after_them():
    u0, u1 = cadence(_res())
    assert "0 of 149 periods off by > 1 us" in u0  # the host grid is exact
    assert "at the reader 0.000 / 0.000 / 0.00" in u0
    # frame 200: two periods 0.5 ms off in the deadlines (and so at the reader); frame 300: two 0.8 ms off after them
    assert "2 of 349 periods off by > 1 us" in u1
    assert "at the reader 0.000 / 0.500 / 0.80" in u1  # 4 of 349 periods off: the p99 is one of them
    assert "the deadlines alone 0.000 / 0.000 / 0.50" in u1
    assert "after the deadline 0.000 / 0.000 / 0.80" in u1 and "after the writer's write 0.000 / 0.000 / 0.80" in u1


def test_kernel_path_splits_a_write_into_its_steps_and_names_what_ran_meanwhile():
    res = _res(130)
    res["pids"] = {"emulator": 10, "reader": 20, "writer": 30}
    lines = []
    for k in range(130):
        t = 100.0 + k * 0.005 + 0.00001  # the writer's write 10 us after the deadline
        worker = 0.0005 if k == 120 else 0.00004  # frame 120: the worker waits 0.5 ms behind the loop (pid 10)
        lines += [
            f" python-30 [000] d..1. {t:.6f}: workqueue_queue_work: work struct=00ab function=flush_to_ldisc "
            "workqueue=events_unbound req_cpu=256 cpu=-1",
            f" python-10 [001] d..2. {t:.6f}: sched_switch: prev_comm=x prev_pid=0 prev_prio=120 prev_state=R "
            "==> next_comm=python next_pid=10 next_prio=120",
            f" kworker/u8:1-5 [001] ..... {t + worker:.6f}: workqueue_execute_start: work struct 00ab: "
            "function flush_to_ldisc",
            f" kworker/u8:1-5 [001] d..2. {t + worker + 0.00001:.6f}: sched_wakeup: comm=python pid=20 prio=120 "
            "target_cpu=001",
            f" kworker/u8:1-5 [001] d..2. {t + worker + 0.00002:.6f}: sched_switch: prev_comm=kworker prev_pid=5 "
            "prev_prio=120 prev_state=S ==> next_comm=python next_pid=20 next_prio=120",
        ]
        res["seen"]["uart1"][k] = (t + worker + 0.00005, k)
    res["trace"] = lines
    out = "\n".join(kernel_path(res))
    assert "30 MONITOR writes" in out  # the first 100 are left out (the reader attaching)
    assert "the writer's write after the deadline: 0.010 / 0.010" in out
    assert "the kernel worker starting after it: 0.040 / 0.500 / 0.50" in out
    assert "the kernel worker starting after it > 0.3 ms: 1 writes (3.3 %); on that CPU meanwhile: " \
           "the emulator's loop thread 1 ms" in out  # 0.52 ms, rounded
