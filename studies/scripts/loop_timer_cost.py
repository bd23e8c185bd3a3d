"""CPU cost of the fast loop's timers alone, this tree against another checkout: the reference's timer pattern
without its work.

The workload (public loop API only, so any tree since the loop's own iteration runs it): a 200 Hz trigger that
arms a 4 ms timeout (cancelled when its "datagram" lands, as the FPGA's gyro timeout is), a datagram hop 0.35 ms
after the trigger that schedules a frame hop 0.9 ms later, a 10 Hz and a 1 Hz source on the trigger's grid (equal
deadlines) and 40 far-future timers that keep the heap as deep as the reference's. Each hop does nothing else, so
the CPU time per tick is what the loop costs per tick with the reference's 4.4 timers and 1 cancellation per tick.

Alternating pairs of fresh subprocesses, one per tree (``PYTHONPATH`` set to the tree), each timed with
``time.process_time``; prints each pair, the ratio (other / this) and its median. Also prints a digest of the
order in which the callbacks ran, which must be the same in both trees (the heap's order of equal deadlines)::

    .venv/bin/python -m studies.scripts.loop_timer_cost OTHER_TREE [ticks] [pairs]
"""

from __future__ import annotations

import sys
from pathlib import Path
from statistics import median

from studies.scripts.compare_trees import run_child

ROOT = Path(__file__).resolve().parents[2]

#: the child: the workload on the tree's own EmulatorLoop; prints one JSON line (CPU s, order digest)
_CHILD = """
import hashlib, json, sys, time
from emulator.clock import EmulatorLoop
ticks = int(sys.argv[1])
period = 0.005
loop = EmulatorLoop("fast")
order = hashlib.sha256()
state = {"k": 0, "timeout": None}

def note(tag):
    order.update(b"%s %.9f;" % (tag, loop.time()))

def frame_hop():
    note(b"f")

def datagram_hop():
    note(b"d")
    state["timeout"].cancel()
    loop.call_at(loop.time() + 0.0009, frame_hop)

def timed_out():
    note(b"x")

def trigger():
    k = state["k"] = state["k"] + 1
    note(b"t")
    if k >= ticks:
        loop.stop()
        return
    t = k * period
    loop.call_at(t + period, trigger)
    state["timeout"] = loop.call_at(t + 0.004, timed_out)
    loop.call_at(t + 0.00035, datagram_hop)
    if k % 20 == 0:
        loop.call_at(t + period * 20, lambda: note(b"c"))
    if k % 200 == 0:
        loop.call_at(t + 1.0, lambda: note(b"g"))

for i in range(40):
    loop.call_at(1e9 + i, note, b"z")
loop.call_at(period, trigger)
c0 = time.process_time()
loop.run_forever()
cpu = time.process_time() - c0
loop.close()
print(json.dumps({"cpu_s": cpu, "us_per_tick": cpu / ticks * 1e6, "order": order.hexdigest()[:16]}))
"""


def _spawn(tree: Path, ticks: int) -> dict[str, float | str]:
    return run_child(tree, _CHILD, [str(ticks)])


def main(argv: list[str] | None = None) -> int:
    args = sys.argv[1:] if argv is None else argv
    if not 1 <= len(args) <= 3:
        raise SystemExit("usage: python -m studies.scripts.loop_timer_cost OTHER_TREE [ticks] [pairs]")
    other = Path(args[0]).resolve()
    ticks = int(args[1]) if len(args) > 1 else 200_000
    pairs = int(args[2]) if len(args) > 2 else 5
    ratios = []
    for i in range(pairs):
        a, b = _spawn(other, ticks), _spawn(ROOT, ticks)
        ratios.append(float(a["cpu_s"]) / float(b["cpu_s"]))
        print(f"pair {i + 1}: other {a['us_per_tick']:.2f} us/tick ({a['order']}), this {b['us_per_tick']:.2f} "
              f"us/tick ({b['order']}), ratio {ratios[-1]:.3f}", flush=True)
    print(f"median ratio (other CPU / this CPU) over {pairs} pairs: {median(ratios):.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
