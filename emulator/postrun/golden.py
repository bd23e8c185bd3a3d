"""Change indicator: golden records of the library scenarios' estimator state and input bytes.

For every scenario of the library (``scenarios/*.yaml``) two small text files live in
``tests/golden/``:

``<name>.state.csv``
    The estimator's state history: the host's navigation output (position, velocity, attitude,
    mode; the last frame at or before each whole second), and the firmware's filter state sampled 2.5 ms after
    each whole second (``filter_state.csv``: the diagonal of the covariance P and the gyro / accelerometer bias
    estimates), one row every ``interval`` seconds (1 s, or coarser so that a file stays below
    about 200 rows). Numbers have 12 significant digits.
``<name>.inputs.txt``
    SHA-256 digests of every captured byte that travels towards the DSP (sensor ports and DSP
    UARTs, direction ``in``): one line per link with its byte and chunk counts, and one line of
    short digests per time block, so that a difference can be located in time.

The scenario test (``scenarios/conftest.py``) runs each scenario in fast mode (deterministic for a
given seed) and compares: the inputs must match exactly (the bytes are integers; any change in a
sensor model, a wire format or a fault injector shows), the state within :data:`TOLERANCES`
(float noise; see docs/scenarios.md for why these values). A difference fails the test unless the
golden files are regenerated on purpose, with ONE command whose diff then shows in review::

    make golden                                              # every library scenario
    psns-hil golden --update quickstart static_alignment     # some of them

``psns-hil golden`` (:mod:`emulator.cli.golden`) without ``--update`` only checks and prints the differences.
"""

from __future__ import annotations

import csv
import hashlib
import math
from pathlib import Path
from typing import Any

__all__ = [
    "GOLDEN_DIR",
    "LIBRARY_DIR",
    "ROOT",
    "TOLERANCES",
    "compare_golden",
    "input_digest",
    "library",
    "render_inputs",
    "render_state",
    "row_interval",
    "state_history",
    "write_golden",
]

ROOT = Path(__file__).resolve().parents[2]
GOLDEN_DIR = ROOT / "tests" / "golden"
LIBRARY_DIR = ROOT / "scenarios"
#: nav.csv columns kept in the state history
NAV_COLUMNS = ("lat_deg", "lon_deg", "height_m", "vel_e_mps", "vel_n_mps", "vel_u_mps", "roll_deg", "pitch_deg",
               "heading_deg", "mode")
#: (absolute, relative) tolerance per column prefix; ``|a - b| <= atol + rtol * |b|`` passes.
#: The firmware runs in float32 (24-bit mantissa, 6e-8 relative): the same inputs on another CPU, BLAS or
#: numpy build may round a few operations differently, and a closed-loop filter keeps such differences at
#: the rounding level of each state. The floors below are 1-3 orders above that level (lat/lon 1e-8 deg is
#: 1 mm) and 1-3 orders below what any real change of the algorithm or its parameters does to the state.
TOLERANCES: dict[str, tuple[float, float]] = {
    "lat_deg": (1e-8, 0.0), "lon_deg": (1e-8, 0.0), "height_m": (1e-3, 0.0),
    "vel_": (1e-4, 1e-6), "roll_deg": (1e-4, 0.0), "pitch_deg": (1e-4, 0.0), "heading_deg": (1e-4, 0.0),
    "mode": (0.0, 0.0), "p": (1e-30, 1e-4), "gyro_bias": (1e-9, 1e-4), "accel_bias": (1e-7, 1e-4),
}
MAX_ROWS = 120
#: capture links and direction that carry the estimator's inputs
INPUT_LINKS = ("gyro", "gnss", "psns", "host", "uart0", "uart1", "uart2", "uart3")


def row_interval(duration_s: float) -> int:
    """Seconds between state rows: 1 s, or coarser for long scenarios (at most :data:`MAX_ROWS` rows)."""
    return max(1, math.ceil(duration_s / MAX_ROWS))


def _tol(col: str) -> tuple[float, float]:
    for prefix, tol in TOLERANCES.items():
        if col == prefix or col.startswith(prefix):
            return tol
    return (1e-9, 1e-6)


def _read_csv(path: Path) -> tuple[list[str], list[list[str]]]:
    with open(path, newline="", encoding="utf-8") as f:
        r = csv.reader(f)
        header = next(r, [])
        return header, [row for row in r]


