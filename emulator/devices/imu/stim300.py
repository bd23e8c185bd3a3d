"""The STIM300 IMU as a gyro-port device: STIM300 normal-mode datagrams on the same RS422 link as the STIM210.

The gyro channel is the STIM210 model's (:class:`~.stim210.Stim210Gyro`: the same error model, low-pass group
delay, look-ahead and injected faults; the STIM300 gyros share the STIM210's LSBs, TS1524 r31 7.5.2.2); the
datagram is the configured STIM300 ID (:data:`protocols.stim300.STIM300_DATAGRAMS`, default 0x93: rate,
acceleration, inclination; the datasheet's default), CRC-32/MPEG-2 with its dummy bytes. The other clusters:

* accelerometers (10 g range, 2^-19 g/LSB) and inclinometers (2^-22 g/LSB): the interval's mean specific force
  from truth, body axes, quantised; no error model of their own (the virtual FPGA navigates with its analog
  accelerometers and uses only the gyro words; these words are for a consumer of the datagram, e.g. a real
  board on a ``pty://``/``serial://`` gyro port);
* temperatures from the IMU temperature profile (2^-8 degC);
* the PPS/AUX word 0 (no PPS wired to the IMU).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from protocols.constants import G_STD
from protocols.stim import TEMP_LSB_DEGC
from protocols.stim300 import INCL_LSB_G, STIM300_ACCEL_LSB_G, STIM300_DATAGRAMS, Stim300Datagram, Stim300Format

from ...links.base import Link
from .lookahead import Ahead, ImuTruthTap
from .stim210 import Stim210Gyro

__all__ = ["STIM300_ACCEL_RANGE_G", "Stim300Imu"]

#: accelerometer range option of the modelled unit, g (TS1524 r31: 5, 10, 30 or 80 g)
STIM300_ACCEL_RANGE_G = 10


class Stim300Imu(Stim210Gyro):
    """A STIM300 in external-trigger mode sending datagram ``ident`` (see module docstring); the other
    parameters are those of :class:`~.stim210.Stim210Gyro`."""

    def __init__(self, link: Link, tap: ImuTruthTap, rng: np.random.Generator, *args: Any, ident: int = 0x93,
                 **kw: Any) -> None:
        super().__init__(link, tap, rng, *args, **kw)
        self.format = Stim300Format(ident)  # type: ignore[assignment]  # the gyro port's datagram
        self.ident = ident
        self.groups = STIM300_DATAGRAMS[ident][0]
        self._interval = (0.0, 0.0)

    def trigger(self, t: float, t_prev: float) -> None:
        self._interval = (t_prev, t)
        super().trigger(t, t_prev)

    def _specific_force_words(self, lsb_g: float) -> tuple[int, int, int]:
        t0, t1 = self._interval
        if t1 <= t0:
            return (0, 0, 0)
        _dtheta, dv = self.tap.increments(t0, t1)
        f = np.asarray(dv) / (t1 - t0)
        v = self.tap.vibration_at(t1)
        if v is not None:
            f = f + v
        w = np.clip(np.round(f / (lsb_g * G_STD)), -0x800000, 0x7FFFFF).astype(np.int64)
        return (int(w[0]), int(w[1]), int(w[2]))

    def _window(self, ahead: Ahead, t_edge: float) -> list[tuple[bytes, np.ndarray, float, int]]:
        """No datagrams ahead: a STIM300 datagram carries the accelerometer and inclinometer words of the interval
        being triggered, taken from truth at the trigger; each row's gyro words go through :meth:`_encode`."""
        return []

    def _encode(self, words: list[list[int]], status: Sequence[int], counters: Sequence[int],
                temps_c: Sequence[float]) -> bytes:
        """The STIM300 datagram of one trigger (a window of one: the interval is the one being triggered)."""
        if len(words) != 1:
            raise ValueError("a STIM300 datagram is built one trigger at a time")
        w = words[0]
        gyro_words = (w[0], w[1], w[2])
        tw = round(temps_c[0] / TEMP_LSB_DEGC)
        temps = (tw, tw, tw)
        g = self.groups
        acc = self._specific_force_words(STIM300_ACCEL_LSB_G[STIM300_ACCEL_RANGE_G]) if "acc" in g else None
        incl = self._specific_force_words(INCL_LSB_G) if "incl" in g else None
        has_t = "temp" in g
        d = Stim300Datagram(
            ident=self.ident, gyro=gyro_words, gyro_status=status[0], counter=counters[0],
            latency_us=self.latency_us,
            accel=acc, accel_status=0 if acc is not None else None,
            incl=incl, incl_status=0 if incl is not None else None,
            gyro_temp=temps if has_t else None, gyro_temp_status=0 if has_t else None,
            accel_temp=temps if has_t and acc is not None else None,
            accel_temp_status=0 if has_t and acc is not None else None,
            incl_temp=temps if has_t and incl is not None else None,
            incl_temp_status=0 if has_t and incl is not None else None,
            aux=0 if "aux" in g else None, aux_status=0 if "aux" in g else None,
        )
        return self.format.build(d)  # type: ignore[arg-type]
