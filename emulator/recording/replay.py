"""``psns-hil replay CAPTURE``: re-run the firmware on a recording.

The capture header carries the whole validated scenario (``scenario_spec``). Replay rebuilds
the DSP, its firmware, the FPGA-DSP UARTs and the host port from it -- no sensors, no FPGA
acquisition -- and hands each DSP UART the bytes the capture says it received (``uart0`` ..
``uart3`` records, direction ``in``) at their recorded times. Everything downstream (the DSP's
cycle-to-time model, the host port, the recorder) runs as in the original, so in fast mode a
replay reproduces the original ``nav.csv`` and host bytes bit for bit; change the firmware and
the same recording shows what the change does.

Every external link is replaced by ``mem://`` (nothing outside takes part in a replay).
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from ..errors import RecordingError
from .capture import read_capture

__all__ = ["load_replay", "run_replay", "same_file"]


def load_replay(capture: str | Path) -> tuple[Any, list[Any], dict[str, Any]]:
    """``(scenario, records, header)`` of a capture, ready for :class:`emulator.assembly.runner.Emulator`."""
    from ..scenario.loader import validate_scenario_data
    from ..scenario.schema import Scenario

    header, records = read_capture(capture)
    spec = header.get("scenario_spec")
    if not isinstance(spec, dict):
        raise RecordingError(f"{capture}: the capture carries no scenario (recorded by an older psns-hil); "
                             "replay needs the scenario_spec header field")
    try:
        scn: Scenario = validate_scenario_data(spec, {}, f"{capture}#scenario_spec", check_environment=False)
    except Exception as exc:  # ScenarioError lists the issues
        raise RecordingError(f"{capture}: its scenario does not validate in this version: {exc}") from exc
    return scn, records, header


def run_replay(capture: str | Path, run_dir: str | Path, mode: str = "fast", speed: float = 1.0,
               on_started: Callable[[Any], None] | None = None,
               progress: Callable[[float, float], None] | None = None, force: bool = False) -> dict[str, Any]:
    """Replay ``capture`` into a fresh DSP/firmware; returns the run summary."""
    from ..assembly.runner import Emulator, run_emulator

    scn, records, header = load_replay(capture)
    emu = Emulator(scn, Path(run_dir), mode=mode, seed=header.get("seed"), progress=progress, replay=records)
    emu.replay_source = str(capture)
    return run_emulator(emu, speed, on_started, force=force)


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