def state_history(run_dir: str | Path, duration_s: float) -> tuple[list[str], list[list[Any]]]:
    """The state history of a run: header and rows (time, nav output, filter state), see module docstring."""
    run_dir = Path(run_dir)
    step = row_interval(duration_s)
    nav_h, nav_rows = _read_csv(run_dir / "nav.csv")
    ti = nav_h.index("time_s")
    idx = [nav_h.index(c) for c in NAV_COLUMNS]
    nav: dict[int, list[str]] = {}
    for row in nav_rows:  # the last frame at or before each whole second k (frames come every 10 ms)
        t = float(row[ti])
        k = math.ceil(t - 1e-9)
        if k % step == 0:
            nav[k] = [row[i] for i in idx]
    fs_path = run_dir / "filter_state.csv"
    fs_h, fs_rows = _read_csv(fs_path) if fs_path.exists() else ([], [])
    fs_cols = [c for c in fs_h if c not in ("time_s", "state")]
    fs: dict[int, list[str]] = {}
    for row in fs_rows:
        d = dict(zip(fs_h, row))
        k = round(float(d["time_s"]))
        if k % step == 0:
            fs[k] = [d.get(c, "") for c in fs_cols]
    header = ["time_s", *NAV_COLUMNS, *(f"fw_{c}" if c == "mode" else c for c in fs_cols)]
    rows = []
    for k in sorted(set(nav) | set(fs)):
        nv = nav.get(k, [""] * len(NAV_COLUMNS))
        fv = fs.get(k, [""] * len(fs_cols))
        rows.append([k, *nv, *fv])
    return header, rows


def _num(x: Any) -> str:
    if x == "" or x is None:
        return ""
    v = float(x)
    if not math.isfinite(v):
        return repr(v)
    if v == int(v) and abs(v) < 1e15:
        return str(int(v))
    return format(v, ".12g")


def render_state(header: list[str], rows: list[list[Any]]) -> str:
    return ",".join(header) + "\n" + "".join(",".join(_num(x) for x in r) + "\n" for r in rows)


