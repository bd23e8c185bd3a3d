"""The camera as a device: POLARIZATION_OBS frames at its frame rate on the RS232 PSNS link."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from protocols.psns import PsnsHeader, PsnsStatus, encode_polarization_obs_columns, max_points

from ...links.base import Link
from .geometry import PointObservations, wire_aop_cdeg
from .model import PolarizationCameraModel

__all__ = ["PolarizationCamera"]


class PolarizationCamera:
    """The camera as a device: captures at ``rate_hz`` and sends POLARIZATION_OBS frames on its link.

    Parameters
    ----------
    link : the PSNS port (RS232) towards the FPGA.
    model : the rendering/processing model.
    rate_hz : frame rate.
    exposure_s : exposure time (the frame's ``exposure_us``).
    processing_s : end of exposure to the frame being handed to the UART.
    phase_s : time of the first exposure start.
    mosaic_source : for recorded data: ``f(t_mid) -> mosaic | None`` replaces the rendering.
    """

    def __init__(self, link: Link, model: PolarizationCameraModel, rate_hz: float = 5.0, exposure_s: float = 1e-3,
                 processing_s: float = 0.02, phase_s: float = 0.0,
                 mosaic_source: Callable[[float], np.ndarray | None] | None = None) -> None:
        self.link = link
        self.model = model
        self.rate_hz = rate_hz
        self.exposure_s = exposure_s
        self.processing_s = processing_s
        self.phase_s = phase_s
        self.mosaic_source = mosaic_source
        budget = max_points(link.line.baud, rate_hz, round(link.line.bits_per_byte))
        if model.geo.n_points > budget:
            raise ValueError(f"{model.geo.n_points} observation points do not fit the PSNS line: "
                             f"{link.line.baud} baud at {rate_hz:g} frames/s carries at most {budget} "
                             f"(protocols.psns.max_points); use a smaller grid or a lower rate")
        self.seq = 0
        self.frames_sent = 0
        self.last: PointObservations | None = None
        self._k = 0
        #: injected fault: the lens is covered (frames without points); frames sent so (fault evidence)
        self.blocked = False
        self.frames_blocked = 0

    def set_blocked(self, blocked: bool) -> None:
        """Cover or uncover the lens (emulator.faults): a covered camera sends frames with no points,
        status OCCLUDED | LOW_DOP."""
        self.blocked = blocked

    def start(self) -> None:
        self._schedule()

    #: frames whose truth is evaluated in one trajectory call (:meth:`PolarizationCameraModel.truth_ahead`)
    TRUTH_AHEAD = 25

    def _t_start(self, k: int) -> float:
        """Exposure start of frame ``k`` (s)."""
        return self.phase_s + k / self.rate_hz

    def _t_mid(self, t_start: float) -> float:
        """Mid-exposure instant (s) of the frame whose exposure starts at ``t_start``: what the frame sees."""
        return t_start + 0.5 * self.exposure_s

    def _schedule(self) -> None:
        t0 = self._t_start(self._k)
        self.link.loop.call_at(t0 + self.exposure_s + self.processing_s, self._capture, t0)

    def _capture(self, t_start: float) -> None:
        self._k += 1
        self._schedule()
        t_mid = self._t_mid(t_start)
        if not self.model.has_truth(t_mid):  # this frame's and the next frames' truth, in one evaluation
            k = self._k - 1
            ahead = [self._t_mid(self._t_start(j)) for j in range(k + 1, k + self.TRUTH_AHEAD)]
            self.model.truth_ahead([t_mid, *ahead])
        mosaic = None
        if self.mosaic_source is not None:
            mosaic = self.mosaic_source(t_mid)
            if mosaic is None:  # no recorded frame for this capture
                return
        obs = self.model.observe(t_mid, mosaic)
        if self.blocked:
            e = np.zeros(0)
            obs = PointObservations(e.astype(int), e.astype(int), e, e, e, np.zeros(0, dtype=bool),
                                    int(PsnsStatus.OCCLUDED | PsnsStatus.LOW_DOP), obs.sun_elevation)
            self.frames_blocked += 1
        self.last = obs
        self.link.send(self.encode(obs, t_mid))
        self.frames_sent += 1
        self.seq = (self.seq + 1) & 0xFFFF

    def encode(self, obs: PointObservations, t_mid: float) -> bytes:
        """The POLARIZATION_OBS frame of ``obs`` with its latency from ``t_mid`` to the first start bit."""
        now = self.link.loop.time()
        t_first_bit = max(now, self.link.busy_until())
        latency_us = round((t_first_bit - t_mid) * 1e6)
        aop = wire_aop_cdeg(obs.aop)
        dop = np.clip(np.round(obs.dop * 65535.0), 0, 65535).astype(np.int64)
        s0 = np.clip(np.round(obs.s0_dn), 0, 65535).astype(np.int64)
        # the points' columns as plain ints (tolist), as int() of each element gave; packed without point objects
        cols = (np.asarray(obs.x_px).astype(np.int64).tolist(), np.asarray(obs.y_px).astype(np.int64).tolist(),
                aop.tolist(), dop.tolist(), s0.tolist())
        # the exposure this frame had (auto exposure: the model's scale of the configured one; the capture's timing
        # keeps the configured exposure, which moves the mid-exposure instant by at most half of it)
        hdr = PsnsHeader(self.seq, round(self.exposure_s * self.model.exposure_scale * 1e6), latency_us, obs.status,
                         len(cols[0]))
        return encode_polarization_obs_columns(hdr, *cols)
