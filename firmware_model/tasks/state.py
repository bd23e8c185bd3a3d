"""What the cyclic executive shares with its tasks: mode-manager states, :class:`TickResult`, the
:class:`LoopStatus` record (mode manager, aiding times, the heading's standing) and the :class:`CpuLoad`.

``Firmware.__init__`` makes one of each and hands them to the tasks that write or report them.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from protocols.host import NavMode

if TYPE_CHECKING:  # gnss.py imports count_rejection from here
    pass

__all__ = ["CpuLoad", "FirmwareState", "LoopStatus", "SolarSolve", "TickResult", "count_rejection"]


class FirmwareState:
    """Mode-manager states."""

    COARSE_ALIGN = "coarse_align"
    FINE_ALIGN = "fine_align"
    NAVIGATE = "navigate"


@dataclass
class SolarSolve:
    """One solar vector the firmware solved from a PSNS frame (what the recorder compares with truth).

    ``t_exposure_s``: the frame's mid-exposure time (s, FPGA time base, docs/architecture.md "Conventions");
    ``s_b``: the unit bi-direction solar vector ``+-S^b`` in the body frame (x right, y forward, z up), as solved
    (base paper Eqs. 9-14; the filter picks the sign with the smaller residual, the remark after Eq. 38); ``n_used``:
    observation points that entered ``K``; ``quality``: ``lambda_1 / lambda_2`` of ``K``; ``source``: ``camera``
    (solved here) or ``sensor`` (an on-sensor solve); ``use``: what the loop did with it -- ``accepted`` /
    ``refused`` by the filter's update (its innovation gate), ``alignment`` (coarse alignment), or why no update
    was tried: ``sun_low``, ``stale``, ``no_utc``, ``disabled``.
    """

    t_exposure_s: float
    s_b: tuple[float, float, float]
    n_used: int
    quality: float
    source: str
    use: str = "solved"


@dataclass
class TickResult:
    """What one run of the cyclic executive produced.

    ``cycles`` is the total charged; each output is ``(uart, bytes, cycles_at_emit)``. ``solar_solves``: the
    solar vectors solved in this tick (:class:`SolarSolve`; optional in the interface: a firmware without a
    solve leaves it empty).
    """

    t_fpga_s: float
    cycles: int
    outputs: list[tuple[int, bytes, int]] = field(default_factory=list)
    events: list[dict[str, Any]] = field(default_factory=list)
    solar_solves: list[SolarSolve] = field(default_factory=list)


@dataclass
class LoopStatus:
    """The mode manager's state and the aiding times: written by the alignment and the measurement tasks, reported
    by the output and host tasks (a record the executive owns and hands to them; times in s, FPGA time base)."""

    state: str = FirmwareState.COARSE_ALIGN
    mode: NavMode = NavMode.ALIGNING
    #: end of the coarse alignment (start of FINE_ALIGN)
    t_aligned: float = 0.0
    #: latest accepted GNSS update; the innovation gate refused rows of the last GNSS fix (gnss_status bit 7)
    last_gnss_update_t: float = -1e9
    gnss_gated: bool = False
    #: latest accepted solar update and latest refused one
    last_psns_t: float = -1e9
    last_psns_reject_t: float = -1e9
    #: the heading's sigma the filter started from (rad; a reset starts from it again) and whether the heading is
    #: the configured placeholder of a PSNS alignment that timed out (D-5.50)
    heading_sigma0: float = 0.0
    heading_placeholder: bool = False

    def psns_status(self, t: float) -> int:
        """``psns_status`` of NAV_SOLUTION / STATUS at ``t``: 1 aiding, 2 refused lately, 0 none."""
        return 1 if t - self.last_psns_t < 2.0 else 2 if t - self.last_psns_reject_t < 2.0 else 0

    def gnss_status_byte(self, last_fix: tuple[float, float, float, int] | None) -> int:
        """``gnss_status``: the last fix's GGA quality (bits 0-6), bit 7 when the innovation gate refused rows of
        the last GNSS fix (docs/hostile-input.md)."""
        quality = last_fix[3] & 0x7F if last_fix is not None else 0
        return quality | (0x80 if self.gnss_gated else 0)


class CpuLoad:
    """The CPU load the firmware reports: the worst tick of the last second (sliding maximum), the worst since
    start, and the deadline misses the DSP host noted. Collaborator: ``tick_budget`` (cycles per IMU tick)."""

    def __init__(self, tick_budget: int) -> None:
        self._tick_budget = tick_budget
        self._window: deque[tuple[float, int]] = deque()
        self._max = 0
        self.deadline_misses = 0

    def record(self, t: float, cycles: int) -> None:
        """The tick at ``t`` (s) charged ``cycles``."""
        while self._window and self._window[-1][1] <= cycles:
            self._window.pop()
        self._window.append((t, cycles))
        while self._window[0][0] <= t - 1.0:
            self._window.popleft()
        self._max = max(self._max, cycles)

    def load_pct(self) -> float:
        """Worst tick of the last second, % of the tick budget (NAV_SOLUTION / STATUS ``cpu_load``)."""
        worst = self._window[0][1] if self._window else 0
        return 100.0 * worst / self._tick_budget

    def max_pct(self) -> float:
        """Worst tick since start, % of the tick budget (STATUS ``cpu_load_max``)."""
        return 100.0 * self._max / self._tick_budget

    def note_miss(self) -> None:
        """The DSP host found a tick late."""
        self.deadline_misses += 1


def count_rejection(counters: dict[str, int], reason: str) -> None:
    """Count one message refused by :mod:`firmware_model.input_guard` in ``counters`` (``input_rejected`` and
    ``input_rejected_<reason>``)."""
    counters["input_rejected"] += 1
    key = "input_rejected_" + reason
    counters[key] = counters.get(key, 0) + 1