def input_digest(capture: str | Path, duration_s: float) -> list[str]:
    """Digest lines of the captured input bytes (see module docstring)."""
    from ..recording.capture import iter_capture

    block = max(10, 10 * math.ceil(duration_s / 20.0 / 10.0))
    n_blocks = max(1, math.ceil(duration_s / block))
    total: dict[tuple[str, str], Any] = {}
    counts: dict[tuple[str, str], list[int]] = {}
    blocks: dict[tuple[str, str], list[Any]] = {}
    _hdr, recs = iter_capture(capture)
    for r in recs:
        if r.direction != "in" or r.link not in INPUT_LINKS:
            continue
        key = (r.link, r.direction)
        if key not in total:
            total[key] = hashlib.sha256()
            counts[key] = [0, 0]
            blocks[key] = [hashlib.sha256() for _ in range(n_blocks)]
        total[key].update(r.data)
        counts[key][0] += len(r.data)
        counts[key][1] += 1
        b = min(n_blocks - 1, max(0, int(r.t_s // block)))
        blocks[key][b].update(r.data)
    lines = [f"# input bytes towards the DSP: link direction bytes chunks sha256; then per {block} s block "
             f"the first 12 hex digits of each block's sha256"]
    for key in sorted(total):
        link, d = key
        lines.append(f"{link} {d} {counts[key][0]} {counts[key][1]} {total[key].hexdigest()}")
        lines.append(f"{link} {d} blocks_{block}s " + " ".join(h.hexdigest()[:12] for h in blocks[key]))
    return lines


def render_inputs(name: str, seed: int, lines: list[str]) -> str:
    head = f"# psns-hil change indicator: captured inputs of scenario {name} (fast mode, seed {seed})\n"
    return head + "\n".join(lines) + "\n"


def golden_paths(name: str, golden_dir: Path = GOLDEN_DIR) -> tuple[Path, Path]:
    return golden_dir / f"{name}.state.csv", golden_dir / f"{name}.inputs.txt"


def record(run_dir: str | Path, name: str, seed: int, duration_s: float) -> tuple[str, str]:
    """The two golden texts of a finished run."""
    run_dir = Path(run_dir)
    header, rows = state_history(run_dir, duration_s)
    return render_state(header, rows), render_inputs(name, seed, input_digest(run_dir / "capture.psnscap", duration_s))


def write_golden(run_dir: str | Path, name: str, seed: int, duration_s: float, golden_dir: Path = GOLDEN_DIR
                 ) -> tuple[Path, Path]:
    state, inputs = record(run_dir, name, seed, duration_s)
    golden_dir.mkdir(parents=True, exist_ok=True)
    ps, pi = golden_paths(name, golden_dir)
    ps.write_text(state, encoding="utf-8")
    pi.write_text(inputs, encoding="utf-8")
    return ps, pi


def compare_state(new: str, old: str, max_report: int = 8) -> list[str]:
    """Differences beyond :data:`TOLERANCES` between two state histories (empty: same within float noise)."""
    nr = list(csv.reader(new.splitlines()))
    orr = list(csv.reader(old.splitlines()))
    if not nr or not orr:
        return ["empty state history"]
    nh, oh = nr[0], orr[0]
    out: list[str] = []
    if nh != oh:
        gone = [c for c in oh if c not in nh]
        added = [c for c in nh if c not in oh]
        out.append(f"columns differ: missing {gone or '-'}, new {added or '-'}")
    nt = {r[0]: r for r in nr[1:]}
    ot = {r[0]: r for r in orr[1:]}
    if set(nt) != set(ot):
        out.append(f"rows differ: {len(nt)} rows (t = {min(nt, key=float, default='-')}.."
                   f"{max(nt, key=float, default='-')} s) vs golden {len(ot)} (t = {min(ot, key=float, default='-')}.."
                   f"{max(ot, key=float, default='-')} s)")
    common = [c for c in oh if c in nh and c != "time_s"]
    for c in common:
        i_n, i_o = nh.index(c), oh.index(c)
        atol, rtol = _tol(c)
        bad = []
        for t in sorted(set(nt) & set(ot), key=float):
            a, b = nt[t][i_n], ot[t][i_o]
            if a == b:
                continue
            if a == "" or b == "":
                bad.append((t, a, b, math.inf))
                continue
            fa, fb = float(a), float(b)
            d = abs(fa - fb)
            if c.endswith("heading_deg"):
                d = abs((fa - fb + 180.0) % 360.0 - 180.0)
            if not d <= atol + rtol * abs(fb):
                bad.append((t, a, b, d))
        if bad:
            t, a, b, d = bad[0]
            out.append(f"{c}: {len(bad)} of {len(set(nt) & set(ot))} rows differ beyond tolerance (atol {atol:g}, "
                       f"rtol {rtol:g}); first at t = {t} s: {a or '(empty)'} vs golden {b or '(empty)'} "
                       f"(|diff| {d:.3g})")
            if len(out) >= max_report:
                out.append("...")
                break
    return out


def compare_inputs(new: str, old: str) -> list[str]:
    """Differences between two input digests (exact)."""
    def parse(text: str) -> dict[tuple[str, str, str], str]:
        d = {}
        for ln in text.splitlines():
            if not ln or ln.startswith("#"):
                continue
            parts = ln.split()
            if len(parts) >= 3 and parts[2].startswith("blocks_"):
                d[(parts[0], parts[1], parts[2])] = " ".join(parts[3:])
            elif len(parts) == 5:
                d[(parts[0], parts[1], "total")] = " ".join(parts[2:])
        return d

    n, o = parse(new), parse(old)
    out = []
    for key in sorted(set(n) | set(o), key=lambda k: (k[0], k[1], k[2] != "total", k[2])):
        if n.get(key) == o.get(key):
            continue
        link, d, what = key
        if key not in n or key not in o:
            out.append(f"input {link} {d}: {'missing' if key not in n else 'new'} (golden has "
                       f"{'it' if key in o else 'none'})")
        elif what == "total":
            nb, nc, _ = n[key].split()
            ob, oc, _ = o[key].split()
            out.append(f"input bytes on {link} ({d}) differ: {nb} bytes in {nc} chunks vs golden {ob} in {oc}")
        else:
            nbk, obk = n[key].split(), o[key].split()
            size = int(what[len("blocks_"):-1])
            first = next((i for i, (x, y) in enumerate(zip(nbk, obk)) if x != y), min(len(nbk), len(obk)))
            out.append(f"  first difference on {link} ({d}) in the block {first * size}-{(first + 1) * size} s")
    return out


def compare_golden(run_dir: str | Path, name: str, seed: int, duration_s: float, golden_dir: Path = GOLDEN_DIR
                   ) -> list[str]:
    """Every difference between a finished run and its golden files (empty: unchanged)."""
    ps, pi = golden_paths(name, golden_dir)
    if not ps.exists() or not pi.exists():
        return [f"no golden record for {name} in {golden_dir} (create it with `make golden` or "
                f"`psns-hil golden --update {name}`, then commit it)"]
    state, inputs = record(run_dir, name, seed, duration_s)
    diffs = (compare_inputs(inputs, pi.read_text(encoding="utf-8"))
             + compare_state(state, ps.read_text(encoding="utf-8")))
    from ..numeric_baseline import describe, pinned

    if diffs and not pinned():
        diffs.append(f"note: this process did not run the pinned numeric baseline ({describe()}); the goldens are "
                     "recorded with it (emulator.numeric_baseline: run through `make test` / `psns-hil`, or set "
                     "its environment before numpy loads)")
    return diffs


def library(library_dir: Path = LIBRARY_DIR) -> list[Path]:
    """The scenario files of the library."""
    return sorted([*library_dir.glob("*.yaml"), *library_dir.glob("*.yml")])
