"""``psns-hil replay CAPTURE``: re-run the firmware on a recording.

The capture header carries the whole validated scenario (``scenario_spec``). Replay rebuilds
the DSP, its firmware, the FPGA-DSP UARTs and the host port from it -- no sensors, no FPGA
acquisition -- and hands each DSP UART the bytes the capture says it received (``uart0`` ..
``uart3`` records, direction ``in``) at their recorded times. Everything downstream (the DSP's
cycle-to-time model, the host port, the recorder) runs as in the original, so in fast mode a
replay reproduces the original ``nav.csv`` and host bytes bit for bit; change the firmware and
the same recording shows what the change does.

Every external link is replaced by ``mem://`` (nothing outside takes part in a replay). The replay is its own
builder, :class:`ReplayEmulator`: the run's :class:`~emulator.assembly.session.Emulator` with the build steps a
replay changes overridden (the host port only, no sensors, no DSP outside, the built-in firmware; the captured
bytes instead of the sources).

A capture may be hostile (docs/hostile-input.md): the reader validates its header
(:mod:`emulator.recording.capture`); of the records replayed, one whose time is not finite or negative is dropped,
one whose time goes back is delivered at the time of the record before it (the emulator's clock never goes back),
and both are counted in the summary's ``replay`` section (``bad_time_records``, ``backward_time_records``,
``records_in_capture``), so a replay never silently uses part of a capture.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..assembly.ports import UART_NUM
from ..assembly.session import Emulator
from ..clock import EmulatorLoop
from ..errors import RecordingError
from ..links import Link, MemHub
from ..recording.capture import CaptureRecord, read_capture
from ..scenario.schema import Scenario

__all__ = ["NavComparison", "ReplayEmulator", "compare_nav", "load_replay", "replay_base_dir", "replayable_records",
           "run_replay", "same_file"]

#: a capture whose last record is this much before the scenario's end holds less than the run (IMU frames
#: arrive every 5 ms, so a complete capture ends within a few ms of the end)
TRUNCATION_SLACK_S = 0.5


def load_replay(capture: str | Path) -> tuple[Any, list[Any], dict[str, Any]]:
    """``(scenario, records, header)`` of a capture, ready for :class:`emulator.assembly.session.Emulator`."""
    from ..scenario.loader import validate_scenario_data

    header, records = read_capture(capture)
    spec = header.get("scenario_spec")
    if not isinstance(spec, dict):
        raise RecordingError(f"{capture}: the capture carries no scenario (recorded by an older psns-hil); "
                             "replay needs the scenario_spec header field")
    base_dir = replay_base_dir(capture, header.get("scenario_base_dir"))
    try:
        scn: Scenario = validate_scenario_data(spec, {}, f"{capture}#scenario_spec", base_dir=base_dir,
                                               check_environment=False)
    except Exception as exc:  # ScenarioError lists the issues
        raise RecordingError(f"{capture}: its scenario does not validate in this version: {exc}") from exc
    return scn, records, header


def replayable_records(records: list[CaptureRecord]) -> tuple[list[CaptureRecord], dict[str, int]]:
    """The DSP UARTs' inbound records as the replay delivers them, in file order, and what was done to them.

    A time that is not finite or negative drops its record (``bad_time_records``); a time earlier than the record
    before it is raised to that record's time (``backward_time_records``): delivery order is file order, and the
    emulator's clock never goes back. ``records_in_capture`` counts the inbound UART records of the file.
    """
    kept: list[CaptureRecord] = []
    bad = back = total = 0
    t_prev = 0.0
    for r in records:
        if r.link not in UART_NUM or r.direction != "in":
            continue
        total += 1
        if not (math.isfinite(r.t_s) and r.t_s >= 0.0):
            bad += 1
            continue
        if r.t_s < t_prev:
            back += 1
            r = CaptureRecord(t_prev, r.link, r.direction, r.data, r.pitch_s)
        t_prev = r.t_s
        kept.append(r)
    return kept, {"records_in_capture": total, "bad_time_records": bad, "backward_time_records": back}


def replay_base_dir(capture: str | Path, named: Any) -> Path:
    """The directory a replayed scenario's relative files (a spec sheet, a calibration file) are confined to.

    The capture's header names where the run found them (``scenario_base_dir``), but a capture may come from anyone:
    that directory is taken only when it lies inside the working directory or a ``PSNS_HIL_ALLOW_PATHS`` root (the
    user's trusted roots, :func:`emulator.scenario.paths.allowed_roots`) and still exists; else the capture's own
    directory. A crafted header naming ``/`` therefore widens nothing.
    """
    from ..scenario.paths import allowed_roots

    fallback = Path(capture).resolve().parent
    if not isinstance(named, str) or "\x00" in named or not Path(named).is_absolute():
        return fallback
    base = Path(named).resolve()
    if any(base == root or base.is_relative_to(root) for root in allowed_roots(Path.cwd())) and base.is_dir():
        return base
    return fallback


class ReplayEmulator(Emulator):
    """A replay's build (see the module docstring): ``records`` (a capture's, :func:`replayable_records`) are
    handed to the DSP's UARTs at their times instead of running sensors and FPGA acquisition."""

    replaying = True

    def __init__(self, scn: Scenario, run_dir: Path, records: list[CaptureRecord], mode: str | None = None,
                 seed: int | None = None, progress: Callable[[float, float], None] | None = None,
                 source: str | None = None) -> None:
        super().__init__(scn, run_dir, mode=mode, seed=seed, progress=progress)
        self.records = records
        #: the capture replayed (the summary's ``replay.source``) and how many records reached the DSP
        self.replay_source = source
        self.replayed_records = 0
        self._replay_recs: list[CaptureRecord] = []
        self._replay_i = 0

    def _open_ports(self, hub: MemHub, loop: EmulatorLoop) -> tuple[dict[str, Link], dict[str, Link]]:
        """The host port only, in-process: the sensors are replaced by the capture, nothing outside takes part."""
        ext: dict[str, Link] = {}
        internal: dict[str, Link] = {}
        self._pair_port(hub, loop, self.cfg.ports["host"], ext, internal)
        return ext, internal

    def _cut_dsp_uarts(self, uart_fpga: dict[str, Link], hub: MemHub, loop: EmulatorLoop) -> None:
        """The DSP's UARTs stay in-process (the captured bytes are what it received)."""

    def _build_sensors(self, traj: Any, internal: dict[str, Link]) -> tuple[Any, Any, Any]:
        return None, None, None

    def build_dsp(self, uart_dsp: dict[int, Any], rx_cfg: dict[int, Any], events: Any) -> Any:
        """The firmware model, whatever ``dsp.external`` says: the replay re-runs this package's firmware."""
        return self._build_model_dsp(uart_dsp, rx_cfg, events)

    def _start_sources(self) -> None:
        """Schedule the captured DSP-UART input."""
        assert self.loop is not None
        recs = [r for r in self.records if r.link in UART_NUM and r.direction == "in"]
        self._replay_recs = recs
        self._replay_i = 0
        if recs:
            self.loop.call_at(recs[0].t_s, self._replay_step)

    def _replay_step(self) -> None:
        recs = self._replay_recs
        i = self._replay_i
        t = recs[i].t_s
        while i < len(recs) and recs[i].t_s == t:
            r = recs[i]
            link = self.links[r.link]
            link.last_rx_pitch = r.pitch_s if r.pitch_s is not None else link.line.byte_time
            link._deliver(r.data)
            self.replayed_records += 1
            i += 1
        self._replay_i = i
        if i < len(recs) and self.loop is not None:
            self.loop.call_at(recs[i].t_s, self._replay_step)

    def _replay_section(self) -> dict[str, Any] | None:
        return {"source": self.replay_source, "records": self.replayed_records}


