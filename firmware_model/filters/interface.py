"""Navigation-filter variants behind one interface: :class:`NavFilter`, what it asks of the loop
(:class:`FilterHost`), what an update reports (:class:`UpdateReport`) and the registry (:func:`register_filter`).

The main loop (:mod:`firmware_model.firmware`) owns I/O, time keeping, alignment, the strapdown and
the task schedule; a :class:`NavFilter` owns the error state, its covariance and the measurement
models. The loop calls, per tick and only when there is something to do::

    predict(nav, f_n_mean, T_k)              every ``kf_predict_every`` IMU ticks
    update_gnss(nav, meas, p_ins, v_ins)      a GNSS fix is pending (1 Hz)
    update_solar(nav, obs, s_n, cbn_exp)      a PSNS solar vector is pending (frame rate)
    update_compass(nav, frame, t_exp)         a multi-unit compass frame is pending
    update_polarization_obs(nav, frame, t_exp)  a POLARIZATION_OBS frame, for variants that set
                                              ``raw_polarization_obs`` (instead of the firmware's solve)
    feedback(nav)                             closed-loop correction after updates

and, for every variant, once per tick (cheap: the base variant returns nothing)::

    drain_events()                            decisions to log (TickResult.events)
    variant_status()                          (variant_mode, psns_units, psns_q_mask) for the NAV_SOLUTION
                                              VARIANT block and STATUS, or None (base: no block)

Services of the main loop a variant may use (:class:`FilterHost`, handed over by :meth:`NavFilter.attach`):
UTC for the ephemeris, the INS state at a measurement's time, the mean of the MAG frames around a given
time, the current tick time.

Variants register themselves in :data:`firmware_model.config.FILTER_VARIANTS` with :func:`register_filter`; the
scenario's ``firmware.filter`` picks one by name. The variants of :mod:`firmware_model.variants` (dual-vector
switching, K-means 3-D attitude, federated filter with chi-square isolation, sun-elevation positioning with a
Sage-Husa adaptive KF) subclass :class:`NavFilter` (or :class:`~firmware_model.filters.base.BaseFilter`) and
override the updates they change; the loop stays as it is.

Units and frames of the interface: ``f_n_mean`` m/s^2 in the local-level ENU frame n, ``T_k`` s, ``p_ins`` (lat, lon
rad, h m), ``v_ins`` ENU m/s, ``s_n`` a unit vector in n, ``cbn_exp`` the body-to-n direction cosine matrix at the
exposure, ``t_exp`` s on the FPGA time base; the covariance ``P`` in the units of :mod:`firmware_model.kf`'s state
layout. The base variant is :class:`firmware_model.filters.base.BaseFilter`; the measurement models are
:mod:`firmware_model.filters.gnss` and :mod:`firmware_model.filters.solar`.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any, Protocol, TypeVar

import numpy as np

from protocols.host import FILTER_VARIANT_NAMES

from .. import c674x
from ..arrays import F64Array, FloatArray, FloatDtype
from ..config import FILTER_VARIANTS, FirmwareConfig
from ..kf import N_STATES
from ..nav_state import NavState
from .gnss import GnssMeasurement
from .solar import SOLAR_VECTOR_DOF, SolarObservation, solar_fix_nis

__all__ = [
    "FilterHost",
    "NavFilter",
    "UpdateReport",
    "register_filter",
]


@dataclass
class UpdateReport:
    """What a measurement update did (for counters, events and the status byte)."""

    kind: str
    accepted: bool
    n_rows: int = 0
    max_norm_innov: float = 0.0
    detail: dict[str, Any] | None = None


class FilterHost(Protocol):
    """What the main loop offers a variant (:class:`firmware_model.tasks.navigation.NavCore` implements it)."""

    def utc_days(self, t_fpga_s: float) -> float | None:
        """Grena days (UT) at FPGA time ``t_fpga_s``, once GNSS gave date and time (else None)."""

    def ins_at(self, t_meas: float) -> tuple[F64Array, FloatArray, FloatArray]:
        """INS position (lat, lon rad, h m; float64), ENU velocity and attitude quaternion ``q_b^n`` at ``t_meas``.

        Fresh arrays built from the INS history (docs/decisions/performance.md D-10.F2)."""

    def mag_mean_nt(self, t_center_s: float, half_window_s: float = 0.025) -> tuple[FloatArray, int] | None:
        """Mean magnetometer field (nT, body axes) of the MAG frames sampled within ``t_center_s +- half_window_s``."""

    def now_s(self) -> float:
        """FPGA time of the current tick, s."""


class NavFilter:
    """Interface of a navigation filter variant (see module docstring).

    Attributes the loop reads: ``P`` (n, n) covariance whose first 9 states are
    ``[phi, dv, dL dlambda dh]`` (for the reported sigmas), ``gyro_bias`` (rad/s, body) and
    ``accel_bias`` (m/s^2, body) used to compensate the IMU increments, ``counters`` (merged into the
    firmware's counters).
    """

    name = "abstract"
    #: Variant number in NAV_SOLUTION ``mode`` bits 8-11 and STATUS (``protocols.host.FilterVariant``,
    #: docs/architecture.md numbering of the firmware variants); set by :func:`register_filter` from the variant's name.
    variant_id = 0
    #: True: POLARIZATION_OBS frames go to :meth:`update_polarization_obs` instead of the firmware's solve.
    raw_polarization_obs = False
    #: the rotation the gyros measured over the coming predict's interval: the sum of the absolute angle
    #: increments per body axis (rad), set by the loop before each :meth:`predict` (rotation-dependent noise)
    rotation_b_rad: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __init__(self, cfg: FirmwareConfig, meter: c674x.CycleMeter, dtype: FloatDtype) -> None:
        self.cfg = cfg
        self.meter = meter
        self.dtype = dtype
        self.gyro_bias = np.zeros(3, dtype=dtype)
        self.accel_bias = np.zeros(3, dtype=dtype)
        self.P = np.zeros((N_STATES, N_STATES), dtype=dtype)
        self.cost = c674x.KernelCosts("float64" if np.dtype(dtype) == np.float64 else "float32")
        self.host: FilterHost | None = None
        self.counters: dict[str, int] = {}
        #: innovation statistics per measurement type: ``{"rows": n, "nis_sum": sum of nu^2 / s}`` of every scalar
        #: row processed (accepted), for the consistency check (emulator/distributed/campaign/consistency.py)
        self.innovation_stats: dict[str, dict[str, float]] = {}

    def _count_rows(self, kind: str, dof: int, nis: float) -> None:
        """Add ``dof`` degrees of freedom carrying the NIS ``nis`` to :attr:`innovation_stats` under ``kind``."""
        st = self.innovation_stats.get(kind)
        if st is None:
            st = self.innovation_stats[kind] = {"rows": 0, "nis_sum": 0.0}
        st["rows"] += dof
        st["nis_sum"] += nis

    def _count_nis(self, kind: str, norm_innov: float) -> None:
        """Add one scalar row's normalised innovation ``nu / sqrt(s)`` to :attr:`innovation_stats`."""
        self._count_rows(kind, 1, norm_innov * norm_innov)

    def _count_solar_nis(self, norm_innovs: Sequence[float], z: FloatArray, s_n: FloatArray, r: float) -> None:
        """Count one accepted solar-vector fix in :attr:`innovation_stats` as ``SOLAR_VECTOR_DOF`` rows with its NIS
        across the sun (:func:`solar_fix_nis`; ``z`` the residual, ``s_n`` the unit sun in the local-level frame)."""
        along = float(np.dot(z.astype(np.float64), s_n.astype(np.float64)))
        self._count_rows("solar_vector", SOLAR_VECTOR_DOF, solar_fix_nis(norm_innovs, along, r))

    def attach(self, host: FilterHost) -> None:
        """Called by the main loop once the filter exists (and again after a variant switch)."""
        self.host = host

    def drain_events(self) -> list[dict[str, Any]]:
        """Decision events since the last call (``[]`` for variants without a mode manager)."""
        return []

    def variant_status(self) -> tuple[int, int, int] | None:
        """``(variant_mode, psns_units, psns_q_mask)`` for NAV_SOLUTION / STATUS; None: no VARIANT block."""
        return None

    def update_polarization_obs(self, nav: NavState, frame: Any, t_exposure_s: float) -> UpdateReport | None:
        """Raw POLARIZATION_OBS frames (only for variants with ``raw_polarization_obs``)."""
        return None

    def initialise(self, nav: NavState, heading_sigma_rad: float) -> None:
        raise NotImplementedError

    def predict(self, nav: NavState, f_n: FloatArray, Tk: float) -> None:
        """Time update over ``Tk`` s; ``f_n``: mean specific force (m/s^2, n). The loop sets
        :attr:`rotation_b_rad` before the call."""
        raise NotImplementedError

    def update_gnss(self, nav: NavState, meas: GnssMeasurement, p_ins: FloatArray, v_ins: FloatArray) -> UpdateReport:
        raise NotImplementedError

    def update_solar(self, nav: NavState, obs: SolarObservation, s_n: FloatArray, cbn_exp: FloatArray) -> UpdateReport:
        raise NotImplementedError

    def update_compass(self, nav: NavState, frame: Any, t_exposure_s: float) -> UpdateReport | None:
        """Multi-unit compass frames: not used by the base variant (the compass variants use them)."""
        return None

    def feedback(self, nav: NavState) -> None:
        raise NotImplementedError


_FilterClass = TypeVar("_FilterClass", bound=type[NavFilter])


def register_filter(name: str) -> Callable[[_FilterClass], _FilterClass]:
    """Class decorator: make a :class:`NavFilter` selectable as ``firmware.filter: name`` (enters it in the
    build's table :data:`firmware_model.config.FILTER_VARIANTS`)."""

    def deco(cls: _FilterClass) -> _FilterClass:
        cls.name = name
        if name in FILTER_VARIANT_NAMES:  # the host protocol's variant number (STATUS, SELECT_VARIANT)
            cls.variant_id = int(FILTER_VARIANT_NAMES[name])
        FILTER_VARIANTS[name] = cls
        return cls

    return deco
