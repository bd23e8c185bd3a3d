"""The cycle meter: nested tasks, kernel charges, and the one-call forms ``begin(..., kernel, cycles)`` and
``end(kernel, cycles)`` that the 200 Hz tick uses, against the separate calls they stand for."""

from __future__ import annotations

import random

from firmware_model.c674x import CycleMeter


def test_nested_tasks_count_their_kernels_and_the_enclosing_totals():
    m = CycleMeter(300e6, 200.0)
    m.begin("tick", 0.005)
    m.begin("imu", 0.005, "decode", 100)
    m.charge("convert", 50)
    assert m.elapsed == 150
    assert m.end("strapdown", 400) == 550
    m.begin("output", 0.01)
    m.charge("pack", 30)
    assert m.end() == 30 and m.elapsed == 580
    assert m.end() == 580 and m.elapsed == 0
    rows = {r["task"]: r for r in m.table()}
    assert rows["imu"]["kernels"] == {"decode": 100, "convert": 50, "strapdown": 400}
    assert rows["tick"]["kernels"] == {} and rows["tick"]["cycles_last"] == 580
    assert rows["output"]["kernels"] == {"pack": 30}
    assert m.tick_budget == 1_500_000
    # nothing open: no task counts it; elapsed holds it until the next outermost begin (as charge() then end())
    assert m.end("late", 7) == 0 and m.elapsed == 7
    m.begin("tick", 0.005)
    assert m.elapsed == 0


def _run(script: list[tuple[int, int]], combined: bool) -> tuple[list[object], list[dict[str, object]]]:
    m = CycleMeter(300e6, 200.0)
    seen: list[object] = []
    for op, c in script:
        task, kernel = f"task{c % 3}", f"k{c % 4}"
        if op == 0:
            m.begin(task, 0.005)
        elif op == 1:
            if combined:
                m.begin(task, 0.005, kernel, c)
            else:
                m.begin(task, 0.005)
                m.charge(kernel, c)
        elif op == 2:
            m.charge(kernel, c)
        elif op == 3:
            seen.append(m.end())
        else:
            if combined:
                seen.append(m.end(kernel, c))
            else:
                m.charge(kernel, c)
                seen.append(m.end())
        seen.append(m.elapsed)
    return seen, m.table()


def test_one_call_forms_are_the_separate_calls():
    rng = random.Random(6747)
    for _ in range(20):
        script = [(rng.randrange(5), rng.randrange(5000)) for _ in range(rng.randrange(1, 400))]
        assert _run(script, True) == _run(script, False)