def run_replay(capture: str | Path, run_dir: str | Path, mode: str = "fast", speed: float = 1.0,
               on_started: Callable[[Any], None] | None = None,
               progress: Callable[[float, float], None] | None = None, force: bool = False) -> dict[str, Any]:
    """Replay ``capture`` into a fresh DSP/firmware; returns the run summary."""
    from ..assembly.session import run_emulator

    scn, all_records, header = load_replay(capture)
    records, times = replayable_records(all_records)
    held = max((r.t_s for r in records), default=0.0)
    full = scn.duration_s
    truncated = bool(header.get("truncated_record")) or held < full - TRUNCATION_SLACK_S
    if truncated:  # replay what the capture holds, and say so
        scn = scn.model_copy(update={"duration_s": max(held, 1e-3)})
    emu = ReplayEmulator(scn, Path(run_dir), records, mode=mode, seed=header.get("seed"), progress=progress,
                         source=str(capture))
    summary = run_emulator(emu, speed, on_started, force=force)
    if summary.get("replay") is not None:
        summary["replay"].update(truncated=truncated, captured_s=held, scenario_duration_s=full, **times)
        (Path(run_dir) / "summary.json").write_text(_strict(summary) + "\n", encoding="utf-8")
    return summary


def _strict(summary: dict[str, Any]) -> str:
    from ..recording.formatting import strict_json

    return strict_json(summary)


class NavComparison(dict[str, Any]):
    """``identical``, ``rows`` (a, b), ``differing_columns`` (in column order), ``only_arrival``: whether the
    only differences are in ``arrival_s`` (a realtime capture: the solution is the same, its delivery time is not)."""


def compare_nav(a: str | Path, b: str | Path) -> NavComparison:
    """Compare two ``nav.csv`` files column by column (see :class:`NavComparison`)."""
    import csv

    with open(a, newline="", encoding="utf-8") as fa, open(b, newline="", encoding="utf-8") as fb:
        ra, rb = list(csv.reader(fa)), list(csv.reader(fb))
    head_a, head_b = (ra[0] if ra else []), (rb[0] if rb else [])
    cols = head_a if head_a == head_b else sorted(set(head_a) | set(head_b))
    differing: list[str] = []
    if head_a != head_b:
        differing = [c for c in cols if c not in head_a or c not in head_b]
    ia, ib = {c: i for i, c in enumerate(head_a)}, {c: i for i, c in enumerate(head_b)}
    for c in cols:
        if c in differing or c not in ia or c not in ib:
            continue
        i, j = ia[c], ib[c]
        if any((x[i] if i < len(x) else None) != (y[j] if j < len(y) else None) for x, y in zip(ra[1:], rb[1:])):
            differing.append(c)
    same_rows = len(ra) == len(rb)
    return NavComparison(identical=same_rows and not differing, rows=(max(len(ra) - 1, 0), max(len(rb) - 1, 0)),
                         differing_columns=differing, only_arrival=same_rows and differing == ["arrival_s"])


def same_file(a: str | Path, b: str | Path) -> bool:
    """True when two files hold identical bytes."""
    pa, pb = Path(a), Path(b)
    if pa.stat().st_size != pb.stat().st_size:
        return False
    with open(pa, "rb") as fa, open(pb, "rb") as fb:
        while True:
            x = fa.read(1 << 20)
            if x != fb.read(1 << 20):
                return False
            if not x:
                return True
